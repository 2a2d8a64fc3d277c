// Where the module's model holds in speed (host/thermal/speed_coverage.hpp), on the spindle4
// network with its true values reduced at the warm-up speeds only (4000, 6000, 8000 rpm): below
// 4000 rpm the module interpolates towards "stopped" and sits well above a healthy bearing.
#include "host/thermal/reduce.hpp"
#include "host/thermal/speed_coverage.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>

namespace btsm::thermal {
namespace {

ScheduledReduction warmup_speeds_only(double drift_K, double low_drift_K, double alarm_K_min) {
  const Network net = preset_network("spindle4");
  ReduceOptions o;
  o.speeds_rpm = {4000, 6000, 8000};
  o.channel_node = {{0, 1, 2, -1, 3}};
  ScheduledReduction r = build_scheduled_model(net, test::true_parameters(net), o);
  for (int ch : {0, 1, 2, 4}) {
    r.model.detector[ch].drift_K = drift_K;
    r.model.detector[ch].low_drift_K = low_drift_K;
    r.model.detector[ch].warn_evidence_K_min = alarm_K_min / 2;
    r.model.detector[ch].alarm_evidence_K_min = alarm_K_min;
  }
  requantize(r);
  return r;
}

// A lower drift raised over the error (what --calibrate-bands did) passes the steady-error rule,
// yet a 10 W fault at the bearing below 4000 rpm leaves the residual under the upper drift.
TEST(SpeedCoverage, ADriftRaisedOverTheErrorStillFailsWhereItHidesTheDesignFault) {
  const Network net = preset_network("spindle4");
  const Eigen::VectorXd p = test::true_parameters(net);
  const ScheduledReduction r = warmup_speeds_only(1.0, 8.0, 1.0);
  SpeedCoverageOptions plain;
  EXPECT_TRUE(check_speed_coverage(net, p, r, plain).covers_all);
  SpeedCoverageOptions with_fault = plain;
  with_fault.design_heat_w = 10.0;
  const SpeedCoverage c = check_speed_coverage(net, p, r, with_fault);
  ASSERT_FALSE(c.covers_all);
  const SpeedGap& g = c.gaps.front();
  EXPECT_TRUE(g.hides_fault);
  EXPECT_EQ(g.channel, 0);  // the rear bearing
  EXPECT_LT(g.worst_error_K, -1.0);  // the model well above a healthy spindle
  EXPECT_GT(g.fault_rise_K, 1.0);
  EXPECT_LT(g.from_rpm, 1500.0);
  EXPECT_GT(g.to_rpm, 2500.0);
  EXPECT_LT(g.to_rpm, 4000.0);
  EXPECT_GE(c.valid_from_rpm, g.to_rpm);  // the breakpoints themselves hold
  EXPECT_EQ(c.valid_to_rpm, 8000.0);
  for (double e : c.bands_hide_fault_K) EXPECT_EQ(e, 0.0);  // these bands would see the fault on an exact model
  const auto lines = describe_gaps(c);
  EXPECT_NE(lines.front().find("10 W more at the channel's node"), std::string::npos) << lines.front();
  EXPECT_NE(lines.front().find("would not ALARM within 120 min"), std::string::npos) << lines.front();
}

// Bands wider than the fault's own rise hide it everywhere: said per channel, not a gap of the
// model (an exact model would not help).
TEST(SpeedCoverage, BandsWiderThanTheFaultAreNamedApart) {
  const Network net = preset_network("spindle4");
  const Eigen::VectorXd p = test::true_parameters(net);
  const ScheduledReduction r = warmup_speeds_only(20.0, 20.0, 40.0);
  SpeedCoverageOptions o;
  o.design_heat_w = 10.0;
  const SpeedCoverage c = check_speed_coverage(net, p, r, o);
  EXPECT_TRUE(c.covers_all);
  EXPECT_GT(*std::max_element(c.bands_hide_fault_K.begin(), c.bands_hide_fault_K.end()), 20.0);
}

}  // namespace
}  // namespace btsm::thermal
