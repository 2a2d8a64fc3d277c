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
// row scores g_t = J_t^T r_t with Bartlett weights over each recording's residual autocorrelation
// bandwidth (Newey-West). For white residuals the bandwidth is a few rows and sigma is the
// classical one.
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

// Fills res.residual_sigma_K, res.condition_number, res.covariance, res.estimates and the
// identifiability warnings from the final stage `fin` of problem `pr` (res.params and
// res.residuals_K, one per run, already set).
void estimate_uncertainty(const Network& net, const std::vector<bool>& held, const OutputErrorProblem& pr,
                          const LmOutcome& fin, const FitOptions& opts, FitResult& res);

}  // namespace btsm::thermal::fitting
