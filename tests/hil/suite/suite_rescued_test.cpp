// Cases of the full undeclared-effect suite (seed 2024, 3 per variant: the README table's set) that
// the residual loop once failed and now answers: each is regenerated bit for bit from its id
// through host/sim/suite (same master seed, same case seeds) and run through the real
// `btsm residual`, and must stay named (family + nodes) with the goal met (claimed, check error
// cut >= 5x or within 2x the noise floor). A regression of the loop on any of them fails here,
// not only in the next full suite table.
#include "host/sim/suite/runner.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <iostream>

namespace btsm::sim::suite {
namespace {

// id -> what once failed on it (the reason it is pinned)
struct Rescued {
  const char* id;
  const char* once;
};
const Rescued kRescued[] = {
    {"event_conductance_cover_open_02", "an earlier loop did not name both of its nodes (rear bearing + housing)"},
    {"ambient_dynamics_air_lag_02", "x316 but rejected at its bound, until the unseen conductance of a pure lag was held"},
    {"ambient_dynamics_air_lag_01", "x55 but rejected on C_ambient_lag's |z| 2.6: the lag's evidence is its time constant C/g"},
    {"heat_source_transient_additive_02", "an earlier loop did not name it at the rear bearing alone"},
    {"extra_heat_input_unprobed_shaft_03", "taken for a probe lag until heat at the unprobed node was refitted as its rival"},
    {"extra_heat_input_unprobed_shaft_02",
     "unexplained: the screening ranked the shaft's heat 6th; it is now refitted when a decision ends without a claim"},
};

TEST(EffectSuiteRescued, CasesOnceFailedStayNamedWithTheGoalMet) {
  SuiteOptions so;
  so.set = SuiteSet::Full;
  so.per_family = 3;
  so.seed = 2024;
  for (const auto& r : kRescued) so.only.push_back(r.id);
  const std::vector<SuiteCase> cases = make_cases(so);
  ASSERT_EQ(cases.size(), std::size(kRescued));  // an id that no longer exists would pass silently
  RunnerOptions ro;
  ro.out_dir = testing::TempDir() + "/effect_suite_rescued";
  std::filesystem::remove_all(ro.out_dir);
  ro.btsm_path = std::string(BTSM_BIN_DIR) + "/btsm";
  ro.jobs = 2;
  ro.progress = [](const std::string& s) { std::cerr << s << std::endl; };
  const SuiteReport rep = run_suite(cases, ro);
  std::cout << rep.table_md;
  ASSERT_EQ(rep.results.size(), std::size(kRescued));
  for (const auto& c : rep.results) {
    const auto it = std::find_if(std::begin(kRescued), std::end(kRescued), [&](const Rescued& r) { return c.id == r.id; });
    ASSERT_NE(it, std::end(kRescued)) << c.id;
    const std::string ctx = c.id + " (once: " + it->once + "): verdict " + c.verdict + " " + c.effect + ", check " +
                            std::to_string(c.rmse_before_k) + " -> " + std::to_string(c.rmse_after_k) + " K" +
                            (c.error.empty() ? "" : ", " + c.error);
    EXPECT_TRUE(c.named) << ctx;
    EXPECT_TRUE(c.goal) << ctx;
  }
}

}  // namespace
}  // namespace btsm::sim::suite
