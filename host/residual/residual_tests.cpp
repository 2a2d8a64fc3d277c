// Residual tests and heat trace of the residual loop (see residual_tests.hpp).
#include "host/residual/residual_tests.hpp"

#include "host/thermal/heat_inverse.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace btsm::residual {
namespace th = btsm::thermal;
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int kGap = 30;  // NaN rows between concatenated recordings so no lag crosses them

std::vector<double> concat_column(const std::vector<Eigen::MatrixXd>& mats, int col) {
  std::vector<double> v;
  for (const auto& m : mats) {
    if (!v.empty()) v.insert(v.end(), kGap, kNaN);
    for (Eigen::Index k = 0; k < m.rows(); ++k) v.push_back(m(k, col));
  }
  return v;
}

std::vector<double> concat_signal(const std::vector<std::vector<double>>& parts) {
  std::vector<double> v;
  for (const auto& p : parts) {
    if (!v.empty()) v.insert(v.end(), kGap, kNaN);
    v.insert(v.end(), p.begin(), p.end());
  }
  return v;
}

// Candidate explanatory signals for one recording (aligned with its rows).
std::vector<std::pair<std::string, std::vector<double>>> candidate_signals(const th::Network& net, const th::Recording& rec,
                                                                            const Eigen::MatrixXd& nodes_c,
                                                                            const std::vector<int>& measured_nodes) {
  const std::size_t rows = rec.rows();
  std::vector<std::pair<std::string, std::vector<double>>> s;
  s.emplace_back("speed_rpm", rec.speed_rpm);
  std::vector<double> since(rows), decay(rows), amb_rate(rows);
  double last_change = rec.time_s.front(), state = 0;
  for (std::size_t k = 0; k < rows; ++k) {
    if (k > 0 && rec.speed_rpm[k] != rec.speed_rpm[k - 1]) last_change = rec.time_s[k];
    since[k] = std::min(rec.time_s[k] - last_change, 4 * 3600.0);
    if (k > 0) {
      state *= std::exp(-(rec.time_s[k] - rec.time_s[k - 1]) / 1800.0);
      state += std::max(0.0, rec.speed_rpm[k] - rec.speed_rpm[k - 1]) / 1000.0;
    }
    decay[k] = state;
    const std::size_t a = k > 0 ? k - 1 : k, b = k + 1 < rows ? k + 1 : k;
    amb_rate[k] = b > a ? (rec.ambient_c[b] - rec.ambient_c[a]) / (rec.time_s[b] - rec.time_s[a]) * 3600.0 : 0.0;
  }
  s.emplace_back("time_since_speed_change_s", since);
  s.emplace_back("speed_increase_decay_30min", decay);
  s.emplace_back("ambient_c", rec.ambient_c);
  s.emplace_back("ambient_rate_K_per_h", amb_rate);
  for (int i = 0; i < net.node_count(); ++i) {
    std::vector<double> theta(rows), rate(rows);
    for (std::size_t k = 0; k < rows; ++k) {
      theta[k] = nodes_c(k, i) - rec.ambient_c[k];
      const std::size_t a = k > 0 ? k - 1 : k, b = k + 1 < rows ? k + 1 : k;
      rate[k] = b > a ? (nodes_c(b, i) - nodes_c(a, i)) / (rec.time_s[b] - rec.time_s[a]) * 3600.0 : 0.0;
    }
    s.emplace_back("theta_" + net.nodes[i].name, theta);
    s.emplace_back("rate_" + net.nodes[i].name + "_K_per_h", rate);
  }
  for (std::size_t a = 0; a < measured_nodes.size(); ++a)
    for (std::size_t b = a + 1; b < measured_nodes.size(); ++b) {
      const int i = measured_nodes[a], j = measured_nodes[b];
      if (i == j) continue;
      std::vector<double> d(rows);
      for (std::size_t k = 0; k < rows; ++k) d[k] = nodes_c(k, i) - nodes_c(k, j);
      s.emplace_back("theta_" + net.nodes[i].name + "-" + net.nodes[j].name, d);
    }
  return s;
}

}  // namespace

