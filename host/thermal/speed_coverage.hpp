#pragma once
// Where in speed the module's model can be trusted. The module runs breakpoint coefficients
// interpolated linearly in speed (common/model_step.hpp; breakpoint 0 is the stop, so below the
// lowest running breakpoint it interpolates towards "stopped"), while the fitted network knows its
// steady state at every speed. After a long run at speed s the module's steady rise
// b(s) / (1 - a(s)) and the network's differ by the steady error e(s) = network - module (what a
// healthy spindle's residual, measured - predicted, settles to). The detector forgives a residual
// up to its drift; a lasting residual beyond it accumulates evidence without bound, so a healthy
// spindle running there long enough WARNs (then ALARMs). A speed is covered when every diagnosed
// channel's |e(s)| stays within `drift_fraction` of the drift on that side: the rest of the drift
// is left for the transients, which the band calibration measured at the breakpoints and their
// midpoints only.
//
// The drift alone is not the test when it is calibrated: raised to cover a large steady error
// (--calibrate-bands), it hides the error and a fault with it. With `design_heat_w` > 0 a speed is
// covered only when that much more heat at a channel's node (its steady rise X(s) by the network)
// would still ALARM within `design_alarm_within_min`: the lasting residual e(s) + X(s) beyond the
// drift must accumulate the ALARM evidence in that time. Where X(s) alone is too small for that
// (bands set wider than the fault), the error is not to blame: `bands_hide_fault_K` says so apart. A model 3.7 K above a healthy bearing at
// 3000 rpm (breakpoints 4000, 6000, 8000) hid a 10 W fault there for hours behind a raised drift.
#include "network.hpp"
#include "reduce.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <array>
#include <string>
#include <vector>

namespace btsm::thermal {

struct SpeedCoverageOptions {
  double step_rpm = 25.0;        // rpm, spacing of the speeds checked (from step_rpm up)
  double top_rpm = 0.0;          // rpm, highest speed checked (0 = the highest breakpoint)
  double drift_fraction = 0.5;   // 1, share of each channel's drift a steady error may use
  double design_heat_w = 0.0;    // W, the fault that must stay detectable at every speed (0 = not checked)
  double design_alarm_within_min = 120.0;  // min, how soon its lasting residual must reach the ALARM evidence
};

// A run of checked speeds where some channel's steady error is beyond its share of the drift.
struct SpeedGap {
  double from_rpm = 0, to_rpm = 0;   // rpm, first and last checked speed of the run
  int channel = -1;                  // 0-based, the channel with the largest excess there
  double worst_error_K = 0;          // K, that channel's steady error with the largest |.|: + = probe above the model
  double allowed_K = 0;              // K, its allowance on that side (drift_fraction x drift)
  bool hides_fault = false;          // the gap is a design fault that would not ALARM (the error may be within its share)
  double fault_rise_K = 0;           // K, that fault's steady rise at the channel's node (hides_fault)
};

struct SpeedCoverage {
  std::vector<double> speed_rpm;                   // rpm, the speeds checked
  std::array<std::vector<double>, 5> error_K;      // per channel and speed, network - module steady rise (empty: not diagnosed)
  std::array<double, 5> worst_abs_K{};             // per channel, max |error| over the speeds checked
  std::vector<SpeedGap> gaps;                      // ascending in speed
  double valid_from_rpm = 0, valid_to_rpm = 0;     // rpm, the covered run that holds the top breakpoint (from = 0: every speed up to `to`)
  bool covers_all = false;                         // every speed checked is covered
  double drift_fraction = 0.5;
  double design_heat_w = 0.0, design_alarm_within_min = 120.0;
  // per channel, > 0 when at some speed the design fault's rise stays below what the bands need to
  // ALARM in time even with an exact model (hand-set bands wider than the fault): the K it would need
  std::array<double, 5> bands_hide_fault_K{};
};

// The quantized module model of `r` (what the blob holds) against the network at every
// opts.step_rpm from opts.step_rpm to the top speed.
SpeedCoverage check_speed_coverage(const Network& net, const Eigen::VectorXd& params, const ScheduledReduction& r,
                                   const SpeedCoverageOptions& opts = {});

// One line per gap for the console, e.g. "ch1: 25-3650 rpm: 2.10 K below the model (allowed 0.47 K)".
std::vector<std::string> describe_gaps(const SpeedCoverage& c);
nlohmann::json speed_coverage_to_json(const SpeedCoverage& c);

}  // namespace btsm::thermal
