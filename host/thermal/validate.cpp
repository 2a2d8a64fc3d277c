// Validation metrics. NMSE follows the paper's A7, MAPE its A6 (on rises above ambient).
#include "validate.hpp"

#include "fit.hpp"
#include "simulator.hpp"
#include "network.hpp"
#include "model_file.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>

#include <cstdio>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace btsm::thermal {
namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}

ErrorMetrics error_metrics(const Eigen::VectorXd& ref, const Eigen::VectorXd& pred) {
  ErrorMetrics m;
  double sum = 0;
  for (Eigen::Index i = 0; i < ref.size(); ++i)
    if (std::isfinite(ref[i]) && std::isfinite(pred[i])) { sum += ref[i]; ++m.count; }
  if (m.count == 0) { m.nmse = kNaN; m.rmse_K = kNaN; m.max_abs_K = kNaN; return m; }
  const double mean = sum / static_cast<double>(m.count);
  double se = 0, sv = 0;
  for (Eigen::Index i = 0; i < ref.size(); ++i) {
    if (!(std::isfinite(ref[i]) && std::isfinite(pred[i]))) continue;
    const double e = pred[i] - ref[i];
    se += e * e;
    sv += (ref[i] - mean) * (ref[i] - mean);
    m.max_abs_K = std::max(m.max_abs_K, std::abs(e));
  }
  m.rmse_K = std::sqrt(se / static_cast<double>(m.count));
  // A constant reference has no variance to normalise by; rounding of the mean leaves ~1e-25 K^2 of
  // it for some constants (-273.15 gave an NMSE of -9.9e27), so "constant" is a spread below 1 nK.
  constexpr double kNoSpreadK = 1e-9;
  m.nmse = sv > static_cast<double>(m.count) * kNoSpreadK * kNoSpreadK ? 1.0 - se / sv : kNaN;
  return m;
}

Eigen::VectorXd estimate_initial_state(const Network& net, const Eigen::VectorXd& params, const Recording& rec,
                                       std::size_t rows) {
  const Eigen::VectorXd guess = first_sample_state(net, rec);
  if (rows <= 1) return guess;
  rows = std::min(rows, rec.rows());
  Recording head = rec;
  head.time_s.resize(rows);
  head.speed_rpm.resize(rows);
  head.ambient_c.resize(rows);
  head.temp_c = rec.temp_c.topRows(static_cast<Eigen::Index>(rows)).eval();
  const int n = net.node_count();
  // The response is affine in x0: r(x0) = r(guess) + F (x0 - guess); F from unit perturbations.
  const Eigen::MatrixXd r0 = prediction_residuals(net, params, head, guess);
  std::vector<Eigen::MatrixXd> cols;
  for (int i = 0; i < n; ++i) {
    Eigen::VectorXd x = guess;
    x[i] += 1.0;
    cols.push_back(prediction_residuals(net, params, head, x) - r0);
  }
  Eigen::MatrixXd FtF = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd Ftr = Eigen::VectorXd::Zero(n);
  for (Eigen::Index k = 0; k < r0.rows(); ++k)
    for (Eigen::Index m = 0; m < r0.cols(); ++m) {
      if (!std::isfinite(r0(k, m))) continue;
      Eigen::VectorXd f(n);
      for (int i = 0; i < n; ++i) f[i] = cols[static_cast<std::size_t>(i)](k, m);
      FtF += f * f.transpose();
      Ftr += f * r0(k, m);
    }
  // Bayesian ridge: the data (noise sigma from the residuals of the first-sample start, at least
  // 2 mK) against a prior at the first-sample guess, 0.02 K for nodes not measured in row 0 (their
  // start is mostly invisible: an unmeasured shaft's transient decays within minutes).
  std::size_t cnt = 0;
  double ss = 0;
  for (Eigen::Index k = 0; k < r0.rows(); ++k)
    for (Eigen::Index m = 0; m < r0.cols(); ++m)
      if (std::isfinite(r0(k, m))) { ss += r0(k, m) * r0(k, m); ++cnt; }
  const double sn = std::max(0.002, cnt ? std::sqrt(ss / static_cast<double>(cnt)) : 0.0);
  const auto cols_m = measurement_columns(net, rec);
  Eigen::VectorXd prior_sigma = Eigen::VectorXd::Constant(n, 0.02);
  for (std::size_t m = 0; m < cols_m.size(); ++m)
    if (std::isfinite(rec.temp_c(0, cols_m[m]))) prior_sigma[net.measurements[m].node] = 1.0;  // data decide
  Eigen::MatrixXd A = FtF / (sn * sn);
  A.diagonal() += prior_sigma.cwiseAbs2().cwiseInverse();
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(A);
  Eigen::VectorXd x = guess - ldlt.solve(Ftr / (sn * sn));
  // Second pass: the prior of each unmeasured node becomes its quasi-static value given the
  // estimated neighbours and ambient (weights = the conductances at row 0's speed).
  const NodeMatrices m0 = assemble(net, params, rec.speed_rpm[0]);
  Eigen::VectorXd prior = guess;
  for (int i = 0; i < n; ++i) {
    if (prior_sigma[i] >= 1.0) continue;
    double num = m0.ambient_conductance[i] * rec.ambient_c[0], den = m0.ambient_conductance[i];
    for (int j = 0; j < n; ++j)
      if (j != i) { num += -m0.G(i, j) * x[j]; den += -m0.G(i, j); }
    if (den > 0) prior[i] = num / den;
  }
  // minimise |r0 + F (x - guess)|^2 / sn^2 + |(x - prior) / sigma_p|^2
  const Eigen::VectorXd w = prior_sigma.cwiseAbs2().cwiseInverse();
  return guess + ldlt.solve(-Ftr / (sn * sn) + w.cwiseProduct(prior - guess));
}

