#pragma once
// The same output-error problem solved by Ceres (Levenberg-Marquardt trust region, box bounds on
// the transformed parameters, one residual block per run evaluated on all cores, covariance by
// ceres::Covariance). Kept beside the hand-written solver only to decide between them with numbers.
#include "fit_levenberg_marquardt.hpp"

#include <Eigen/Core>

namespace btsm::thermal::fitting {

struct CeresOutcome {
  LmOutcome lm;                    // ev (with J^T J from our evaluator at the solution), u, iterations, converged
  int jacobian_evaluations = 0;
  int residual_evaluations = 0;
  Eigen::MatrixXd covariance_z;    // of the transformed free parameters, unit residual variance (ceres::Covariance)
  bool covariance_ok = false;
};

CeresOutcome ceres_levenberg_marquardt(OutputErrorProblem& pr, const LmOptions& opts, bool with_covariance);

}  // namespace btsm::thermal::fitting
