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
};

// A run of checked speeds where some channel's steady error is beyond its share of the drift.
struct SpeedGap {
  double from_rpm = 0, to_rpm = 0;   // rpm, first and last checked speed of the run
  int channel = -1;                  // 0-based, the channel with the largest excess there
  double worst_error_K = 0;          // K, that channel's steady error with the largest |.|: + = probe above the model
  double allowed_K = 0;              // K, its allowance on that side (drift_fraction x drift)
};

struct SpeedCoverage {
  std::vector<double> speed_rpm;                   // rpm, the speeds checked
  std::array<std::vector<double>, 5> error_K;      // per channel and speed, network - module steady rise (empty: not diagnosed)
  std::array<double, 5> worst_abs_K{};             // per channel, max |error| over the speeds checked
  std::vector<SpeedGap> gaps;                      // ascending in speed
  double valid_from_rpm = 0, valid_to_rpm = 0;     // rpm, the covered run that holds the top breakpoint (from = 0: every speed up to `to`)
  bool covers_all = false;                         // every speed checked is covered
  double drift_fraction = 0.5;
};

// The quantized module model of `r` (what the blob holds) against the network at every
// opts.step_rpm from opts.step_rpm to the top speed.
SpeedCoverage check_speed_coverage(const Network& net, const Eigen::VectorXd& params, const ScheduledReduction& r,
                                   const SpeedCoverageOptions& opts = {});

// One line per gap for the console, e.g. "ch1: 25-3650 rpm: 2.10 K below the model (allowed 0.47 K)".
std::vector<std::string> describe_gaps(const SpeedCoverage& c);
nlohmann::json speed_coverage_to_json(const SpeedCoverage& c);

}  // namespace btsm::thermal
