// The reduced undeclared-effect suite through the real `btsm residual` (what `btsm effect-suite
// --set reduced` runs): recordings of a shortened identification procedure on the simulated
// module, one answer per case, asserted at what the residual loop reliably achieves today.
// Tighten these as the loop improves (README, "Undeclared-effect suite").
#include "host/sim/suite/runner.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iostream>

namespace btsm::sim::suite {
namespace {

const CaseResult& find(const SuiteReport& rep, const std::string& id) {
  for (const auto& r : rep.results)
    if (r.id == id) return r;
  throw std::runtime_error("no case " + id);
}

double parameter(const std::string& dir, const std::string& name) {
  std::ifstream in(dir + "/residual.json");
  const auto j = nlohmann::json::parse(in);
  for (const auto& p : j.at("parameters"))
    if (p.at("name").get<std::string>().find(name) != std::string::npos) return p.at("value").get<double>();
  return NAN;
}

TEST(EffectSuiteReduced, ResidualLoopOnTheReducedSet) {
  SuiteOptions so;
  so.set = SuiteSet::Reduced;
  so.only = {"clean_r", "distractor_ambient_drift_r", "temperature_dependent_heat_rising_r",
             "extra_heat_input_speed_driven_r", "event_conductance_cover_open_r"};
  RunnerOptions ro;
  ro.out_dir = testing::TempDir() + "/effect_suite_reduced";
  std::filesystem::remove_all(ro.out_dir);
  ro.btsm_path = std::string(BTSM_BIN_DIR) + "/btsm";
  ro.progress = [](const std::string& s) { std::cerr << s << std::endl; };
  const SuiteReport rep = run_suite(make_cases(so), ro);
  std::cout << rep.table_md;
  ASSERT_EQ(rep.results.size(), 5u);
  for (const auto& r : rep.results) ASSERT_NE(r.verdict, "error") << r.id << ": " << r.error;

  // The demo's effect family (rear-bearing friction rising with its temperature): named with its
  // node, and the check error cut at least 5x.
  const auto& rising = find(rep, "temperature_dependent_heat_rising_r");
  EXPECT_TRUE(rising.named) << rising.effect;
  EXPECT_TRUE(rising.goal) << rising.rmse_before_k << " -> " << rising.rmse_after_k;
  EXPECT_GE(rising.cut(), 5.0);

  // Speed-driven heat at the shaft, a node without a friction source (the first loop's
  // `unexplained`): named with its node, check error cut at least 5x.
  const auto& extra = find(rep, "extra_heat_input_speed_driven_r");
  EXPECT_TRUE(extra.named) << extra.effect;
  EXPECT_TRUE(extra.goal) << extra.rmse_before_k << " -> " << extra.rmse_after_k;

  // A cover opening that switches a conductance at both bearings, from the declared event column:
  // the family is found and claimed and the check error cut (x2.9 measured); the loop names the
  // rear bearing only (the front bearing's share is not kept), so the node-complete `named` and the
  // 5x goal are NOT met yet -- tighten when they are.
  const auto& cover = find(rep, "event_conductance_cover_open_r");
  EXPECT_TRUE(cover.family_named) << cover.effect;
  EXPECT_TRUE(cover.claimed);
  EXPECT_GE(cover.cut(), 2.0);

  // A drifting room is no effect.
  const auto& drift = find(rep, "distractor_ambient_drift_r");
  EXPECT_FALSE(drift.claimed) << drift.effect;

  // Clean data: no claim. The one tolerated exception: the module's own Kalman filter is a real
  // lag of the recorded temperatures (about 3.5 s at 5 s samples), which a loop might take for a
  // sensor_lag (before the measurement floor it was reported as `partial`; now the answer is
  // `none`). Anything else claimed, or a lag longer than one sample, fails.
  const auto& clean = find(rep, "clean_r");
  if (clean.claimed) {
    EXPECT_EQ(clean.effect, "sensor_lag");
    EXPECT_LT(parameter(ro.out_dir + "/cases/clean_r", "tau"), 5.0);
  }
  EXPECT_LE(clean.rmse_after_k, 2.0 * clean.noise_floor_k);
}

}  // namespace
}  // namespace btsm::sim::suite
