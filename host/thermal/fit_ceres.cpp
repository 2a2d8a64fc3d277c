// Ceres variant of the fit's solver (see fit_ceres.hpp).
#include "fit_ceres.hpp"

#include <ceres/ceres.h>
#include <ceres/covariance.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <thread>

namespace btsm::thermal::fitting {
namespace {

// One run's residuals; Jacobians from the evaluator's forward sensitivities.
class RunResiduals final : public ceres::CostFunction {
 public:
  RunResiduals(const OutputErrorProblem& whole, std::size_t ri) : pr_(single_run(whole, ri)), ev_(pr_) {
    const Run& run = pr_.runs[0];
    int count = 0;
    for (std::size_t k = run.begin; k <= run.end; ++k)
      for (int c : run.cols) count += std::isfinite(run.rec->temp_c(static_cast<Eigen::Index>(k), c)) ? 1 : 0;
    set_num_residuals(count);
    mutable_parameter_block_sizes()->push_back(pr_.nf());
    if (pr_.estimate_x0) mutable_parameter_block_sizes()->push_back(pr_.n());
  }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    Eigen::VectorXd u(pr_.unknowns());
    u.head(pr_.nf()) = Eigen::Map<const Eigen::VectorXd>(parameters[0], pr_.nf());
    if (pr_.estimate_x0) u.tail(pr_.n()) = Eigen::Map<const Eigen::VectorXd>(parameters[1], pr_.n());
    double* jp = jacobians ? jacobians[0] : nullptr;
    double* jx = jacobians && pr_.estimate_x0 ? jacobians[1] : nullptr;
    ev_.run_residuals(0, u, residuals, jp, jx);
    return Eigen::Map<const Eigen::VectorXd>(residuals, num_residuals()).allFinite();
  }

 private:
  static OutputErrorProblem single_run(const OutputErrorProblem& whole, std::size_t ri) {
    OutputErrorProblem pr = whole;
    pr.runs = {whole.runs[ri]};
    pr.x0 = {whole.x0[ri]};
    pr.sum_c = kNaN;
    return pr;
  }
  mutable OutputErrorProblem pr_;
  mutable OutputErrorEvaluator ev_;
};

// The capacitance gauge as the same stiff residual the hand-written solver uses.
class GaugeResidual final : public ceres::CostFunction {
 public:
  explicit GaugeResidual(const OutputErrorProblem& pr) : pr_(pr) {
    set_num_residuals(1);
    mutable_parameter_block_sizes()->push_back(pr_.nf());
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const double* z = parameters[0];
    Eigen::VectorXd p = pr_.p;
    for (int j = 0; j < pr_.nf(); ++j) p[pr_.free[static_cast<std::size_t>(j)]] = pr_.tf[static_cast<std::size_t>(j)].to_p(z[j]);
    double sum = 0;
    for (const auto& nd : pr_.net->nodes) sum += p[nd.capacitance_param];
    constexpr double w = OutputErrorEvaluator::kGaugeWeight;
    residuals[0] = w * std::log(sum / pr_.sum_c);
    if (jacobians && jacobians[0]) {
      for (int j = 0; j < pr_.nf(); ++j) {
        jacobians[0][j] = 0;
        for (const auto& nd : pr_.net->nodes)
          if (nd.capacitance_param == pr_.free[static_cast<std::size_t>(j)])
            jacobians[0][j] += w * pr_.tf[static_cast<std::size_t>(j)].dp_dz(z[j]) / sum;
      }
    }
    return std::isfinite(residuals[0]);
  }

 private:
  OutputErrorProblem pr_;
};

}  // namespace

CeresOutcome ceres_levenberg_marquardt(OutputErrorProblem& pr, const LmOptions& opts, bool with_covariance) {
  CeresOutcome out;
  Eigen::VectorXd u = pack(pr);
  clamp_to_bounds(pr, u);
  Eigen::VectorXd z = u.head(pr.nf());
  std::vector<Eigen::VectorXd> x0 = pr.x0;
  ceres::Problem problem;
  problem.AddParameterBlock(z.data(), pr.nf());
  for (int j = 0; j < pr.nf(); ++j) {
    problem.SetParameterLowerBound(z.data(), j, pr.tf[static_cast<std::size_t>(j)].zmin);
    problem.SetParameterUpperBound(z.data(), j, pr.tf[static_cast<std::size_t>(j)].zmax);
  }
  for (std::size_t r = 0; r < pr.runs.size(); ++r) {
    auto* cost = new RunResiduals(pr, r);
    if (pr.estimate_x0) problem.AddResidualBlock(cost, nullptr, z.data(), x0[r].data());
    else problem.AddResidualBlock(cost, nullptr, z.data());
  }
  if (std::isfinite(pr.sum_c)) problem.AddResidualBlock(new GaugeResidual(pr), nullptr, z.data());

  ceres::Solver::Options so;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;  // DENSE_QR measured too: slower still
  so.max_num_iterations = opts.max_iterations;
  so.function_tolerance = opts.relative_tolerance;
  so.parameter_tolerance = 1e-10;
  so.num_threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  out.jacobian_evaluations = summary.num_jacobian_evaluations;
  out.residual_evaluations = summary.num_residual_evaluations;
  out.lm.iterations = summary.num_successful_steps + summary.num_unsuccessful_steps;
  out.lm.converged = summary.termination_type == ceres::CONVERGENCE;

  if (with_covariance) {
    ceres::Covariance::Options co;
    co.algorithm_type = ceres::DENSE_SVD;
    co.null_space_rank = -1;
    co.num_threads = so.num_threads;
    ceres::Covariance cov(co);
    std::vector<std::pair<const double*, const double*>> blocks{{z.data(), z.data()}};
    if (cov.Compute(blocks, &problem)) {
      out.covariance_z.resize(pr.nf(), pr.nf());
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> c(pr.nf(), pr.nf());
      cov.GetCovarianceBlock(z.data(), z.data(), c.data());
      out.covariance_z = c;
      out.covariance_ok = true;
    }
  }

  u.head(pr.nf()) = z;
  if (pr.estimate_x0)
    for (std::size_t r = 0; r < pr.runs.size(); ++r) u.segment(pr.nf() + static_cast<int>(r) * pr.n(), pr.n()) = x0[r];
  OutputErrorEvaluator evaluator(pr);
  out.lm.ev = evaluator.evaluate(u, true);  // leaves pr.p / pr.x0 at the solution; J^T J for the uncertainty
  out.lm.u = u;
  return out;
}

}  // namespace btsm::thermal::fitting
