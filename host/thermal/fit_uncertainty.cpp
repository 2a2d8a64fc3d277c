// Parameter uncertainty and identifiability of the fit (see fit_uncertainty.hpp).
#include "fit_uncertainty.hpp"

#include "fit_support.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>

namespace btsm::thermal::fitting {

int residual_correlation_rows(const Eigen::MatrixXd& residuals) {
  const Eigen::Index rows = residuals.rows();
  int widest = 0;
  for (Eigen::Index c = 0; c < residuals.cols(); ++c) {
    double mean = 0;
    int count = 0;
    for (Eigen::Index k = 0; k < rows; ++k)
      if (std::isfinite(residuals(k, c))) { mean += residuals(k, c); ++count; }
    if (count < 8) continue;
    mean /= count;
    Eigen::VectorXd x(rows);  // centred, missing cells 0 (they add nothing to the sums)
    for (Eigen::Index k = 0; k < rows; ++k) x[k] = std::isfinite(residuals(k, c)) ? residuals(k, c) - mean : 0.0;
    const double c0 = x.squaredNorm();
    if (!(c0 > 0)) continue;
    auto rho = [&](Eigen::Index lag) { return x.head(rows - lag).dot(x.tail(rows - lag)) / c0; };
    // Geyer's initial positive sequence: the lags while the sum of neighbouring pairs stays positive.
    int lag = 0;
    for (Eigen::Index l = 1; l + 1 < rows / 4; l += 2) {
      if (rho(l) + rho(l + 1) <= 0) break;
      lag = static_cast<int>(l + 1);
    }
    widest = std::max(widest, lag);
  }
  return widest;
}

Eigen::MatrixXd long_run_covariance(const Eigen::MatrixXd& scores, int bandwidth_rows) {
  // h_t = sum_l (1 - |l|/(L+1)) g_{t+l} is the triangle-weighted sum, computed as two running box
  // sums of width L+1 (a triangle is a box convolved with a box), so the cost does not grow with L.
  const Eigen::Index rows = scores.rows(), cols = scores.cols();
  const Eigen::Index w = bandwidth_rows + 1;
  Eigen::MatrixXd prefix = Eigen::MatrixXd::Zero(rows + 1, cols);
  for (Eigen::Index t = 0; t < rows; ++t) prefix.row(t + 1) = prefix.row(t) + scores.row(t);
  Eigen::MatrixXd box = Eigen::MatrixXd::Zero(rows + w, cols);  // box[t] = sum g[t-L .. t]
  for (Eigen::Index t = 0; t < rows + w - 1; ++t)
    box.row(t) = prefix.row(std::min(t + 1, rows)) - prefix.row(std::max<Eigen::Index>(0, t - w + 1));
  Eigen::MatrixXd box_prefix = Eigen::MatrixXd::Zero(rows + w + 1, cols);
  for (Eigen::Index t = 0; t < rows + w; ++t) box_prefix.row(t + 1) = box_prefix.row(t) + box.row(t);
  Eigen::MatrixXd h(rows, cols);  // sum box[t .. t+L] / (L+1)
  for (Eigen::Index t = 0; t < rows; ++t) h.row(t) = (box_prefix.row(t + w) - box_prefix.row(t)) / static_cast<double>(w);
  Eigen::MatrixXd m = scores.transpose() * h;
  return 0.5 * (m + m.transpose());
}

Eigen::MatrixXd scores_summed_over_runs(const std::vector<Eigen::MatrixXd>& run_scores, int shared, int per_run) {
  Eigen::Index rows = 0;
  for (const auto& g : run_scores) rows = std::max(rows, g.rows());
  const int runs = static_cast<int>(run_scores.size());
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(rows, shared + runs * per_run);
  for (int r = 0; r < runs; ++r) {
    const Eigen::MatrixXd& g = run_scores[static_cast<std::size_t>(r)];
    sum.block(0, 0, g.rows(), shared) += g.leftCols(shared);
    if (per_run > 0) sum.block(0, shared + r * per_run, g.rows(), per_run) += g.rightCols(per_run);
  }
  return sum;
}

void estimate_uncertainty(const Network& net, const std::vector<bool>& held, const OutputErrorProblem& pr,
                          const LmOutcome& fin, const FitOptions& opts, FitResult& res) {
  const int np = net.param_count();
  const int nu = pr.unknowns();
  const double dof = static_cast<double>(fin.ev.count) - nu;
  const double s2 = dof > 0 ? fin.ev.ssr / dof : kNaN;
  res.residual_sigma_K = std::sqrt(s2);

  // ---- covariance (scaled normal matrix, pseudo-inverse) and identifiability
  Eigen::VectorXd dsc(nu);
  for (int i = 0; i < nu; ++i) dsc[i] = fin.ev.H(i, i) > 0 ? 1.0 / std::sqrt(fin.ev.H(i, i)) : 1.0;
  const Eigen::MatrixXd Hs = dsc.asDiagonal() * fin.ev.H * dsc.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Hs);
  const Eigen::VectorXd lam = es.eigenvalues();
  const double lmax = lam.maxCoeff();
  res.condition_number = lam.minCoeff() > 0 ? lmax / lam.minCoeff() : std::numeric_limits<double>::infinity();
  Eigen::VectorXd lam_inv(nu);
  for (int i = 0; i < nu; ++i) lam_inv[i] = lam[i] > 1e-14 * lmax ? 1.0 / lam[i] : 0.0;
  const Eigen::MatrixXd h_inv =
      dsc.asDiagonal() * (es.eigenvectors() * lam_inv.asDiagonal() * es.eigenvectors().transpose()) * dsc.asDiagonal();
  Eigen::MatrixXd cov_z = h_inv * s2;
  res.correlation_rows.assign(pr.runs.size(), 0);
  res.sigma_method = "1 sigma from the Gauss-Newton covariance scaled by the residual variance (assumes white residuals)";
  if (opts.correlated_residuals) {
    // Sandwich H^-1 M H^-1 with M the long-run covariance of the scores J^T r: residuals that
    // stay on one side for hours carry far less information than their count says. Recordings of
    // one protocol (warm-up, stop, cooling) leave the same misfit at the same time since their
    // start, so the runs' scores are summed row by row before the Bartlett sum (Driscoll-Kraay):
    // summing each run's long-run covariance alone would treat that repeated misfit as independent
    // evidence and claim up to sqrt(runs) times the precision.
    OutputErrorProblem at = pr;
    OutputErrorEvaluator evaluator(at);
    std::vector<Eigen::MatrixXd> scores;
    int bandwidth = 0;
    for (std::size_t r = 0; r < pr.runs.size(); ++r) {
      res.correlation_rows[r] = residual_correlation_rows(res.residuals_K[r]);
      bandwidth = std::max(bandwidth, res.correlation_rows[r]);
      scores.push_back(evaluator.row_scores(r, fin.u));
    }
    const int per_run = pr.estimate_x0 ? pr.n() : 0;
    const int nf = pr.nf();
    Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(nu, nu);
    if (opts.sum_scores_over_runs) {
      meat = long_run_covariance(scores_summed_over_runs(scores, nf, per_run), bandwidth);
    } else {
      for (std::size_t r = 0; r < scores.size(); ++r) {  // each run alone, its own bandwidth
        const Eigen::MatrixXd m = long_run_covariance(scores[r], res.correlation_rows[r]);
        meat.topLeftCorner(nf, nf) += m.topLeftCorner(nf, nf);
        if (per_run > 0) {
          const int off = nf + static_cast<int>(r) * per_run;
          meat.block(off, off, per_run, per_run) += m.bottomRightCorner(per_run, per_run);
          meat.block(0, off, nf, per_run) += m.topRightCorner(nf, per_run);
          meat.block(off, 0, per_run, nf) += m.bottomLeftCorner(per_run, nf);
        }
      }
    }
    const double small_sample = dof > 0 ? static_cast<double>(fin.ev.count) / dof : 1.0;
    cov_z = h_inv * meat * h_inv * small_sample;
    res.sigma_method = opts.sum_scores_over_runs
                           ? "1 sigma from the sandwich covariance H^-1 M H^-1, M the Bartlett long-run covariance of the "
                             "scores summed over the recordings at each time since their start (Driscoll-Kraay), bandwidth "
                             "the widest residual autocorrelation (fit.recordings[].residual_correlation_rows)"
                           : "1 sigma from the sandwich covariance H^-1 M H^-1, M the Bartlett long-run covariance of the "
                             "scores over each recording's residual autocorrelation (fit.recordings[].residual_correlation_rows)";
  }
  res.covariance = Eigen::MatrixXd::Zero(np, np);
  Eigen::VectorXd dpdz(pr.nf());
  for (int j = 0; j < pr.nf(); ++j) dpdz[j] = pr.tf[static_cast<std::size_t>(j)].dp_dz(fin.u[j]);
  for (int a = 0; a < pr.nf(); ++a)
    for (int b = 0; b < pr.nf(); ++b)
      res.covariance(pr.free[static_cast<std::size_t>(a)], pr.free[static_cast<std::size_t>(b)]) = dpdz[a] * dpdz[b] * cov_z(a, b);

