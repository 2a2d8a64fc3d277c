#pragma once
// The fit's nonlinear least-squares solver: Levenberg-Marquardt on the normal equations of an
// OutputErrorProblem, with box bounds on the transformed parameters (variables at a bound whose
// descent direction points outside are held for the iteration).
#include "fit_output_error.hpp"

#include <Eigen/Core>

#include <vector>

namespace btsm::thermal::fitting {

struct LmOptions {
  int max_iterations = 60;            // iterations (Jacobian evaluations) of one solve
  double relative_tolerance = 1e-10;  // converged when the cost decreases less than this (relative)
  // Restarts with fresh damping while the cost still falls by more than 1e-6 (relative) and the
  // iteration budget lasts; 0 = a single solve.
  int restarts = 0;
};

struct LmOutcome {
  Evaluation ev;       // at the solution, with Jacobian
  Eigen::VectorXd u;   // the unknowns at the solution (see fit_output_error.hpp)
  int iterations = 0;  // over all restarts
  bool converged = false;
  // The cost (Evaluation::cost) at the end of each iteration, over all restarts: how fast
  // the solve was still descending when it stopped (fit.cpp's continuation past the budget).
  std::vector<double> cost_by_iteration;
};

// Solves from the problem's current values, which it leaves at the solution.
LmOutcome levenberg_marquardt(OutputErrorProblem& pr, const LmOptions& opts);

}  // namespace btsm::thermal::fitting