ResidualTestsResult test_residuals(const th::Network& base, const std::vector<th::Recording>& fit,
                                   const std::vector<th::Recording>& check, const std::vector<Eigen::MatrixXd>& nodes_fit,
                                   const std::vector<Eigen::MatrixXd>& nodes_check, const std::vector<Eigen::MatrixXd>& resid_fit,
                                   const std::vector<Eigen::MatrixXd>& resid_check, double whiteness_p, double correlation_p) {
  ResidualTestsResult out;
  const int nc = static_cast<int>(base.measurements.size());
  std::vector<int> measured_nodes;
  for (const auto& m : base.measurements) measured_nodes.push_back(m.node);
  std::vector<std::vector<std::pair<std::string, std::vector<double>>>> sig_parts;
  for (std::size_t r = 0; r < fit.size(); ++r) sig_parts.push_back(candidate_signals(base, fit[r], nodes_fit[r], measured_nodes));
  for (std::size_t r = 0; r < check.size(); ++r) sig_parts.push_back(candidate_signals(base, check[r], nodes_check[r], measured_nodes));
  std::vector<Eigen::MatrixXd> all_res = resid_fit;
  all_res.insert(all_res.end(), resid_check.begin(), resid_check.end());
  std::vector<std::vector<double>> speed_parts;
  for (const auto& r : fit) speed_parts.push_back(r.speed_rpm);
  for (const auto& r : check) speed_parts.push_back(r.speed_rpm);
  const std::vector<double> speed_all = concat_signal(speed_parts);
  for (int c = 0; c < nc; ++c) {
    ChannelDiagnostics d;
    d.column = base.measurements[static_cast<std::size_t>(c)].column;
    d.node = base.nodes[static_cast<std::size_t>(base.measurements[static_cast<std::size_t>(c)].node)].name;
    const std::vector<double> e = concat_column(all_res, c);
    d.all = ljung_box(e);
    std::vector<double> eo = e, ec = e;
    for (std::size_t k = 0; k < e.size(); ++k) {
      if (!std::isfinite(speed_all[k])) continue;
      (base.mode_at(speed_all[k]) == th::Mode::Operating ? ec : eo)[k] = kNaN;
    }
    d.operating = ljung_box(eo);
    d.cooling = ljung_box(ec);
    d.white = !(d.all.p_value < whiteness_p / nc);
    out.all_white = out.all_white && d.white;
    const std::size_t nsig = sig_parts[0].size();
    for (std::size_t s = 0; s < nsig; ++s) {
      std::vector<std::vector<double>> parts;
      for (const auto& p : sig_parts) parts.push_back(p[s].second);
      const CorrelationTest t = correlation_test(sig_parts[0][s].first, e, concat_signal(parts));
      if (t.p_value < correlation_p) d.correlations.push_back(t);
    }
    std::sort(d.correlations.begin(), d.correlations.end(), [](const auto& a, const auto& b) { return std::abs(a.r) > std::abs(b.r); });
    if (d.correlations.size() > 5) d.correlations.resize(5);
    out.diagnostics.push_back(d);
  }
  return out;
}

std::vector<NodeTrace> trace_unexplained_heat(const th::Network& base, const Eigen::VectorXd& params, const th::Recording& rec,
                                              const Eigen::VectorXd& x0, double step_s, double noise_sigma_k) {
  std::vector<int> trace_nodes;
  for (const auto& m : base.measurements)
    if (std::find(trace_nodes.begin(), trace_nodes.end(), m.node) == trace_nodes.end()) trace_nodes.push_back(m.node);
  std::sort(trace_nodes.begin(), trace_nodes.end());
  th::InverseProblem ip = th::make_inverse_problem(base, params, rec, trace_nodes, true);
  ip.initial_state_c = x0;
  th::HeatInverseOptions ho;
  std::vector<double> dts;
  for (std::size_t k = 1; k < rec.rows(); ++k) dts.push_back(rec.time_s[k] - rec.time_s[k - 1]);
  std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2), dts.end());
  ho.step_s = step_s > 0 ? step_s : std::max(60.0, 10.0 * dts[dts.size() / 2]);
  ho.scheme = th::Discretisation::ExactZoh;
  ho.alpha_points = 25;
  // the loop's noise level (pooled over the fit recordings): one recording's own estimate can be
  // zero when it holds still long enough at the probes' quantisation
  ho.noise_sigma_k = std::max(noise_sigma_k, 1e-5);
  const th::HeatInverseResult hr = th::solve_heat_inverse(ip, ho);
  std::vector<NodeTrace> out;
  for (std::size_t j = 0; j < trace_nodes.size(); ++j) {
    NodeTrace t;
    t.node = base.nodes[static_cast<std::size_t>(trace_nodes[j])].name;
    t.time_s = hr.piece_start_s;
    const auto jj = static_cast<Eigen::Index>(j);
    for (Eigen::Index i = 0; i < hr.heat_w.rows(); ++i) t.heat_w.push_back(hr.heat_w(i, jj));
    t.rms_w = std::sqrt(hr.heat_w.col(jj).squaredNorm() / static_cast<double>(std::max<Eigen::Index>(1, hr.heat_w.rows())));
    out.push_back(t);
  }
  return out;
}

}  // namespace btsm::residual
