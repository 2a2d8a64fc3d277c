#pragma once
// The module's residual detector (common/diagnosis.hpp: per channel two one-sided CUSUMs of the
// residual measured - predicted) calibrated from recordings of normal running, by a stated rule:
//
//   1. The module's model (fixed point, exactly as flashed) is replayed over every recording,
//      started from its first row as after a boot; per channel E+ and E- = the worst residual
//      above and below the model.
//   2. drift = max(drift_floor, drift_fraction x E+), lower drift the same of E-: a residual
//      within the drift never accumulates, so the model's long-lasting small errors are forgiven
//      (the two signs separately: a model can err more on one side).
//   3. With those drifts the evidence is replayed too; H+ and H- = its worst upper and lower value.
//   4. WARN = margin x H+ + floor, ALARM = alarm_factor x WARN, lower WARN = margin x H- + floor
//      (K min): nothing recorded in normal running comes within `margin` of a WARN.
// The recordings must be normal running (no fault) and should contain what production does:
// warm-ups, stops, speed changes; a margin below 1 or recordings that miss a kind of transient
// give false alarms. The same replay checks hand-set thresholds (refuse_below_own_error).
#include "model_reference.hpp"
#include "recording.hpp"

#include "common/model_blob.hpp"

#include <array>
#include <string>
#include <vector>

namespace btsm::thermal {

struct DetectorRule {
  double drift_fraction = 0.75;       // 1, drift = this x the worst |residual|
  double drift_floor_K = 0.05;        // K, smallest drift (sensor noise, Kalman lag)
  double margin = 1.5;                // 1, WARN = margin x the worst upper evidence + floor
  double alarm_factor = 2.0;          // 1, ALARM = this x WARN
  double evidence_floor_K_min = 0.5;  // K min, added to every threshold
  std::string describe() const;
};

struct ChannelCalibration {
  bool diagnosed = false;             // the channel has a model of its own and a recorded column
  std::string column;                 // recording column replayed
  std::size_t samples = 0;            // residuals used
  double worst_residual_K = 0;        // max |residual|
  double worst_above_K = 0;           // E+, measured above the model
  double worst_below_K = 0;           // E-, measured below the model
  double worst_high_K_min = 0;        // H+ with the chosen drift
  double worst_low_K_min = 0;         // H-
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

// The rule above. `model` supplies the abs limit and rise limit to keep (per channel); throws
// std::invalid_argument naming the recording and column when a mapped column is missing.
DetectorCalibration calibrate_detector(const ReducedModel& q, const ReducedModelF64& model,
                                       const std::vector<const Recording*>& recordings,
                                       const std::array<std::string, kModelChannels>& columns, const DetectorRule& rule);

// Writes the calibrated detectors into `model` (diagnosed channels only).
void apply_calibration(const DetectorCalibration& c, ReducedModelF64& model);

}  // namespace btsm::thermal
