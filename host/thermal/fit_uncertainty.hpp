#pragma once
// Parameter uncertainty and identifiability at the fit's solution: the Gauss-Newton covariance of
// the final stage (scaled normal matrix, pseudo-inverse), 1 sigma per parameter, the
// identifiability verdict from the relative sigma, strong correlations and the weakest direction.
#include "fit.hpp"
#include "fit_levenberg_marquardt.hpp"

#include <vector>

namespace btsm::thermal::fitting {

// Fills res.residual_sigma_K, res.condition_number, res.covariance, res.estimates and the
// identifiability warnings from the final stage `fin` of problem `pr` (res.params already set).
void estimate_uncertainty(const Network& net, const std::vector<bool>& held, const OutputErrorProblem& pr,
                          const LmOutcome& fin, const FitOptions& opts, FitResult& res);

}  // namespace btsm::thermal::fitting