std::string prediction_problem(const Network& net, const Eigen::VectorXd& params, const Eigen::MatrixXd& predicted_c,
                               const Recording& rec) {
  for (Eigen::Index k = 0; k < predicted_c.rows(); ++k)
    for (Eigen::Index n = 0; n < predicted_c.cols(); ++n) {
      const double t = predicted_c(k, n);
      if (std::isfinite(t) && t >= kMinRecordedTempC && t <= kMaxRecordedTempC) continue;
      const auto r = static_cast<std::size_t>(k);
      // row k's state comes from the interval before it, run at that row's speed
      const double speed = r < rec.rows() ? rec.speed_rpm[r > 0 ? r - 1 : 0] : NAN;
      char value[32];
      std::snprintf(value, sizeof value, "%.4g degC", t);
      char where[96];
      std::snprintf(where, sizeof where, "t = %.6g s (%.0f rpm)", r < rec.rows() ? rec.time_s[r] : NAN,
                    r < rec.rows() ? rec.speed_rpm[r] : NAN);
      // Why, told apart: a network unstable at this speed (its stability is checked at rest and at
      // the reference speed only), or a stable one whose heat settles it absurdly far from ambient
      // (a 5 MW source was called "not stable ... heat growing faster than it flows away").
      std::string why = " (the network is not stable at the speeds this recording runs, or a heat source or resistance is far out of range)";
      if (std::isfinite(speed) && params.size() == net.param_count()) {
        if (const std::string unstable = instability_at(net, params, speed); !unstable.empty())
          why = ": " + unstable;
        else if (const std::string rise = steady_rise_problem(net, params, speed); !rise.empty())
          why = ": " + rise;
      }
      return "the model's prediction diverges: node '" + net.nodes[static_cast<std::size_t>(n)].name + "' at " + where + " is " +
             (std::isfinite(t) ? std::string(value) : std::string("not finite")) + why;
    }
  return "";
}

