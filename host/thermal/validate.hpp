#pragma once
// Validation of a fitted network against recordings: NMSE (paper A7), RMSE and max abs error per
// measured node and mode, and steady-state MAPE (paper A6) at the end of settled operating phases.
#include "network.hpp"
#include "recording.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace btsm::thermal {

struct ErrorMetrics {
  double nmse = 0;        // 1 - |x_ref - x|^2 / |x_ref - mean(x_ref)|^2
  double rmse_K = 0;
  double max_abs_K = 0;
  std::size_t count = 0;  // samples compared
};

struct SteadyStatePoint {
  double speed_rpm = 0;
  double stop_time_s = 0;
  Eigen::VectorXd measured_rise_K;   // per measurement, at the stop instant (extrapolated where needed)
  Eigen::VectorXd predicted_rise_K;  // model steady state at that speed
  Eigen::VectorXd ape_percent;       // |pred - meas| / |meas| * 100 per measurement
  double mape_percent = 0;           // mean over measurements (A6)
};

struct RecordingValidation {
  std::string source;
  Eigen::VectorXd initial_state_c;
  Eigen::MatrixXd predicted_c;                 // rows x nodes
  std::vector<ErrorMetrics> all;               // per measurement, all rows
  std::vector<ErrorMetrics> operating, cooling;// per measurement and mode (count 0 = no data)
  std::vector<SteadyStatePoint> steady;
  // The longest operating phase at one speed that ends in a stop, in slowest time constants (what a
  // steady state needs settled_time_constants of): why `steady` may be empty.
  double longest_phase_time_constants = 0, longest_phase_s = 0, longest_phase_rpm = 0;
};

struct ValidateOptions {
  // Initial state: least squares on the first `initial_rows` rows (a small ridge pulls directions
  // these rows cannot see towards ambient + mean measured rise). 0 = first samples only.
  std::size_t initial_rows = 120;
  double settled_time_constants = 5.0;   // an operating phase counts as steady after this many slowest tau
  std::size_t extrapolation_rows = 8;    // quadratic back-extrapolation window after the stop
  std::size_t averaging_rows = 12;       // mean of the last rows before the stop (measured nodes)
};

RecordingValidation validate_recording(const Network& net, const Eigen::VectorXd& params, const Recording& rec,
                                       const ValidateOptions& opts = {});
// Least-squares initial state over the first `rows` rows (see ValidateOptions::initial_rows).
Eigen::VectorXd estimate_initial_state(const Network& net, const Eigen::VectorXd& params, const Recording& rec,
                                       std::size_t rows);
// "" when every predicted temperature is finite and inside the range a recording may hold; else
// where the prediction first leaves it (time, speed, node, value): a model unstable at a speed the
// recording runs (its stability is checked at rest and at its reference speed only) diverges there,
// and its NaN rows would otherwise drop out of every metric unnoticed.
// When it leaves, the cause is told from the model at that row's speed: not stable there, or stable
// but heated further than kMaxSteadyRiseK from ambient (model_file.hpp).
std::string prediction_problem(const Network& net, const Eigen::VectorXd& params, const Eigen::MatrixXd& predicted_c,
                               const Recording& rec);
ErrorMetrics error_metrics(const Eigen::VectorXd& reference, const Eigen::VectorXd& predicted);  // NaN skipped

}  // namespace btsm::thermal
