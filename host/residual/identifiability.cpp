// Evidence of what the fit recordings cannot decide (see identifiability.hpp).
#include "host/residual/identifiability.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace btsm::residual {
namespace th = btsm::thermal;

BaseConfounding base_confounding(const th::Network& net, int base_count, const th::FitResult& fr, const std::string& param) {
  BaseConfounding out;
  const int i = net.param_index(param);
  const Eigen::MatrixXd& cov = fr.covariance;
  if (i < 0 || i >= cov.rows() || !(cov(i, i) > 0)) return out;
  // the free base parameters (held ones have zero rows)
  std::vector<int> set{i};
  for (int j = 0; j < std::min<int>(base_count, static_cast<int>(cov.rows())); ++j) {
    if (!(cov(j, j) > 0)) continue;
    set.push_back(j);
    const double rho = cov(i, j) / std::sqrt(cov(i, i) * cov(j, j));
    if (std::abs(rho) > std::abs(out.pair_correlation)) {
      out.pair_correlation = rho;
      out.partner = net.params[static_cast<std::size_t>(j)].name;
    }
  }
  if (set.size() < 2) return out;
  // Conditional variance of the parameter given the base ones: 1 / (Sigma_S^-1)_00 over S = {i} +
  // base, on the correlation scale (the parameters' units differ by orders of magnitude). The
  // pseudo-inverse keeps an exactly singular base direction from producing infinities.
  const auto n = static_cast<Eigen::Index>(set.size());
  Eigen::MatrixXd corr(n, n);
  for (Eigen::Index a = 0; a < n; ++a)
    for (Eigen::Index b = 0; b < n; ++b) {
      const int pa = set[static_cast<std::size_t>(a)], pb = set[static_cast<std::size_t>(b)];
      corr(a, b) = cov(pa, pb) / std::sqrt(cov(pa, pa) * cov(pb, pb));
    }
  const Eigen::MatrixXd precision = corr.completeOrthogonalDecomposition().pseudoInverse();
  const double vif = precision(0, 0);  // = 1 / (1 - R^2) on the correlation scale
  if (std::isfinite(vif) && vif >= 1.0) {
    out.inflation = std::sqrt(vif);
    out.multiple_correlation = std::sqrt(std::max(0.0, 1.0 - 1.0 / vif));
  } else if (!std::isfinite(vif)) {
    out.inflation = std::numeric_limits<double>::infinity();
    out.multiple_correlation = 1.0;
  }
  return out;
}

TriggerCoverage trigger_coverage(const th::Network& net, const std::vector<th::Recording>& recs, TransientTrigger trigger, double tau_s,
                                 double active_share) {
  TriggerCoverage c;
  if (!(tau_s > 0)) return c;
  for (const auto& rec : recs) {
    const std::vector<double> u = transient_triggers(net, rec, trigger);
    double last_t = -1;  // a recording starts from standstill: no transient left from before it
    for (std::size_t k = 0; k < u.size(); ++k) {
      if (!(u[k] > 0)) continue;
      ++c.triggers;
      if (k > 0 && net.mode_at(rec.speed_rpm[k - 1]) == th::Mode::Operating) ++c.while_running;
      if (last_t >= 0) {
        const double left = std::exp(-(rec.time_s[k] - last_t) / tau_s);
        c.max_state = std::max(c.max_state, left);
        if (left > active_share) ++c.while_active;
      }
      last_t = rec.time_s[k];
    }
  }
  return c;
}

}  // namespace btsm::residual
