#pragma once
// Parameter uncertainty and identifiability at the fit's solution: the covariance of the final
// stage, 1 sigma per parameter, the identifiability verdict from the relative sigma, strong
// correlations and the weakest direction.
//
// Residuals of real recordings are not white: a model that misses a few seconds of sensor lag or
// a speed change between two samples leaves residuals that stay on one side for many minutes, and
// the classical s^2 (J^T J)^-1 then claims tens of times the precision the data hold (on simulated
// module recordings the truth lay up to 84 sigma away). So the covariance is the sandwich
// H^-1 M H^-1 (H = J^T J, pseudo-inverse on the scaled matrix), M the long-run covariance of the
// row scores g_t = J_t^T r_t with Bartlett weights (Newey-West) over the residual autocorrelation
// bandwidth. For white residuals the bandwidth is a few rows and sigma is the classical one.
//
// The recordings' scores are summed at each row since their start before the Bartlett sum
// (Driscoll & Kraay 1998, panels with cross-sectional dependence): the module's misfit (its
// Kalman filter lags the temperatures by ~3.6 s; a speed change falls between two samples) is the
// same response to the same protocol in every warm-up, so the runs' scores are correlated, and a
// per-run sum claimed up to sqrt(runs) too much precision. Measured over 12 simulated module
// experiments (tests/data/module-warmups/README.md): the truth within 1 / 2 sigma for 70 % / 95 %
// of the parameters (nominal 68 / 95 %), where the per-run sum gave 60 % / 89 %. Runs of other
// protocols stay valid (independent runs' cross terms average out), only less efficient.
#include "fit.hpp"
#include "fit_levenberg_marquardt.hpp"

#include <vector>

namespace btsm::thermal::fitting {

// Autocorrelation bandwidth of one run's residuals (rows x channels, NaN = missing) in rows: the
// widest over the channels of Geyer's initial positive sequence (the lags while rho(l) + rho(l+1)
// stays positive), at most a quarter of the rows. 0 for white residuals.
int residual_correlation_rows(const Eigen::MatrixXd& residuals);

// sum_t g_t h_t^T (symmetrised) with h_t = sum_{|l| <= L} (1 - |l|/(L+1)) g_{t+l}: the Bartlett
// (Newey-West) long-run covariance of a series of row scores g (rows x unknowns), L = bandwidth.
Eigen::MatrixXd long_run_covariance(const Eigen::MatrixXd& scores, int bandwidth_rows);

// The runs' score rows (rows x (shared + per_run)) summed row by row since each run's start into
// one series over all unknowns: the shared columns add up, each run's own per_run columns (its
// initial state) go to their block (shared + r * per_run). Shorter runs end early.
Eigen::MatrixXd scores_summed_over_runs(const std::vector<Eigen::MatrixXd>& run_scores, int shared, int per_run);

// Fills res.residual_sigma_K, res.condition_number, res.covariance, res.estimates and the
// identifiability warnings from the final stage `fin` of problem `pr` (res.params and
// res.residuals_K, one per run, already set).
void estimate_uncertainty(const Network& net, const std::vector<bool>& held, const OutputErrorProblem& pr,
                          const LmOutcome& fin, const FitOptions& opts, FitResult& res);

}  // namespace btsm::thermal::fitting
