// The detector calibration rule (host/thermal/detector_calibration.hpp) on recordings simulated
// from the reference network: thresholds cover everything of normal running (recordings and the
// duty cycle) with the stated margin, the drift is the candidate whose ALARM the design fault
// reaches soonest, and an extra heat at the rear bearing reaches ALARM.
#include "host/thermal/detector_calibration.hpp"
#include "host/thermal/reduce.hpp"
#include "host/thermal/simulator.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

namespace btsm::thermal {
namespace {

// A recording of the network at 5 s (T1..T3 and the shaft on T5), with an optional extra heat at
// the rear bearing from `fault_s`.
Recording simulate(const Network& net, const Eigen::VectorXd& p, const std::vector<std::pair<double, double>>& profile,
                   double fault_w = 0, double fault_s = 1e18) {
  Recording r;
  r.source = "simulated";
  r.channels = {"T1", "T2", "T3", "T5"};
  Simulator sim(net, p);
  sim.reset(Eigen::VectorXd::Constant(4, 20.0));
  std::vector<std::array<double, 4>> rows;
  double t = 0;
  Eigen::VectorXd extra = Eigen::VectorXd::Zero(4);
  for (const auto& [rpm, dur] : profile)
    for (double u = 0; u < dur; u += 5, t += 5) {
      r.time_s.push_back(t);
      r.speed_rpm.push_back(rpm);
      r.ambient_c.push_back(20.0);
      const Eigen::VectorXd& x = sim.node_temp_c();
      rows.push_back({x[0], x[1], x[2], x[3]});
      extra[0] = t >= fault_s ? fault_w : 0.0;
      sim.step(5, rpm, 20.0, &extra);
    }
  r.temp_c.resize(static_cast<Eigen::Index>(rows.size()), 4);
  for (std::size_t i = 0; i < rows.size(); ++i)
    for (int c = 0; c < 4; ++c) r.temp_c(static_cast<Eigen::Index>(i), c) = rows[i][static_cast<std::size_t>(c)];
  return r;
}

// spindle4 reduced at 4000, 6000 and 8000 rpm, ch5 on the shaft.
ScheduledReduction reduce_at_warmup_speeds(const Network& net, const Eigen::VectorXd& p) {
  ReduceOptions o;
  o.speeds_rpm = {4000, 6000, 8000};
  o.channel_node = {{0, 1, 2, -1, 3}};
  return build_scheduled_model(net, p, o);
}

// Lost samples: a 10-minute gap in a calibration recording was replayed as 120 steps each compared
// with the reading after the gap (and at its speed), which piled up evidence and widened the bands
// 20-fold. The steps across a gap give no residual: the bands are those of the recording without it.
TEST(DetectorCalibration, AGapOfLostSamplesDoesNotWidenTheBands) {
  const Network net = preset_network("spindle4");
  const Eigen::VectorXd p = test::true_parameters(net);
  const ScheduledReduction red = reduce_at_warmup_speeds(net, p);
  const double h = 3600;
  const Recording whole = simulate(net, p, {{6000, 4 * h}, {0, 3 * h}});
  Recording gap = whole;  // rows 1000..1119 lost: 10 min while warming up
  const auto drop = [](auto& v) { v.erase(v.begin() + 1000, v.begin() + 1120); };
  drop(gap.time_s);
  drop(gap.speed_rpm);
  drop(gap.ambient_c);
  Eigen::MatrixXd t(whole.temp_c.rows() - 120, whole.temp_c.cols());
  t << whole.temp_c.topRows(1000), whole.temp_c.bottomRows(whole.temp_c.rows() - 1120);
  gap.temp_c = t;
  const std::array<std::string, kModelChannels> cols = {"T1", "T2", "T3", "", "T5"};
  const DetectorCalibration a = calibrate_detector(red, {&whole}, cols, DetectorRule{});
  const DetectorCalibration b = calibrate_detector(red, {&gap}, cols, DetectorRule{});
  for (int j : {0, 1, 2, 4}) {
    const auto c = static_cast<std::size_t>(j);
    EXPECT_NEAR(b.channels[c].detector.alarm_evidence_K_min, a.channels[c].detector.alarm_evidence_K_min,
                0.05 * a.channels[c].detector.alarm_evidence_K_min) << j;
    EXPECT_NEAR(b.channels[c].detector.low_warn_evidence_K_min, a.channels[c].detector.low_warn_evidence_K_min,
                0.05 * a.channels[c].detector.low_warn_evidence_K_min) << j;
  }
  EXPECT_EQ(replay_residuals(red.quantized, gap, cols)[0].size(), replay_residuals(red.quantized, whole, cols)[0].size() - 120);
}

TEST(DetectorCalibration, FollowsTheStatedRuleAndSeparatesNormalFromAFault) {
  const Network net = preset_network("spindle4");
  const Eigen::VectorXd p = test::true_parameters(net);
  const ScheduledReduction red = reduce_at_warmup_speeds(net, p);
  ASSERT_TRUE(red.quantize_status.ok());
  ASSERT_FALSE(red.duty.residual_K[0].empty());
  ASSERT_EQ(red.design_fault.rise_K[0].size(), 1440u);
  EXPECT_GT(red.design_fault.rise_K[0].back(), red.design_fault.rise_K[0][100]) << "the fault's rise grows";
  const double h = 3600;
  const Recording a = simulate(net, p, {{6000, 4 * h}, {0, 3 * h}});
  const Recording b = simulate(net, p, {{4000, 1.5 * h}, {0, 0.5 * h}, {8000, 2 * h}, {5000, 1 * h}, {0, 2 * h}});
  const std::array<std::string, kModelChannels> cols = {"T1", "T2", "T3", "", "T5"};
  DetectorRule rule;
  const DetectorCalibration cal = calibrate_detector(red, {&a, &b}, cols, rule);
  EXPECT_EQ(cal.recordings, 2u);
  EXPECT_FALSE(cal.channels[3].diagnosed) << "the ambient channel";
  for (int j : {0, 1, 2, 4}) {
    const auto c = static_cast<std::size_t>(j);
    const ChannelCalibration& cc = cal.channels[c];
    ASSERT_TRUE(cc.diagnosed) << j;
    // The rule, recomputed from the residuals: recordings and the duty cycle.
    std::vector<std::vector<double>> res;
    for (const Recording* r : {&a, &b}) res.push_back(replay_residuals(red.quantized, *r, cols)[c]);
    res.push_back(red.duty.residual_K[c]);
    const auto [hi, lo] = worst_evidence(res, cc.detector.drift_K, cc.detector.low_drift_K, 5000);
    EXPECT_DOUBLE_EQ(cc.detector.warn_evidence_K_min, 1.5 * hi + 0.5) << j;
    EXPECT_DOUBLE_EQ(cc.detector.alarm_evidence_K_min, 2 * cc.detector.warn_evidence_K_min) << j;
    EXPECT_DOUBLE_EQ(cc.detector.low_warn_evidence_K_min, 1.5 * lo + 0.5) << j;
    EXPECT_GE(cc.detector.low_drift_K, cc.detector.drift_K) << j << ": the lower side is never tighter than the upper";
    // The chosen drift: no other candidate brings the design fault's ALARM sooner.
    ASSERT_GE(cc.design_alarm_min, 0) << j;
    for (double d = 0.05; d <= cc.worst_above_K + 0.05; d += 0.05) {
      const double w = 1.5 * worst_evidence(res, d, 1e9, 5000).first + 0.5;
      const double t = minutes_to_evidence(red.design_fault.rise_K[c], d, 2 * w, 5000);
      if (t >= 0) {
        EXPECT_GE(t, cc.design_alarm_min - 1e-9) << "channel " << j << " drift " << d;
      }
    }
    EXPECT_DOUBLE_EQ(minutes_to_evidence(red.design_fault.rise_K[c], cc.detector.drift_K,
                                         cc.detector.alarm_evidence_K_min, 5000),
                     cc.design_alarm_min);
    std::cout << "channel " << j + 1 << ": drift " << cc.detector.drift_K << " K, ALARM " << cc.detector.alarm_evidence_K_min
              << " K min, 10 W at its node: ALARM after " << cc.design_alarm_min << " min\n";
  }
  // 30 W more at the rear bearing two hours into a 6000 rpm run: its upper evidence passes ALARM,
  // with the calibrated drift, soon after.
  ReducedModelF64 m = red.model;
  apply_calibration(cal, m);
  const Recording f = simulate(net, p, {{6000, 4 * h}}, 30.0, 2 * h);
  const auto rf = replay_residuals(red.quantized, f, cols)[0];
  double ev = 0;
  double alarm_at = -1;
  for (std::size_t k = 0; k < rf.size(); ++k) {
    ev = std::max(0.0, ev + rf[k] - m.detector[0].drift_K);
    if (alarm_at < 0 && ev * 5 / 60 > m.detector[0].alarm_evidence_K_min) alarm_at = (k + 1) * 5.0;
  }
  ASSERT_GT(alarm_at, 2 * h) << "no alarm before the fault";
  EXPECT_LT(alarm_at - 2 * h, 900) << "ALARM " << (alarm_at - 2 * h) / 60 << " min after the fault";
  std::cout << "30 W at the rear bearing: upper evidence past ALARM " << (alarm_at - 2 * h) / 60 << " min after it starts\n";
  // A mapped column the recording lacks is named.
  const std::array<std::string, kModelChannels> bad = {"T1", "T2", "T9", "", "T5"};
  EXPECT_THROW(calibrate_detector(red, {&a}, bad, rule), std::invalid_argument);
}

}  // namespace
}  // namespace btsm::thermal
