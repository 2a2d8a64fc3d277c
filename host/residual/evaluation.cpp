// Model evaluation on recordings (see evaluation.hpp).
#include "host/residual/evaluation.hpp"

#include "host/thermal/column_map.hpp"
#include "host/thermal/fit.hpp"
#include "host/thermal/simulator.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>

namespace btsm::residual {
namespace th = btsm::thermal;
namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}

Evaluation evaluate_model(const th::Network& net, const Eigen::VectorXd& params, const th::Recording& rec,
                          const Eigen::MatrixXd* extra, const Eigen::VectorXd* x0_given, const std::vector<int>& rest) {
  Evaluation ev;
  const int n = net.node_count();
  Eigen::VectorXd x0;
  if (x0_given) {
    x0 = *x0_given;
  } else {
    // r(x0) = pred - meas is affine in x0: the least-squares initial state (a small ridge towards
    // the first-sample guess for nodes the data barely see); nodes at rest stay at the ambient
    Eigen::VectorXd guess = th::first_sample_state(net, rec);
    for (int i : rest) guess(i) = rec.ambient_c.front();
    const Eigen::MatrixXd r0 = th::prediction_residuals(net, params, rec, guess, extra);
    std::vector<Eigen::MatrixXd> cols;
    for (int i = 0; i < n; ++i) {
      if (std::find(rest.begin(), rest.end(), i) != rest.end()) {
        cols.push_back(Eigen::MatrixXd::Zero(r0.rows(), r0.cols()));
        continue;
      }
      Eigen::VectorXd xi = guess;
      xi(i) += 1.0;
      cols.push_back(th::prediction_residuals(net, params, rec, xi, extra) - r0);
    }
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(n);
    for (Eigen::Index k = 0; k < r0.size(); ++k) {
      if (!std::isfinite(r0.data()[k])) continue;
      for (int i = 0; i < n; ++i) {
        b(i) -= cols[i].data()[k] * r0.data()[k];
        for (int j = 0; j < n; ++j) A(i, j) += cols[i].data()[k] * cols[j].data()[k];
      }
    }
    A.diagonal().array() += 1e-9 * std::max(A.trace() / n, 1e-12);
    x0 = guess + A.ldlt().solve(b);
  }
  ev.x0_c = x0;
  ev.nodes_c = th::simulate_recording(net, params, rec, x0, extra);
  const std::vector<int> cols = th::measurement_columns(net, rec);
  const auto rows = static_cast<Eigen::Index>(rec.rows());
  ev.model_c.resize(rows, static_cast<Eigen::Index>(cols.size()));
  ev.residual_k.resize(rows, static_cast<Eigen::Index>(cols.size()));
  for (std::size_t j = 0; j < cols.size(); ++j) {
    const auto& m = net.measurements[j];
    const auto jj = static_cast<Eigen::Index>(j);
    ev.model_c.col(jj) = ev.nodes_c.col(m.node);
    if (m.drift_param >= 0)
      for (Eigen::Index k = 0; k < rows; ++k)
        ev.model_c(k, jj) += params[m.drift_param] * (rec.time_s[static_cast<std::size_t>(k)] - rec.time_s.front()) / 3600.0;
    for (Eigen::Index k = 0; k < rows; ++k) {
      const double y = rec.temp_c(k, cols[j]);
      ev.residual_k(k, jj) = std::isfinite(y) ? y - ev.model_c(k, jj) : kNaN;
    }
    if (m.drift_param >= 0) {
      // the drifting probe's offset at the recording's start: its least-squares value (the least-
      // squares initial state above saw the same offset removed: prediction_residuals)
      const double offset = th::drift_offset_k(ev.residual_k.col(jj));
      ev.model_c.col(jj).array() += offset;
      ev.residual_k.col(jj).array() -= offset;
    }
  }
  return ev;
}

ErrorMetrics error_metrics(const std::vector<Eigen::MatrixXd>& res, const std::vector<Eigen::MatrixXd>& meas) {
  ErrorMetrics m;
  double ss = 0;
  m.nmse_min = std::numeric_limits<double>::infinity();
  const Eigen::Index nc = res.empty() ? 0 : res[0].cols();
  for (Eigen::Index c = 0; c < nc; ++c) {
    double se = 0, sy = 0, syy = 0;
    std::size_t cnt = 0;
    for (std::size_t r = 0; r < res.size(); ++r)
      for (Eigen::Index k = 0; k < res[r].rows(); ++k) {
        const double e = res[r](k, c), y = meas[r](k, c);
        if (!std::isfinite(e) || !std::isfinite(y)) continue;
        se += e * e;
        sy += y;
        syy += y * y;
        ++cnt;
        m.max_abs_k = std::max(m.max_abs_k, std::abs(e));
      }
    if (cnt == 0) continue;
    ss += se;
    m.cells += cnt;
    const double var = syy - sy * sy / static_cast<double>(cnt);
    if (var > 0) m.nmse_min = std::min(m.nmse_min, 1.0 - se / var);
  }
  m.rmse_k = m.cells ? std::sqrt(ss / static_cast<double>(m.cells)) : kNaN;
  if (!std::isfinite(m.nmse_min)) m.nmse_min = kNaN;
  return m;
}

std::vector<Eigen::MatrixXd> measured_columns_of(const th::Network& net, const std::vector<th::Recording>& recs) {
  std::vector<Eigen::MatrixXd> out;
  for (const auto& r : recs) {
    const std::vector<int> cols = th::measurement_columns(net, r);
    Eigen::MatrixXd m(static_cast<Eigen::Index>(r.rows()), static_cast<Eigen::Index>(cols.size()));
    for (std::size_t j = 0; j < cols.size(); ++j) m.col(static_cast<Eigen::Index>(j)) = r.temp_c.col(cols[j]);
    out.push_back(m);
  }
  return out;
}

double sum_of_squares(const std::vector<Eigen::MatrixXd>& r, std::size_t& n) {
  double s = 0;
  n = 0;
  for (const auto& m : r)
    for (Eigen::Index i = 0; i < m.size(); ++i)
      if (std::isfinite(m.data()[i])) {
        s += m.data()[i] * m.data()[i];
        ++n;
      }
  return s;
}

double bic(double rss, std::size_t n, int k) {
  const double nn = static_cast<double>(std::max<std::size_t>(n, 1));
  return nn * std::log(std::max(rss, 1e-300) / nn) + k * std::log(nn);
}

}  // namespace btsm::residual
