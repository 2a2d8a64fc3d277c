// The residual loop on real recordings (tests/data/*/README.md: source, licence, caveats): every
// verdict pinned. The loop must claim an effect only where the data support it, and find the one
// real closure there is (the incubator's lid openings as a switched conductance).
#include "host/residual/residual_loop.hpp"
#include "host/residual/residual_report.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

namespace btsm::residual {
namespace {
namespace th = btsm::thermal;

LoopResult run(const std::string& folder, const std::string& network, const std::string& fit, const std::string& check) {
  const std::string dir = std::string(BTSM_TEST_DATA_DIR) + "/" + folder + "/";
  return run_residual_loop(th::load_network(dir + network), Eigen::VectorXd(), {th::read_recording_csv(dir + fit)},
                           {th::read_recording_csv(dir + check)}, {});
}

bool names(const std::vector<std::string>& v, const std::string& x) { return std::find(v.begin(), v.end(), x) != v.end(); }

void expect_nothing_claimed(const LoopResult& r) {
  EXPECT_EQ(r.verdict, "unexplained") << format_table(r);
  EXPECT_EQ(r.effect, "unexplained");
  EXPECT_DOUBLE_EQ(r.after_check.rmse_k, r.before_check.rmse_k);
  for (const auto& c : r.candidates) EXPECT_NE(c.status, "effect") << c.label << ": " << c.reason;
}

// CAIVIAC/FL_THERMAL (MIT): the 3-node network chosen from the data does not describe the machine
// (undocumented sensor positions, an actively cooled channel); the loop says so and where.
TEST(ResidualLoopRealData, FlThermalIsUnexplainedNotMisattributed) {
  const LoopResult r = run("spindle-fl-thermal", "fl3_network.json", "fl_fit_0-20h.csv", "fl_check_20-46h.csv");
  expect_nothing_claimed(r);
  EXPECT_GT(r.before_check.rmse_k, 0.3);
  EXPECT_TRUE(names(r.nodes, "column"));
  EXPECT_FALSE(r.correlated_signals.empty());
}

// SJTU spindle warm-up: the 54 h plateau is predicted ~1 K off; nothing in the library fixes it
// (no declared boundary here: the room sensor is the only one).
TEST(ResidualLoopRealData, SjtuElongationIsUnexplainedNotMisattributed) {
  const LoopResult r = run("spindle-sjtu-elongation", "sjtu4_network.json", "sjtu_fit_0-24h.csv", "sjtu_check_24-78h.csv");
  expect_nothing_claimed(r);
  EXPECT_LT(r.before_fit.rmse_k, 0.4);
  EXPECT_GT(r.before_check.rmse_k, 0.7);
  EXPECT_TRUE(names(r.nodes, "rear"));
  EXPECT_TRUE(names(r.correlated_signals, "ambient_c"));
}

// Incubator DT 2023 calibration run (empty closed box): structured residual, nothing claimed; the
// well-identified box-to-room resistance agrees with the source's own calibration (1.735 K/W).
TEST(ResidualLoopRealData, IncubatorCalibrationIsUnexplained) {
  const LoopResult r = run("incubator-dt", "incubator2_2023_network.json", "calib2023_fit_0-55min.csv", "calib2023_check_55-111min.csv");
  expect_nothing_claimed(r);
  EXPECT_LT(r.before_check.rmse_k, 0.3);
  const int i = r.base_net.param_index("R_box");
  ASSERT_GE(i, 0);
  EXPECT_NEAR(r.base_fit.params[i], 1.735, 0.1);
}

// Incubator DT 2021, the old cut: fitted on the 34 min before the first lid opening. The lid
// column is not in these files, so no event effect can be fitted, and nothing else explains the
// openings: unexplained.
TEST(ResidualLoopRealData, IncubatorLidOpeningsWithoutEventsInTheFitPartAreUnexplained) {
  const LoopResult r = run("incubator-dt", "incubator2_2021_network.json", "lid2021_fit_0-34min.csv", "lid2021_check_34-323min.csv");
  expect_nothing_claimed(r);
  EXPECT_GT(r.before_check.rmse_k, 3.0);
}

// Incubator DT 2021, re-cut so that the fit part (0-170 min) holds lid openings, with the logged
// openings as the declared event column lid_open: the switched conductance from the air to the
// room explains the held-out part (check 3.42 -> 0.72 K when this was written).
TEST(ResidualLoopRealData, IncubatorLidOpeningsAreAnEventConductance) {
  const LoopResult r = run("incubator-dt", "incubator2_2021_network.json", "lid2021_events_fit_0-170min.csv",
                           "lid2021_events_check_170-323min.csv");
  EXPECT_EQ(r.verdict, "effect") << format_table(r);
  EXPECT_EQ(r.effect, "event_conductance");
  EXPECT_TRUE(names(r.nodes, "air"));
  EXPECT_GE(r.before_check.rmse_k / r.after_check.rmse_k, 4.0) << format_table(r);
  ASSERT_FALSE(r.quantities.empty());
  EXPECT_GT(r.quantities[0].value, 0.0) << r.quantities[0].meaning;  // the open lid loses heat, it does not add it
}

}  // namespace
}  // namespace btsm::residual
