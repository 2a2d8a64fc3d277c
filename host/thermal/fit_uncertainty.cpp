// Parameter uncertainty and identifiability of the fit (see fit_uncertainty.hpp).
#include "fit_uncertainty.hpp"

#include "fit_support.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>

namespace btsm::thermal::fitting {

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
  const Eigen::MatrixXd cov_z = dsc.asDiagonal() * (es.eigenvectors() * lam_inv.asDiagonal() * es.eigenvectors().transpose()) *
                                dsc.asDiagonal() * s2;
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
