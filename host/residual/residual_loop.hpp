#pragma once
// The closed loop: fit the base model, test its residuals, trace the unexplained heat, try the
// effect library, and attribute the residual to one effect, to "none" (white residual) or to
// "unexplained" (significant structure nothing in the library explains).
//
// Decision rule (an effect is claimed only if ALL hold, so a clean recording yields "none"):
//   * BIC on the fit recordings drops by at least `bic_margin` (parameters counted: free model
//     parameters + effect parameters + initial states),
//   * the check-recording RMSE improves by at least `check_improvement` (ratio before/after),
//   * the effect's key parameter differs from its "no effect" value by >= `param_z` sigma,
//   * with the effect, the check RMSE is at most `max_check_to_fit_ratio` x the fit RMSE (the
//     effect explains the check residual, not just a part of it).
// Among the claimed effects the one with the lowest check RMSE wins (BIC breaks ties).
#include "host/residual/effects.hpp"
#include "host/residual/residual_stats.hpp"
#include "host/thermal/fit.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"

#include <Eigen/Core>

#include <functional>
#include <string>
#include <vector>

namespace btsm::residual {

struct LoopOptions {
  double bic_margin = 10.0;          // required BIC decrease on the fit recordings
  double check_improvement = 1.25;   // required ratio check RMSE before / after
  double param_z = 3.0;              // required |key parameter| / sigma
  double max_check_to_fit_ratio = 5.0;  // after the effect, check RMSE must be <= this x fit RMSE
  double whiteness_p = 0.01;         // Ljung-Box level (Bonferroni-corrected over channels)
  double significant_rms_factor = 2.0;  // residual rms above this x noise sigma = significant structure
  double correlation_p = 1e-3;       // a candidate signal is "correlated" below this p-value
  // Heat effects are tried at this many nodes, most traced heat first. Not fewer than a spindle
  // network has nodes: a base fit that absorbs part of an effect can move the traced heat to the
  // neighbours (seen: heat into the housing traced to the shaft and the rear bearing).
  int max_heat_nodes = 4;
  int max_sensor_columns = 2;        // sensor_lag tried on the columns most correlated with their rate
  std::vector<EffectKind> effects;   // empty = the whole library
  bool fit_base = true;              // false: use the given parameter values as the base model
  double trace_step_s = 0;           // inverse-heat step for the trace; 0 = max(60 s, 10 samples)
  int max_iterations = 60;           // Levenberg-Marquardt iterations per screening fit
  int refine_candidates = 2;         // the best candidates (by BIC gain) are then refined ...
  int refine_iterations = 600;       // ... with this many iterations (also the base fit's budget)
  std::function<void(const std::string&)> progress;
};

struct ErrorMetrics {
  double rmse_k = 0;     // over all measured cells
  double nmse_min = 0;   // worst channel, NMSE = 1 - |e|^2 / |y - mean y|^2 (paper Eq. A7)
  double max_abs_k = 0;
  std::size_t cells = 0;
};

struct ChannelDiagnostics {
  std::string column, node;
  WhitenessTest all, operating, cooling;   // over fit + check residuals
  bool white = true;
  std::vector<CorrelationTest> correlations;  // significant ones, strongest first (<= 5)
};

struct NodeTrace {
  std::string node;
  double rms_w = 0;              // rms of the unexplained heat flow
  std::vector<double> time_s;    // step starts (first fit recording)
  std::vector<double> heat_w;
};

struct ParamReport {
  std::string name, unit;
  double value = 0, sigma = 0;
};

struct CandidateResult {
  std::string label;              // e.g. sensor_lag@T1
  std::string effect;             // library name
  std::vector<std::string> nodes;
  std::vector<ParamReport> params;
  ErrorMetrics fit, check;
  double aic = 0, bic = 0, delta_bic = 0;  // delta = base - candidate (> 0 favours the candidate)
  double check_factor = 0;                 // check rmse before / after
  double key_z = 0;
  bool accepted = false;
  std::string reason;                      // why accepted / rejected, or the error if the fit failed
  // the augmented model (for plots)
  thermal::Network net;
  Eigen::VectorXd values;
  int transient_node = -1;                 // virtual node of heat_source_transient (impulse input)
};

struct LoopResult {
  std::string effect;                 // library name, "none" or "unexplained"
  std::string label;                  // e.g. "sensor_lag@T1"
  std::vector<std::string> nodes;
  std::vector<ParamReport> params;    // of the chosen effect
  std::vector<std::string> correlated_signals;  // for "unexplained"
  std::string explanation;
  double noise_sigma_k = 0;
  ErrorMetrics before_fit, before_check, after_fit, after_check;
  thermal::FitResult base_fit;
  thermal::Network base_net;
  std::vector<std::string> columns;   // measured columns in order
  std::vector<ChannelDiagnostics> diagnostics;
  std::vector<NodeTrace> trace;
  std::vector<CandidateResult> candidates;
  int chosen = -1;                    // index into candidates
  // residuals (measured - model), per recording rows x columns: before and after
  std::vector<Eigen::MatrixXd> fit_resid_before, check_resid_before, fit_resid_after, check_resid_after;
  std::vector<Eigen::MatrixXd> check_model_before, check_model_after;  // model temperatures at the columns
  std::vector<Eigen::MatrixXd> check_distortion;  // sensor-side effects: probe - node temperature, K
  double seconds = 0;
};

// Throws std::invalid_argument on unusable input (no recordings, missing columns, ...).
LoopResult run_residual_loop(const thermal::Network& base, const Eigen::VectorXd& base_params,
                             const std::vector<thermal::Recording>& fit, const std::vector<thermal::Recording>& check,
                             const LoopOptions& opts = {});

// Model temperatures at the measured columns and residuals (measured - model) for one recording,
// with the initial state estimated by linear least squares (the response is affine in x0).
struct Evaluation {
  Eigen::MatrixXd model_c;     // rows x columns
  Eigen::MatrixXd residual_k;  // rows x columns, NaN where not measured
  Eigen::MatrixXd nodes_c;     // rows x nodes
  Eigen::VectorXd x0_c;
};
Evaluation evaluate_model(const thermal::Network& net, const Eigen::VectorXd& params, const thermal::Recording& rec,
                          const Eigen::MatrixXd* extra_heat_w = nullptr, const Eigen::VectorXd* x0_c = nullptr);

ErrorMetrics error_metrics(const std::vector<Eigen::MatrixXd>& residual_k, const std::vector<Eigen::MatrixXd>& measured_c);

}  // namespace btsm::residual
