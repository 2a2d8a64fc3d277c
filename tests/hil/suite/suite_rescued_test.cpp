// Cases of the full undeclared-effect suite (the README table's set, seed 2024 with 3 per variant,
// unseen cases drawn at seed 31 with 2, and at seeds 99, 2026, 3141, 5150 and 8128 with 1) that the residual loop once failed and now answers:
// each is regenerated bit for bit from its id through host/sim/suite (same master seed, same case
// seeds) and run through the real `btsm residual`, and must stay named (family + nodes) with the
// goal met (claimed, check error cut >= 5x or within 2x the noise floor). A regression of the loop
// on any of them fails here, not only in the next full suite table.
#include "host/sim/suite/runner.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <vector>

namespace btsm::sim::suite {
namespace {

// A suite (master seed, cases per variant) and the ids of it that are pinned, each with what once
// failed on it (the reason it is pinned).
struct Rescued {
  const char* id;
  const char* once;
};
struct RescuedSet {
  unsigned seed;
  int per_family;
  std::vector<Rescued> cases;
};
const std::vector<RescuedSet>& rescued_sets() {
  static const std::vector<RescuedSet> sets = {
      {2024, 3,  // the README table's full set
       {{"event_conductance_cover_open_02", "an earlier loop did not name both of its nodes (rear bearing + housing)"},
        {"ambient_dynamics_air_lag_02", "x316 but rejected at its bound, until the unseen conductance of a pure lag was held"},
        {"ambient_dynamics_air_lag_01", "x55 but rejected on C_ambient_lag's |z| 2.6: the lag's evidence is its time constant C/g"},
        {"heat_source_transient_additive_02", "an earlier loop did not name it at the rear bearing alone"},
        {"extra_heat_input_unprobed_shaft_03", "taken for a probe lag until heat at the unprobed node was refitted as its rival"},
        {"extra_heat_input_unprobed_shaft_02",
         "unexplained: the screening ranked the shaft's heat 6th; it is now refitted when a decision ends without a claim"},
        {"extra_heat_input_unprobed_shaft_01",
         "unexplained: the shaft's heat, refitted from the base fit that holds it in the bearings' sources, reached x4.5 and a "
         "temperature-dependent source explained the check better; it is now also started from the best-fitting candidate's base"}}},
      {31, 2,  // unseen cases drawn to measure rates
       {{"ambient_dynamics_air_lag_01",
         "x67 but rejected: the lag's conductance became unidentifiable on the full-rate refit and was not held there"},
        {"temperature_dependent_heat_rising_01",
         "partial coupled_heat: its base fit restarted into another basin (1.221 -> 0.412 K) and the re-polish (0.290 K) no longer "
         "set off the second screening; it now does after a restarted base (rescreen_rule.hpp)"}}},
      {2026, 1,  // a fresh unseen seed
       {{"extra_heat_input_unprobed_shaft_01",
         "coupled_heat@rear_bearing claimed (x2.15, a wrong family): a heat claim at a probed node was not challenged by heat at "
         "the unprobed shaft, and that rival started only from the base fit"},
        {"sensor_lag_lag_01",
         "partial sensor_lag@T2: the base fit absorbed the shaft probe's 8.5 min lag and no refit went on from the base fitted "
         "without T5; a decision without a claim now refits a lag at each probe from there"},
        {"heat_source_transient_additive_01",
         "unexplained: the plant's variant (additive, every speed increase, rear bearing) was never refitted, the screening "
         "proposed two others; every (trigger, coupling) variant of a refitted transient now is (refit_selection.hpp rule 3)"}}},
      {99, 1,  // an unseen seed drawn to measure rates
       {{"heat_source_transient_additive_01",
         "named but x3.5 < 5: the transient's refits all held the base fit's values, which absorbed part of the run-in heat (fit "
         "0.013 K); the latent mass fitted the fit part at 0.003 K. A claim fitting that much worse than another candidate is now "
         "refitted from that candidate's base (residual_loop.cpp, refit_claim_from_better_basin)"}}},
      {3141, 1,  // a fresh unseen seed
       {{"heat_source_transient_additive_01",
         "claimed at the rear bearing alone (x2.3): the screening proposed the run-in where it shows most and the node pruning "
         "only removes nodes; a heat claim that leaves the check well above its floor is now refitted at each other heat source "
         "too (residual_loop.cpp, extend_claim_to_more_nodes)"},
        {"temperature_dependent_heat_rising_01",
         "coupled_heat@rear_bearing claimed (x8.7, a wrong family): the truth's family passed too but at both bearings (check "
         "0.0147 K against 0.0130 K), and only the chosen effect was pruned on the check; a passing rival within 2x of it now is "
         "too (residual_loop.cpp, prune_chosen_on_check)"}}},
      {5150, 1,  // a fresh unseen seed
       {{"second_boundary_coolant_01",
         "extra_heat_input claimed (x2.2, a wrong family): the declared coolant (0.45 W/K at the front bearing) bent the base fit "
         "to 0.557 K, 101x its floor; the boundary, screened about that base at housing + shaft and refitted from its values, fitted "
         "nothing. A declared boundary is now also refitted at every node from the data alone when the base fit ends that far off"}}},
      {8128, 1,  // a fresh unseen seed
       {{"ambient_dynamics_air_lag_01",
         "x113 but rejected at its bound: the lag's unseen conductance was held where the refit left it (2.6e6 W/K), which put its "
         "capacitance at 1e10 J/K for the 65 min lag; both now slide (ratio kept) until the capacitance is inside its bounds"},
        {"sensor_lag_lag_01",
         "claimed at x2.3 (goal 3x): T1's 3.5 min lag carried 38 % of the base residual, under the share that starts the refit "
         "from the base fitted without the probe; a lag claim left above 2x the floor is now refitted from there"},
        {"event_conductance_cover_open_01",
         "claimed at the rear bearing alone (x9.5) where the cover opens onto housing + rear bearing: the node extension of a claim "
         "left above 2x the floor now covers event-switched and boundary conductances at every other node"}}},
  };
  return sets;
}

TEST(EffectSuiteRescued, CasesOnceFailedStayNamedWithTheGoalMet) {
  for (const RescuedSet& set : rescued_sets()) {
    SuiteOptions so;
    so.set = SuiteSet::Full;
    so.per_family = set.per_family;
    so.seed = set.seed;
    for (const auto& r : set.cases) so.only.push_back(r.id);
    const std::vector<SuiteCase> cases = make_cases(so);
    ASSERT_EQ(cases.size(), set.cases.size()) << "seed " << set.seed;  // an id that no longer exists would pass silently
    RunnerOptions ro;
    ro.out_dir = testing::TempDir() + "/effect_suite_rescued/seed" + std::to_string(set.seed);
    std::filesystem::remove_all(ro.out_dir);
    ro.btsm_path = std::string(BTSM_BIN_DIR) + "/btsm";
    ro.jobs = 2;
    ro.progress = [](const std::string& s) { std::cerr << s << std::endl; };
    const SuiteReport rep = run_suite(cases, ro);
    std::cout << "seed " << set.seed << ":\n" << rep.table_md;
    ASSERT_EQ(rep.results.size(), set.cases.size());
    for (const auto& c : rep.results) {
      const auto it = std::find_if(set.cases.begin(), set.cases.end(), [&](const Rescued& r) { return c.id == r.id; });
      ASSERT_NE(it, set.cases.end()) << c.id;
      const std::string ctx = "seed " + std::to_string(set.seed) + " " + c.id + " (once: " + it->once + "): verdict " + c.verdict + " " +
                              c.effect + ", check " + std::to_string(c.rmse_before_k) + " -> " + std::to_string(c.rmse_after_k) + " K" +
                              (c.error.empty() ? "" : ", " + c.error);
      EXPECT_TRUE(c.named) << ctx;
      EXPECT_TRUE(c.goal) << ctx;
    }
  }
}

}  // namespace
}  // namespace btsm::sim::suite
