#pragma once
// The module's residual detector (common/diagnosis.hpp: per channel two one-sided CUSUMs of the
// residual measured - predicted, each with its drift) calibrated by a stated rule:
//
//   1. Residuals of normal running: the module's model (fixed point, exactly as flashed) replayed
//      over every recording, started from its first row as after a boot; and the same model
//      against the fitted network itself over the reduction's duty cycle (restarts after 15, 30
//      and 60-minute stops, speed steps, a drifting ambient: host/thermal/reduce.hpp DutyCycle),
//      the transients production has and identification recordings may lack.
//   2. For each candidate drift d (multiples of drift_floor up to the worst residual on that side):
//      H(d) = the worst evidence over those residuals; WARN(d) = margin x H(d) + floor (K min),
//      ALARM(d) = alarm_factor x WARN(d). Nothing of normal running comes within `margin` of WARN.
//   3. The upper drift is the candidate whose ALARM a design fault reaches soonest: the rise the
//      fitted network shows at the channel's node for design_heat_w more heat there (reduce.hpp
//      FaultSignature). The lower drift likewise for the same rise below the model and its WARN,
//      but never below the upper drift (a colder probe has no detection-time target).
// The recordings must be normal running (no fault). A margin below 1, or recordings and a duty
// cycle without a kind of transient production has, give false alarms.
#include "model_reference.hpp"
#include "recording.hpp"
#include "reduce.hpp"

#include "common/model_blob.hpp"

#include <array>
#include <string>
#include <vector>

namespace btsm::thermal {

struct DetectorRule {
  double drift_floor_K = 0.05;        // K, the smallest drift and the step of the candidates
  double margin = 1.5;                // 1, WARN = margin x the worst evidence + floor
  double alarm_factor = 2.0;          // 1, ALARM = this x WARN
  double evidence_floor_K_min = 0.5;  // K min, added to every WARN threshold
  bool include_duty_cycle = true;     // also the model's error against the network over the duty cycle
  std::string describe(const FaultSignature& design) const;
};

struct ChannelCalibration {
  bool diagnosed = false;             // the channel has a model of its own and a recorded column
  std::string column;                 // recording column replayed
  std::size_t samples = 0;            // residuals used (recordings and duty cycle)
  double worst_residual_K = 0;        // max |residual|
  double worst_above_K = 0;           // measured above the model
  double worst_below_K = 0;           // measured below the model
  double worst_high_K_min = 0;        // upper evidence with the chosen drift
  double worst_low_K_min = 0;         // lower evidence with the chosen lower drift
  double design_alarm_min = -1;       // the design fault reaches ALARM after this (< 0: not within 2 h)
  double design_low_warn_min = -1;    // its mirror reaches the lower WARN after this
  ChannelDetector detector;           // the calibrated parameters (abs limit and rise kept)
};

struct DetectorCalibration {
  std::array<ChannelCalibration, kModelChannels> channels;
  std::size_t recordings = 0;
  std::string rule;                   // DetectorRule::describe()
};

// Residuals (K, measured - predicted) of model q replayed over one recording, one per model step,
// per channel (empty for channels without a model or a column). columns[j] = recording column of
// channel j ("" = none).
std::array<std::vector<double>, kModelChannels> replay_residuals(const ReducedModel& q, const Recording& rec,
                                                                 const std::array<std::string, kModelChannels>& columns);

// Worst upper and lower evidence (K min) of residual series (K, one per step of dt_ms) with the
// drifts (K) of the two sides, each series starting from zero evidence.
std::pair<double, double> worst_evidence(const std::vector<std::vector<double>>& residuals, double drift_K,
                                         double low_drift_K, uint16_t dt_ms);

// Minutes until the upper evidence of `rise` (K per step of dt_ms) exceeds `threshold_K_min`
// with drift `drift_K`; < 0 when it does not within the series.
double minutes_to_evidence(const std::vector<double>& rise, double drift_K, double threshold_K_min, uint16_t dt_ms);

// Running time (s, speed > 0) the calibration recordings must hold together: a warm-up lasts hours.
inline constexpr double kMinCalibrationRunningS = 3600.0;

// The rule above for the reduction `red` (its quantized model, detector limits to keep, duty cycle
// and design fault). Throws std::invalid_argument naming the recording and column when a mapped
// column is missing, for a rule out of range, or for recordings with less than
// kMinCalibrationRunningS of running.
DetectorCalibration calibrate_detector(const ScheduledReduction& red, const std::vector<const Recording*>& recordings,
                                       const std::array<std::string, kModelChannels>& columns, const DetectorRule& rule);

// Writes the calibrated detectors into `model` (diagnosed channels only).
void apply_calibration(const DetectorCalibration& c, ReducedModelF64& model);

}  // namespace btsm::thermal