RecordingValidation validate_recording(const Network& net, const Eigen::VectorXd& params, const Recording& rec,
                                       const ValidateOptions& opts) {
  RecordingValidation v;
  v.source = rec.source;
  const auto cols = measurement_columns(net, rec);
  // Metrics need two values of one measured column at least; with less every figure is NaN.
  bool comparable = false;
  for (const int c : cols)
    comparable = comparable || (rec.temp_c.col(c).array().isFinite().count() >= 2);
  if (!comparable)
    throw std::invalid_argument(rec.source + ": nothing to validate against: no measured column has two temperature values (" +
                                std::to_string(rec.rows()) + " rows)");
  v.initial_state_c = estimate_initial_state(net, params, rec, opts.initial_rows);
  v.predicted_c = simulate_recording(net, params, rec, v.initial_state_c);
  if (const std::string problem = prediction_problem(net, params, v.predicted_c, rec); !problem.empty())
    throw std::invalid_argument(rec.source + ": " + problem);
  const auto rows = static_cast<Eigen::Index>(rec.rows());
  for (std::size_t m = 0; m < cols.size(); ++m) {
    const Eigen::VectorXd meas = rec.temp_c.col(cols[m]);
    Eigen::VectorXd pred = v.predicted_c.col(net.measurements[m].node);
    if (const int d = net.measurements[m].drift_param; d >= 0) {
      // A drifting probe reads its node + drift x hours + its own offset in this recording (the
      // least-squares constant, as fit and residual take it): scored without it, a 1e10 K/h drift
      // scored like none while heat and residual applied it (probe 5).
      for (Eigen::Index k = 0; k < rows; ++k)
        pred[k] += params[d] * (rec.time_s[static_cast<std::size_t>(k)] - rec.time_s.front()) / 3600.0;
      pred.array() += drift_offset_k(meas - pred);
    }
    v.all.push_back(error_metrics(meas, pred));
    Eigen::VectorXd mo = meas, mc = meas;
    for (Eigen::Index k = 0; k < rows; ++k) {
      // row k's state belongs to the mode that produced it (the interval before it); row 0 to its own
      const std::size_t src = static_cast<std::size_t>(k > 0 ? k - 1 : 0);
      if (net.mode_at(rec.speed_rpm[src]) == Mode::Operating) mc[k] = kNaN; else mo[k] = kNaN;
    }
    v.operating.push_back(error_metrics(mo, pred));
    v.cooling.push_back(error_metrics(mc, pred));
  }
  // Steady states: operating phases at one speed, long enough, followed by a stop.
  std::size_t b = 0;
  const std::size_t nrows = rec.rows();
  while (b < nrows) {
    if (net.mode_at(rec.speed_rpm[b]) != Mode::Operating) { ++b; continue; }
    std::size_t e = b;
    while (e + 1 < nrows && rec.speed_rpm[e + 1] == rec.speed_rpm[b]) ++e;
    const std::size_t stop = e + 1;  // first row after the phase
    if (stop < nrows && net.mode_at(rec.speed_rpm[stop]) == Mode::Cooling) {
      const double speed = rec.speed_rpm[b];
      const double slowest = -poles_per_s(net, params, speed).maxCoeff();
      const double duration = rec.time_s[stop] - rec.time_s[b];
      if (slowest > 0 && duration * slowest > v.longest_phase_time_constants) {
        v.longest_phase_time_constants = duration * slowest;
        v.longest_phase_s = duration;
        v.longest_phase_rpm = rec.speed_rpm[b];
      }
      if (slowest > 0 && duration * slowest >= opts.settled_time_constants) {
        SteadyStatePoint sp;
        sp.speed_rpm = speed;
        sp.stop_time_s = rec.time_s[stop];
        const double amb = rec.ambient_c[stop];
        const Eigen::VectorXd ss = steady_state_c(net, params, speed, amb);
        const auto nm = static_cast<Eigen::Index>(cols.size());
        sp.measured_rise_K.resize(nm);
        sp.predicted_rise_K.resize(nm);
        sp.ape_percent.resize(nm);
        double sum = 0;
        int cnt = 0;
        for (Eigen::Index m = 0; m < nm; ++m) {
          const int c = cols[static_cast<std::size_t>(m)];
          // measured before the stop: mean of the last rows up to the stop instant
          double acc = 0;
          std::size_t nacc = 0;
          for (std::size_t k = stop + 1 > opts.averaging_rows ? stop + 1 - opts.averaging_rows : 0; k <= stop; ++k)
            if (std::isfinite(rec.temp_c(static_cast<Eigen::Index>(k), c))) { acc += rec.temp_c(static_cast<Eigen::Index>(k), c) - rec.ambient_c[k]; ++nacc; }
          double meas = kNaN;
          if (nacc + 1 >= opts.averaging_rows) {
            meas = acc / static_cast<double>(nacc);
          } else {
            // probe inserted at/after the stop: quadratic fit over the first rows, back to the stop
            Eigen::MatrixXd A(0, 3);
            Eigen::VectorXd y(0);
            for (std::size_t k = stop; k < nrows && static_cast<std::size_t>(A.rows()) < opts.extrapolation_rows; ++k) {
              const double t = rec.temp_c(static_cast<Eigen::Index>(k), c);
              if (!std::isfinite(t)) continue;
              const double dt = rec.time_s[k] - rec.time_s[stop];
              A.conservativeResize(A.rows() + 1, 3);
              y.conservativeResize(y.size() + 1);
              A.row(A.rows() - 1) << 1.0, dt, dt * dt;
              y[y.size() - 1] = t - rec.ambient_c[k];
            }
            if (A.rows() >= 3) meas = A.colPivHouseholderQr().solve(y)[0];
          }
          sp.measured_rise_K[m] = meas;
          sp.predicted_rise_K[m] = ss[net.measurements[static_cast<std::size_t>(m)].node] - amb;
          sp.ape_percent[m] = std::abs(sp.predicted_rise_K[m] - meas) / std::abs(meas) * 100.0;
          if (std::isfinite(sp.ape_percent[m])) { sum += sp.ape_percent[m]; ++cnt; }
        }
        sp.mape_percent = cnt ? sum / cnt : kNaN;
        v.steady.push_back(sp);
      }
    }
    b = e + 1;
  }
  return v;
}

}  // namespace btsm::thermal
