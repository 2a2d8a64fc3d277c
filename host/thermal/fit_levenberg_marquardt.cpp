// Levenberg-Marquardt for the fit (see fit_levenberg_marquardt.hpp).
#include "fit_levenberg_marquardt.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <utility>

namespace btsm::thermal::fitting {
namespace {

LmOutcome solve_once(OutputErrorProblem& pr, const LmOptions& opts) {
  OutputErrorEvaluator evaluator(pr);
  LmOutcome out;
  Eigen::VectorXd u = pack(pr);
  clamp_to_bounds(pr, u);
  Evaluation ev = evaluator.evaluate(u, true);
  double mu = 1e-3;
  for (int it = 0; it < opts.max_iterations; ++it) {
    out.iterations = it + 1;
    bool accepted = false;
    for (int attempt = 0; attempt < 12 && !accepted; ++attempt) {
      Eigen::MatrixXd A = ev.H;
      Eigen::VectorXd g = ev.g;
      for (Eigen::Index i = 0; i < A.rows(); ++i) A(i, i) += mu * std::max(ev.H(i, i), 1e-12);
      // Variables at a bound whose descent direction points outside stay put this iteration
      // (a clamped Gauss-Newton step is not a descent step in general).
      for (int j = 0; j < pr.nf(); ++j) {
        const Transform& t = pr.tf[static_cast<std::size_t>(j)];
        if ((u[j] <= t.zmin && g[j] > 0) || (u[j] >= t.zmax && g[j] < 0)) {
          A.row(j).setZero();
          A.col(j).setZero();
          A(j, j) = 1.0;
          g[j] = 0.0;
        }
      }
      Eigen::VectorXd delta = A.ldlt().solve(-g);
      if (!delta.allFinite()) {
        mu *= 10;
        continue;
      }
      Eigen::VectorXd un = u + delta;
      clamp_to_bounds(pr, un);
      const Evaluation trial = evaluator.evaluate(un, false);
      if (std::isfinite(trial.cost) && trial.cost < ev.cost) {
        const double rel = (ev.cost - trial.cost) / std::max(ev.cost, 1e-300);
        const double step = (un - u).cwiseAbs().maxCoeff();
        u = un;
        ev = evaluator.evaluate(u, true);
        mu = std::max(mu / 3.0, 1e-12);
        accepted = true;
        if (rel < opts.relative_tolerance || step < 1e-10) {
          out.converged = true;
        }
      } else {
        mu *= 4.0;
      }
    }
    out.cost_by_iteration.push_back(ev.cost);
    if (!accepted) {  // no decrease possible any more: at a (local) minimum
      out.converged = true;
      evaluator.evaluate(u, false);  // leave pr.p / pr.x0 at u
      break;
    }
    if (out.converged) break;
  }
  evaluator.apply(u);
  out.ev = std::move(ev);
  out.u = u;
  return out;
}

}  // namespace

LmOutcome levenberg_marquardt(OutputErrorProblem& pr, const LmOptions& opts) {
  LmOutcome o = solve_once(pr, opts);
  // Levenberg-Marquardt can stop in a curved valley with its damping grown so large that no
  // step is accepted, well before the minimum (seen: the demo's joint fit stopping at 0.215 K
  // where a second run from that point reached 0.167 K). A restart with fresh damping costs one
  // Jacobian when the point really is a minimum; restart while it still gains and budget is left.
  for (int restart = 0; restart < opts.restarts && o.converged && o.iterations < opts.max_iterations; ++restart) {
    LmOptions again = opts;
    again.max_iterations = opts.max_iterations - o.iterations;
    LmOutcome r = solve_once(pr, again);
    const bool gained = r.ev.ssr < o.ev.ssr * (1 - 1e-6);
    r.iterations += o.iterations;
    r.cost_by_iteration.insert(r.cost_by_iteration.begin(), o.cost_by_iteration.begin(), o.cost_by_iteration.end());
    o = std::move(r);
    if (!gained) break;
  }
  return o;
}

}  // namespace btsm::thermal::fitting