  for (int i = 0; i < np; ++i) {
    const auto& par = net.params[static_cast<std::size_t>(i)];
    ParameterEstimate e;
    e.name = par.name;
    e.unit = par.unit;
    e.value = res.params[i];
    if (held[static_cast<std::size_t>(i)]) {
      e.status = Identifiability::Fixed;
      res.estimates.push_back(e);
      continue;
    }
    e.sigma = std::sqrt(std::max(0.0, res.covariance(i, i)));
    const double rel = std::abs(e.value) > 0 ? e.sigma / std::abs(e.value) : std::numeric_limits<double>::infinity();
    e.status = rel > opts.unidentifiable_relative_sigma ? Identifiability::NotIdentifiable
               : rel > opts.weak_relative_sigma       ? Identifiability::Weak
                                                      : Identifiability::Good;
    e.at_bound = e.value <= par.min * (1 + 1e-9) + 1e-300 || e.value >= par.max * (1 - 1e-9);
    std::string note;
    if (e.at_bound) note += "at its bound; ";
    if (e.status != Identifiability::Good) note += "1 sigma is " + fmt_double(100 * rel, 3) + " % of the value; ";
    for (int j = 0; j < np; ++j) {
      if (j == i || held[static_cast<std::size_t>(j)]) continue;
      const double den = std::sqrt(res.covariance(i, i) * res.covariance(j, j));
      const double rho = den > 0 ? res.covariance(i, j) / den : 0.0;
      if (std::abs(rho) > opts.correlation_warning)
        note += "correlation " + fmt_double(rho, 4) + " with " + net.params[static_cast<std::size_t>(j)].name + "; ";
    }
    e.note = note;
    res.estimates.push_back(e);
  }
  // singular-value view: the weakest direction of the scaled normal matrix and who makes it up
  {
    Eigen::Index imin = 0;
    lam.minCoeff(&imin);
    const Eigen::VectorXd vmin = es.eigenvectors().col(imin);
    std::string who;
    for (int j = 0; j < pr.nf(); ++j)
      if (std::abs(vmin[j]) > 0.3) who += " " + net.params[static_cast<std::size_t>(pr.free[static_cast<std::size_t>(j)])].name;
    if (lam[imin] < 1e-10 * lmax)
      res.warnings.push_back("near-singular direction (singular value ratio " + fmt_double(lam[imin] / lmax, 3) +
                             ") made up of:" + (who.empty() ? " initial states" : who));
    for (auto& e : res.estimates)
      if (e.status == Identifiability::NotIdentifiable)
        res.warnings.push_back("'" + e.name + "' is not identifiable from these recordings (value " + fmt_double(e.value) +
                               " " + e.unit + ", 1 sigma " + fmt_double(e.sigma, 3) + ")");
      else if (e.status == Identifiability::Weak)
        res.warnings.push_back("'" + e.name + "' is only weakly identified (1 sigma " + fmt_double(100 * e.sigma / std::abs(e.value), 3) + " %)");
  }}

}  // namespace btsm::thermal::fitting
