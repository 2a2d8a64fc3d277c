// Balanced analysis in the modal basis and the module's per-channel first-order model.
#include "reduce.hpp"

#include "grid_golden_search.hpp"
#include "model_file.hpp"
#include "simulator.hpp"

#include "common/hex_text.hpp"
#include "common/model_step.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

namespace btsm::thermal {
namespace {

// Symmetric square root factor L (P = L L^T) of a PSD matrix.
Eigen::MatrixXd psd_factor(const Eigen::MatrixXd& P) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(P);
  Eigen::VectorXd d = es.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return es.eigenvectors() * d.asDiagonal();
}

// The balanced analysis of (A, E, all nodes) from one assembly and its modal form.
SpeedReduction balanced(const NodeMatrices& m, const ModalForm& f, double speed, const Eigen::MatrixXd& E) {
  const auto n = static_cast<int>(m.capacitance.size());
  SpeedReduction r;
  r.speed_rpm = speed;
  for (int i = 0; i < n; ++i)
    if (!(f.lambda[i] > 0))
      throw std::runtime_error("reduction: the network is not stable at " + std::to_string(speed) + " rpm (no path to ambient)");
  // Modal coordinates: A~ = -diag(lambda), B~ = V^T C^-1/2 E, C~ = C^-1/2 V.
  const Eigen::VectorXd cis = f.c_sqrt.cwiseInverse();
  const Eigen::MatrixXd Bm = f.V.transpose() * cis.asDiagonal() * E;
  const Eigen::MatrixXd Cm = cis.asDiagonal() * f.V;
  Eigen::MatrixXd P(n, n), Q(n, n);
  const Eigen::MatrixXd BB = Bm * Bm.transpose(), CC = Cm.transpose() * Cm;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      P(i, j) = BB(i, j) / (f.lambda[i] + f.lambda[j]);
      Q(i, j) = CC(i, j) / (f.lambda[i] + f.lambda[j]);
    }
  // Q is full rank (every node is an output): with Q = Lo Lo^T, the squared Hankel singular values
  // are the eigenvalues of Lo^T P Lo, computed without a square root of the ill-conditioned P.
  Eigen::LLT<Eigen::MatrixXd> llt(Q);
  const Eigen::MatrixXd Lo = llt.info() == Eigen::Success ? Eigen::MatrixXd(llt.matrixL()) : psd_factor(Q);
  const Eigen::MatrixXd M = Lo.transpose() * P * Lo;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> hs(M);
  Eigen::VectorXd sig(n);
  Eigen::MatrixXd U(n, n);
  for (int i = 0; i < n; ++i) {  // descending
    sig[i] = std::sqrt(std::max(0.0, hs.eigenvalues()[n - 1 - i]));
    U.col(i) = hs.eigenvectors().col(n - 1 - i);
  }
  int k = 0;
  while (k < n && sig[k] > 1e-12 * sig[0]) ++k;  // minimal (controllable and observable) part
  if (k == 0)  // nothing to balance: the inputs move no node (all heat sources 0 W, or a zero stop state)
    throw std::runtime_error("reduction at " + std::to_string(static_cast<long>(speed)) +
                             " rpm: every Hankel singular value is 0, the inputs heat no node (are all heat sources 0 W?)");
  r.hsv = sig.head(k);
  // T = Lo^-T U S^1/2, Ti = S^-1/2 U^T Lo^T: Ti P Ti^T = T^T Q T = diag(hsv)
  const Eigen::VectorXd sq = sig.head(k).cwiseSqrt();
  const Eigen::MatrixXd T = Lo.transpose().fullPivLu().solve(U.leftCols(k)) * sq.asDiagonal();
  const Eigen::MatrixXd Ti = sq.cwiseInverse().asDiagonal() * U.leftCols(k).transpose() * Lo.transpose();
  const Eigen::MatrixXd Am = (-f.lambda).asDiagonal();
  const Eigen::MatrixXd Ab = Ti * Am * T, Bb = Ti * Bm, Cb = Cm * T;
  // Fix the sign of the balanced state so the dominant output gain is positive.
  const double sgn = Cb.col(0).sum() < 0 ? -1.0 : 1.0;
  r.bt.pole = Ab(0, 0);
  r.bt.b = sgn * Bb.row(0);
  r.bt.c = sgn * Cb.col(0);
  r.bt.d = Eigen::MatrixXd::Zero(n, E.cols());
  if (k > 1) {
    const Eigen::MatrixXd A22i = Ab.bottomRightCorner(k - 1, k - 1).inverse();
    const Eigen::RowVectorXd A12 = Ab.block(0, 1, 1, k - 1);
    const Eigen::VectorXd A21 = Ab.block(1, 0, k - 1, 1);
    r.dc.pole = Ab(0, 0) - (A12 * A22i * A21)(0, 0);
    r.dc.b = sgn * (Bb.row(0) - A12 * A22i * Bb.bottomRows(k - 1));
    r.dc.c = sgn * (Cb.col(0) - Cb.rightCols(k - 1) * A22i * A21);
    r.dc.d = -Cb.rightCols(k - 1) * A22i * Bb.bottomRows(k - 1);
  } else {
    r.dc = r.bt;
  }
  r.poles = -f.lambda;
  std::sort(r.poles.data(), r.poles.data() + n);
  r.sctc_s.resize(n);
  r.sctc_rate_sum = 0;
  for (int i = 0; i < n; ++i) {
    r.sctc_s[i] = m.capacitance[i] / m.G(i, i);
    r.sctc_rate_sum += 1.0 / r.sctc_s[i];
  }
  return r;
}

// Steady node rises above ambient with the heat of the assembled speed.
Eigen::VectorXd steady_rise(const NodeMatrices& m) {
  Eigen::FullPivLU<Eigen::MatrixXd> lu(m.G);
  if (!lu.isInvertible()) throw std::runtime_error("reduction: the network has no path to ambient");
  return lu.solve(m.heat_w);
}

// One node's rise over time from rise x0 at a speed: y(t) = y_inf + sum_i w_i exp(-lambda_i t).
struct NodeResponse {
  double y_inf = 0;
  Eigen::VectorXd w, lambda;
  double at(double t) const {
    double y = y_inf;
    for (Eigen::Index i = 0; i < w.size(); ++i) y += w[i] * std::exp(-lambda[i] * t);
    return y;
  }
};

NodeResponse node_response(const ModalForm& f, const Eigen::VectorXd& x_inf, const Eigen::VectorXd& x0, int node) {
  // x(t) = x_inf + C^-1/2 V exp(-Lambda t) V^T C^1/2 (x0 - x_inf)
  const Eigen::VectorXd z = f.V.transpose() * (f.c_sqrt.asDiagonal() * (x0 - x_inf));
  NodeResponse r;
  r.y_inf = x_inf[node];
  r.lambda = f.lambda;
  r.w = (f.V.row(node).transpose().array() * z.array()).matrix() / f.c_sqrt[node];
  return r;
}

// The pole p of y_inf + (y_start - y_inf) exp(-p (t - t_start)) closest to the node's response in
// the max norm over t in [t_start, t_end] (sampled every `step` s): a coarse log grid, then a
// golden-section search around its best point.
double minimax_pole(const NodeResponse& y, double t_start, double t_end, double step) {
  std::vector<double> t, v;
  for (double s = t_start; s <= t_end; s += step) {
    t.push_back(s - t_start);
    v.push_back(y.at(s));
  }
  const double y0 = v.front();
  const auto err = [&](double log_p) {
    const double p = std::exp(log_p);
    double e = 0;
    for (std::size_t k = 0; k < t.size(); ++k)
      e = std::max(e, std::abs(v[k] - (y.y_inf + (y0 - y.y_inf) * std::exp(-p * t[k]))));
    return e;
  };
  const double lo = std::log(0.1 * y.lambda.minCoeff()), hi = std::log(10.0 * y.lambda.maxCoeff());
  return std::exp(grid_golden_minimize(err, lo, hi, {.grid_cells = 120, .golden_iterations = 60}));
}

// The pole that takes y from y(t0) to y(t1) exactly (free response, y_inf = 0); positive (a
// rising or non-positive response gets a pole of ~ a year: "hold").
double matching_pole(const NodeResponse& y, double t0, double t1) {
  const double y0 = y.at(t0), y1 = y.at(t1);
  const double p = (y0 > 0 && y1 > 0) ? std::log(y0 / y1) / (t1 - t0) : 0.0;
  return std::max(p, 3e-8);
}

}  // namespace

SpeedReduction reduce_with_inputs(const Network& net, const Eigen::VectorXd& params, double speed,
                                  const Eigen::MatrixXd& E) {
  const NodeMatrices m = assemble(net, params, speed);
  return balanced(m, modal_form(m), speed, E);
}

SpeedReduction reduce_at_speed(const Network& net, const Eigen::VectorXd& params, double speed) {
  const NodeMatrices m = assemble(net, params, speed);
  if (m.source_to_node.cols() == 0) throw std::runtime_error("reduction: the network has no heat sources (inputs)");
  SpeedReduction r = balanced(m, modal_form(m), speed, m.source_to_node);
  r.source_w = m.source_w;
  r.steady_rise_K = steady_rise(m);
  r.bt_steady_rise_K = r.bt.c * (-(r.bt.b * m.source_w)(0) / r.bt.pole);
  return r;
}

void requantize(ScheduledReduction& r) {
  r.blob.clear();
  r.quantize_status = quantize(r.model, r.quantized);
  if (r.quantize_status.ok()) {
    r.blob.assign(kReducedModelBlobSize, 0);
    encode(r.quantized, r.blob.data());
  }
}

std::vector<std::pair<double, double>> duty_segments(const ReduceOptions& o, double& top_rpm) {
  const double top = o.duty_max_rpm > 0 ? o.duty_max_rpm : o.speeds_rpm.back();
  // The breakpoint speeds up to the top, the midpoints between them (the module interpolates
  // there) and the top speed itself when it is none of those.
  std::vector<double> speeds;
  for (std::size_t i = 0; i < o.speeds_rpm.size(); ++i) {
    if (o.speeds_rpm[i] <= top + 0.5) speeds.push_back(o.speeds_rpm[i]);
    if (i + 1 < o.speeds_rpm.size()) {
      const double mid = 0.5 * (o.speeds_rpm[i] + o.speeds_rpm[i + 1]);
      if (mid <= top + 0.5) speeds.push_back(mid);
    }
  }
  if (speeds.empty() || std::abs(speeds.back() - top) > 0.5) speeds.push_back(top);
  std::vector<std::pair<double, double>> prof;  // (speed, seconds)
  for (double sp : speeds)
    for (const auto& seg : std::vector<std::pair<double, double>>{{sp, 7200}, {0, 900}, {sp, 3600}, {0, 1800}, {sp, 3600},
                                                                  {0, 3600}, {sp, 3600}})
      prof.push_back(seg);
  for (auto it = speeds.rbegin(); it != speeds.rend(); ++it) prof.emplace_back(*it, 3600.0);
  for (double sp : speeds) prof.emplace_back(sp, 3600.0);
  // Restarts at another speed than before the stop (the bearings' fast modes start from a
  // state the same-speed restarts never show): each speed, stop 30 min, the mirrored speed.
  const std::size_t ns = speeds.size();
  for (std::size_t i = 0; i < ns; ++i) {
    prof.emplace_back(speeds[i], 3600.0);
    prof.emplace_back(0.0, 1800.0);
    prof.emplace_back(speeds[ns - 1 - i], 3600.0);
  }
  // Restarts after a 30-minute stop from every breakpoint speed (up to the top) to every other one:
  // a bearing riding on a slower channel (carrier) meets the carrier's fast warm-up after a start
  // from whatever the stop left, and production restarts at any speed.
  std::vector<double> bps;
  for (double sp : o.speeds_rpm)
    if (sp <= top + 0.5) bps.push_back(sp);
  for (double from : bps)
    for (double to : bps)
      if (to != from) {
        prof.emplace_back(from, 3600.0);
        prof.emplace_back(0.0, 1800.0);
        prof.emplace_back(to, 3600.0);
      }
  // A night: 8 h stopped, then the top speed and the lowest, 2 h each.
  prof.emplace_back(0.0, 8 * 3600.0);
  prof.emplace_back(speeds.back(), 7200.0);
  prof.emplace_back(speeds.front(), 7200.0);
  top_rpm = top;
  return prof;
}

namespace {
// Reports "<what>: N %" through ReduceOptions::progress at most every 5 s, the first after 5 s.
class ThrottledProgress {
 public:
  ThrottledProgress(const std::function<void(const std::string&)>& sink, std::string what)
      : sink_(sink), what_(std::move(what)), last_(std::chrono::steady_clock::now()) {}
  void at(double fraction) {
    if (!sink_) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ < std::chrono::seconds(5)) return;
    last_ = now;
    sink_(fmt::format("{}: {:.0f} %", what_, 100.0 * fraction));
  }

 private:
  const std::function<void(const std::string&)>& sink_;
  std::string what_;
  std::chrono::steady_clock::time_point last_;
};
}  // namespace

namespace {
// The reduction samples each node's response over 5 of its slowest time constants at <= 10 s: a
// model whose slowest mode is astronomically slow (resistances of 1e300 K/W load, being finite)
// ran for hours. A spindle's modes are minutes to hours; 1e6 s (11.6 days) is far past them.
constexpr double kMaxTimeConstantS = 1e6;
void check_time_constants(const ModalForm& f, double speed_rpm) {
  const double tau = 1.0 / f.lambda.minCoeff();
  if (!(tau <= kMaxTimeConstantS))
    throw std::invalid_argument(fmt::format("reduce: at {:g} rpm the model's slowest time constant is {:.3g} s ({:.3g} days), "
                                            "beyond the {:g} s a module model can follow: a node all but cut off from "
                                            "ambient (a resistance or capacitance far out of range?)",
                                            speed_rpm, tau, tau / 86400, kMaxTimeConstantS));
}

// A steady rise of thousands of kelvin is no spindle (steel melts 1,400 K above the room): a heat
// source or resistance far out of range, e.g. a hand-edited 1e300 W. Named before the balanced
// analysis, whose sums overflow on it to singular values of 0 ("the inputs heat no node").
// kMaxSteadyRiseK: the model readers' bound (model_file.hpp), checked here at the reduction's own speeds.
void check_steady_rise(const Network& net, const NodeMatrices& m, const Eigen::VectorXd& rise, double speed_rpm) {
  for (int i = 0; i < rise.size(); ++i) {
    if (std::isfinite(rise[i]) && std::abs(rise[i]) <= kMaxSteadyRiseK) continue;
    std::string largest;
    double largest_w = -1;
    for (int k = 0; k < m.source_w.size() && k < static_cast<int>(net.sources.size()); ++k)
      if (!(std::abs(m.source_w[k]) <= largest_w)) {
        largest_w = std::abs(m.source_w[k]);
        largest = fmt::format("; its largest heat source is '{}' = {:.4g} W", net.sources[static_cast<std::size_t>(k)].name,
                              m.source_w[k]);
      }
    throw std::invalid_argument(fmt::format("reduce: at {:g} rpm the model heats node '{}' {} above ambient at steady state, "
                                            "beyond the {:g} K any spindle can reach{} (a heat source or resistance far out of range?)",
                                            speed_rpm, net.nodes[static_cast<std::size_t>(i)].name,
                                            std::isfinite(rise[i]) ? fmt::format("{:.4g} K", rise[i]) : std::string("without bound"),
                                            kMaxSteadyRiseK, largest));
  }
}
}  // namespace

ScheduledReduction build_scheduled_model(const Network& net, const Eigen::VectorXd& params, const ReduceOptions& o) {
  if (o.speeds_rpm.empty()) throw std::invalid_argument("reduce: give at least one operating speed");
  if (net.has_inputs())
    throw std::invalid_argument("reduce: the network uses declared boundary or event columns; the module's model has speed and "
                                "ambient as its only inputs, so it cannot carry them");
  // heat driven by a node's own rise keeps G symmetric; a difference of other nodes does not
  for (const auto& s : net.sources)
    for (const auto* ts : {&s.operating, &s.cooling})
      for (const auto& t : *ts)
        if (t.driven && !((t.hot == s.node && t.cold == kAmbient) || (t.cold == s.node && t.hot == kAmbient)))
          throw std::invalid_argument("reduce: source '" + s.name + "' is driven by a difference of other nodes; the balanced "
                                      "reduction needs the symmetric form of a passive network");
  if (!(o.dt_s >= kModelMinDtMs / 1000.0 && o.dt_s <= kModelMaxDtMs / 1000.0)) {  // NaN fails too
    char msg[96];
    std::snprintf(msg, sizeof msg, "reduce: the firmware sample period must be %g ... %g s, not %g", kModelMinDtMs / 1000.0,
                  kModelMaxDtMs / 1000.0, o.dt_s);
    throw std::invalid_argument(msg);
  }
  if (o.speeds_rpm.size() + 1 > kModelMaxBreakpoints)
    throw std::invalid_argument("reduce: at most " + std::to_string(kModelMaxBreakpoints - 1) + " operating speeds fit the module's model");
  for (std::size_t i = 0; i < o.speeds_rpm.size(); ++i) {
    const double s = o.speeds_rpm[i];
    if (!(s > net.operating_above_rpm) || s > 65535 || s != std::round(s))
      throw std::invalid_argument("reduce: speed " + std::to_string(s) + " must be a whole rpm above the operating threshold and <= 65535");
    if (i > 0 && !(s > o.speeds_rpm[i - 1])) throw std::invalid_argument("reduce: speeds must be strictly ascending");
  }
  if (!(o.dt_s >= kModelMinDtMs * 1e-3 && o.dt_s <= kModelMaxDtMs * 1e-3))
    throw std::invalid_argument("reduce: dt must be within 0.1 .. 60 s");
  bool any = false;
  for (int ch = 0; ch < 5; ++ch) {
    const int nd = o.channel_node[static_cast<std::size_t>(ch)];
    if (nd >= net.node_count()) throw std::invalid_argument("reduce: channel " + std::to_string(ch + 1) + " maps to a missing node");
    if (nd >= 0 && ch == o.ambient_channel) throw std::invalid_argument("reduce: the ambient channel cannot also map to a node");
    any = any || nd >= 0;
  }
  if (!any) throw std::invalid_argument("reduce: no channel maps to a node of the network");
  const auto& ends = o.stop_phase_end_s;
  for (double e : ends)
    if (!(e >= 0 && e <= 65535) || e != std::round(e)) throw std::invalid_argument("reduce: stop phase ends must be whole seconds within 0..65535");
  if ((ends[0] == 0 && ends[1] != 0) || (ends[1] != 0 && ends[1] <= ends[0]))
    throw std::invalid_argument("reduce: stop phase ends must ascend, the first one set");

  ScheduledReduction out;
  ReducedModelF64& fm = out.model;
  const double dt = o.dt_s;
  fm.dt_ms = static_cast<uint16_t>(std::lround(dt * 1000.0));
  fm.n_breakpoints = static_cast<uint8_t>(o.speeds_rpm.size() + 1);
  fm.ambient_channel = o.ambient_channel < 0 ? kModelAmbientNone : static_cast<uint8_t>(o.ambient_channel);
  fm.enabled_mask = 0;
  for (int k = 0; k < kModelEarlyStopPhases; ++k) fm.stop_end_s[k] = static_cast<uint16_t>(ends[static_cast<std::size_t>(k)]);
  for (int ch = 0; ch < 5; ++ch) {
    const auto c = static_cast<std::size_t>(ch);
    const int nd = o.channel_node[c];
    if (nd >= 0) {
      fm.enabled_mask |= static_cast<uint8_t>(1u << ch);
      fm.role[ch] = o.channel_role[c] >= 0 ? static_cast<uint8_t>(o.channel_role[c])
                                            : role_for_node(net.nodes[static_cast<std::size_t>(nd)].name);
      fm.detector[ch] = o.detector;
    } else if (ch == o.ambient_channel) {
      fm.enabled_mask |= static_cast<uint8_t>(1u << ch);
      fm.role[ch] = kModelRoleAmbient;
      fm.detector[ch].abs_limit_c = o.detector.abs_limit_c;
    } else {
      fm.role[ch] = kModelRoleNotModelled;
    }
    out.channels[c].node = nd;
    out.channels[c].tau_s.assign(fm.n_breakpoints, 0.0);
    out.channels[c].steady_rise_K.assign(fm.n_breakpoints, 0.0);
  }

  // Running breakpoints: per channel the DC-matched first-order step response closest to the
  // node's (one assembly per speed serves the balanced analysis, the steady state and the fit).
  const Eigen::VectorXd cold = Eigen::VectorXd::Zero(net.node_count());
  for (std::size_t i = 0; i < o.speeds_rpm.size(); ++i) {
    const double speed = o.speeds_rpm[i];
    const NodeMatrices m = assemble(net, params, speed);
    if (m.source_to_node.cols() == 0) throw std::runtime_error("reduction: the network has no heat sources (inputs)");
    const ModalForm f = modal_form(m);
    check_time_constants(f, speed);
    const Eigen::VectorXd rise = steady_rise(m);
    check_steady_rise(net, m, rise, speed);
    SpeedReduction r = balanced(m, f, speed, m.source_to_node);
    r.source_w = m.source_w;
    r.steady_rise_K = rise;
    r.bt_steady_rise_K = r.bt.c * (-(r.bt.b * m.source_w)(0) / r.bt.pole);
    const std::size_t bp = i + 1;
    fm.speed_rpm[bp] = static_cast<uint16_t>(speed);
    const double horizon = 5.0 / f.lambda.minCoeff();
    for (int ch = 0; ch < 5; ++ch) {
      const int nd = o.channel_node[static_cast<std::size_t>(ch)];
      if (nd < 0) continue;
      const NodeResponse y = node_response(f, r.steady_rise_K, cold, nd);
      const double p = minimax_pole(y, 0.0, horizon, std::min(10.0, dt));
      const double a = std::exp(-p * dt);
      fm.a[bp][ch] = a;
      fm.b_K[bp][ch] = r.steady_rise_K[nd] * (1.0 - a);  // DC-matched: b / (1 - a) = steady rise
      out.channels[static_cast<std::size_t>(ch)].tau_s[bp] = 1.0 / p;
      out.channels[static_cast<std::size_t>(ch)].steady_rise_K[bp] = r.steady_rise_K[nd];
    }
    out.speeds.push_back(std::move(r));
  }

  // Stopped: the free response from the stop state at the cooling reference speed.
  const double ref_speed = o.cooling_reference_rpm > 0 ? o.cooling_reference_rpm
                                                       : o.speeds_rpm[o.speeds_rpm.size() / 2];
  {
    const NodeMatrices ms = assemble(net, params, ref_speed);
    const Eigen::VectorXd x_stop = steady_rise(ms);
    check_steady_rise(net, ms, x_stop, ref_speed);
    const NodeMatrices mc = assemble(net, params, 0.0);
    const ModalForm fc = modal_form(mc);
    check_time_constants(fc, 0.0);
    // Analysis of the free response as an impulse of C x_stop (reported, as for the speeds).
    out.cooling = balanced(mc, fc, 0.0, mc.capacitance.asDiagonal() * x_stop);
    out.cooling.source_w = Eigen::VectorXd::Zero(1);
    out.cooling.steady_rise_K = Eigen::VectorXd::Zero(net.node_count());
    const double horizon = 5.0 / fc.lambda.minCoeff();
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(net.node_count());
    fm.speed_rpm[0] = 0;
    for (int ch = 0; ch < 5; ++ch) {
      const auto c = static_cast<std::size_t>(ch);
      const int nd = o.channel_node[c];
      if (nd < 0) continue;
      const NodeResponse y = node_response(fc, zero, x_stop, nd);
      double t0 = 0.0;
      for (int k = 0; k < kModelEarlyStopPhases; ++k) {
        const double e = ends[static_cast<std::size_t>(k)];
        if (e == 0) break;
        const double p = matching_pole(y, t0, e);
        fm.stop_a[k][ch] = std::exp(-p * dt);
        out.channels[c].stop_tau_s[static_cast<std::size_t>(k)] = 1.0 / p;
        t0 = e;
      }
      const double p = y.at(t0) > 0 ? minimax_pole(y, t0, std::max(horizon, t0 + 3600.0), std::min(10.0, dt))
                                    : fc.lambda.minCoeff();
      fm.a[0][ch] = std::exp(-p * dt);
      fm.b_K[0][ch] = 0.0;
      out.channels[c].tau_s[0] = 1.0 / p;
    }
  }
  if (o.carriers) fit_carriers(net, params, o, fm, out.channels);
  requantize(out);

  // Deviation over the reduction profile: each breakpoint speed 2 h and the midpoints 1 h
  // (ascending), stop 3 h, lowest speed 1 h, stop 1 h.
  {
    std::vector<std::pair<double, double>> profile;  // (speed, seconds)
    for (std::size_t i = 0; i < o.speeds_rpm.size(); ++i) {
      profile.emplace_back(o.speeds_rpm[i], 7200.0);
      if (i + 1 < o.speeds_rpm.size()) profile.emplace_back(std::round(0.5 * (o.speeds_rpm[i] + o.speeds_rpm[i + 1])), 3600.0);
    }
    profile.emplace_back(0.0, 3 * 3600.0);
    profile.emplace_back(o.speeds_rpm.front(), 3600.0);
    profile.emplace_back(0.0, 3600.0);
    double total = 0;
    for (const auto& s : profile) total += s.second;
    out.deviation.profile_hours = total / 3600.0;
    out.deviation.profile = fmt::format("each breakpoint speed 2 h and the midpoints 1 h (ascending), stop 3 h, lowest speed 1 h, stop 1 h; "
                                          "ambient {:g} °C, dt {:g} s",
                                          o.test_ambient_c, dt);
    Simulator full(net, params);
    full.reset(Eigen::VectorXd::Constant(net.node_count(), o.test_ambient_c));
    ReducedModelF64State sd;
    init_at_ambient(fm, sd, o.test_ambient_c);
    ReducedModelState sq;
    const auto amb_mk = static_cast<int32_t>(std::lround(o.test_ambient_c * 1000.0));
    init_at_ambient(sq, amb_mk);
    const bool quantized_ok = out.quantize_status.ok();
    DeviationSummary& dev = out.deviation;
    ThrottledProgress progress(o.progress, "checking the module model over the deviation profile");
    double simulated = 0;
    for (const auto& seg : profile) {
      const long steps = std::lround(seg.second / dt);
      for (long k = 0; k < steps; ++k, simulated += dt) {
        progress.at(simulated / total);
        double pd[kModelChannels];
        int32_t pq[kModelChannels];
        step(fm, sd, seg.first, o.test_ambient_c, pd);
        if (quantized_ok) step(out.quantized, sq, static_cast<uint16_t>(seg.first), amb_mk, pq);
        const Eigen::VectorXd& xf = full.node_temp_c();
        for (int ch = 0; ch < 5; ++ch) {
          const auto c = static_cast<std::size_t>(ch);
          const int nd = o.channel_node[c];
          if (nd < 0) continue;
          dev.double_vs_full_K[c] = std::max(dev.double_vs_full_K[c], std::abs(pd[ch] - xf[nd]));
          if (quantized_ok) {
            const double q = pq[ch] / 1000.0;
            dev.residual_K[c].push_back(xf[nd] - q);
            dev.quantized_vs_full_K[c] = std::max(dev.quantized_vs_full_K[c], std::abs(q - xf[nd]));
            dev.quantized_vs_double_max_K = std::max(dev.quantized_vs_double_max_K, std::abs(q - pd[ch]));
          }
        }
        full.step(dt, seg.first, o.test_ambient_c);
      }
    }
    for (int ch = 0; ch < 5; ++ch) {
      dev.double_vs_full_max_K = std::max(dev.double_vs_full_max_K, dev.double_vs_full_K[static_cast<std::size_t>(ch)]);
      dev.quantized_vs_full_max_K = std::max(dev.quantized_vs_full_max_K, dev.quantized_vs_full_K[static_cast<std::size_t>(ch)]);
    }
  }
  // The duty cycle: the module model (fixed point) against the network, as a plant would run.
  if (out.quantize_status.ok()) {
    double top = 0;
    const std::vector<std::pair<double, double>> prof = duty_segments(o, top);
    double total = 0;
    for (const auto& seg : prof) total += seg.second;
    out.duty.hours = total / 3600;
    out.duty.profile = fmt::format("from cold, at each breakpoint speed and midpoint up to {:.0f} rpm: 2 h, stop 15 min, 1 h, "
                                   "stop 30 min, 1 h, stop 60 min, 1 h; then 1 h steps down and up through those speeds; "
                                   "restarts after 30 min at the mirrored speed (lowest <-> top) and from every breakpoint "
                                   "speed to every other one; 8 h stopped, then top and "
                                   "lowest speed 2 h each; ambient {:.0f} +- 1 degC (period 8 h); {:.0f} h",
                                   top, o.test_ambient_c, total / 3600);
    Simulator full(net, params);
    full.reset(Eigen::VectorXd::Constant(net.node_count(), o.test_ambient_c));
    ReducedModelState st;
    init_at_ambient(st, static_cast<int32_t>(std::lround(o.test_ambient_c * 1000.0)));
    double t = 0;
    ThrottledProgress progress(o.progress, "checking the module model over the duty cycle");
    for (const auto& seg : prof) {
      const long steps = std::lround(seg.second / dt);
      for (long k = 0; k < steps; ++k, t += dt) {
        progress.at(t / total);
        const double amb = o.test_ambient_c + std::sin(2 * M_PI * t / (8 * 3600.0));
        int32_t pq[5];
        step(out.quantized, st, static_cast<uint16_t>(seg.first), static_cast<int32_t>(std::lround(amb * 1000)), pq);
        for (int ch = 0; ch < 5; ++ch) {
          const auto c = static_cast<std::size_t>(ch);
          const int nd = o.channel_node[c];
          if (nd < 0) continue;
          const double r = full.node_temp_c()[nd] - pq[ch] / 1000.0;
          out.duty.residual_K[c].push_back(r);
          out.duty.max_abs_K[c] = std::max(out.duty.max_abs_K[c], std::abs(r));
        }
        full.step(dt, seg.first, amb);
      }
    }
  }
  // The design fault: design_heat_w more at each channel's node, from the steady state at the
  // middle breakpoint speed, for 2 h.
  {
    const double sp = o.speeds_rpm[o.speeds_rpm.size() / 2];
    out.design_fault.heat_w = o.design_heat_w;
    out.design_fault.speed_rpm = sp;
    for (int ch = 0; ch < 5; ++ch) {
      const auto c = static_cast<std::size_t>(ch);
      const int nd = o.channel_node[c];
      if (nd < 0) continue;
      // The network is linear: the fault's rise over the fault-free response is the extra heat
      // through the step matrices of that speed alone (no sources, no ambient).
      Simulator sim(net, params);
      const StepMatrices& sm = sim.matrices(sp, dt);
      Eigen::VectorXd extra = Eigen::VectorXd::Zero(net.node_count());
      extra[nd] = o.design_heat_w;
      Eigen::VectorXd x = Eigen::VectorXd::Zero(net.node_count());
      for (int k = 0; k < static_cast<int>(7200 / dt); ++k) {
        x = sm.Phi * x + sm.Gamma * extra;
        out.design_fault.rise_K[c].push_back(x[nd]);
      }
    }
  }
  return out;
}

namespace {
nlohmann::json vec(const Eigen::VectorXd& v) {
  nlohmann::json a = nlohmann::json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(v[i]);
  return a;
}
nlohmann::json speed_json(const Network& net, const SpeedReduction& r) {
  nlohmann::json j;
  j["speed_rpm"] = r.speed_rpm;
  j["hsv"] = vec(r.hsv);
  j["poles_per_s"] = vec(r.poles);
  Eigen::VectorXd tau_min = (-r.poles).cwiseInverse() / 60.0;
  j["time_constants_min"] = vec(tau_min);
  j["pole_bt"] = r.bt.pole;
  j["pole_dc"] = r.dc.pole;
  j["sctc_s"] = vec(r.sctc_s);
  j["sctc_rate_sum_per_s"] = r.sctc_rate_sum;
  j["pole_sum_per_s"] = r.poles.sum();
  j["sctc_note"] = "SCTC time constants C_j/G_jj are not the model's time constants; only the sum of their rates is exact (= -sum of poles)";
  if (r.source_w.size() && r.steady_rise_K.size() && r.steady_rise_K.norm() > 0) {
    j["sources_w"] = vec(r.source_w);
    nlohmann::json ss, bt;
    for (int i = 0; i < net.node_count(); ++i) {
      ss[net.nodes[static_cast<std::size_t>(i)].name] = r.steady_rise_K[i];
      bt[net.nodes[static_cast<std::size_t>(i)].name] = r.bt_steady_rise_K[i];
    }
    j["steady_rise_K"] = ss;
    j["bt_steady_rise_K"] = bt;
  }
  return j;
}
nlohmann::json role_json(uint8_t role) {
  if (role == kModelRoleUnchecked) return "unchecked";
  const char* n = wire::channel_role_name(role);
  return n ? nlohmann::json(n) : nlohmann::json(static_cast<int>(role));
}
}  // namespace

nlohmann::json reduction_to_json(const Network& net, const ScheduledReduction& r, const ReduceOptions& o) {
  nlohmann::json j;
  j["format"] = "btsm-reduced-model-2";  // blob format version 2 with carriers (model_blob.hpp)
  j["inputs"] = nlohmann::json::array();
  for (const auto& s : net.sources) j["inputs"].push_back(s.name + " (W)");
  j["outputs"] = nlohmann::json::array();
  for (const auto& nd : net.nodes) j["outputs"].push_back(nd.name + " rise (K)");
  j["speeds"] = nlohmann::json::array();
  for (const auto& s : r.speeds) j["speeds"].push_back(speed_json(net, s));
  j["cooling"] = speed_json(net, r.cooling);
  j["cooling"]["input"] = "stop state (steady state at the cooling reference speed) as an impulse";
  const ReducedModelF64& m = r.model;
  nlohmann::json sm;
  sm["dt_ms"] = m.dt_ms;
  sm["reduction"] =
      "one first-order model per channel: running, the DC-matched first-order step response closest (max norm) to the "
      "node's; stopped, the node's free response from the stop state (early phases exact at their ends, the last closest); "
      "a channel rides on a slower channel's model (carrier) where that cuts its duty-cycle error by >= 10 %, its poles "
      "then refitted with the carrier (max norm)";
  sm["ambient_channel"] = o.ambient_channel < 0 ? nlohmann::json(nullptr) : nlohmann::json(o.ambient_channel + 1);
  sm["enabled_mask"] = m.enabled_mask;
  sm["stop_phase_end_s"] = {m.stop_end_s[0], m.stop_end_s[1]};
  nlohmann::json chans = nlohmann::json::array();
  for (int ch = 0; ch < 5; ++ch) {
    const auto c = static_cast<std::size_t>(ch);
    const ChannelReduction& cr = r.channels[c];
    nlohmann::json cj{{"channel", ch + 1}, {"role", role_json(m.role[ch])}};
    if (cr.node >= 0) {
      cj["node"] = net.nodes[static_cast<std::size_t>(cr.node)].name;
      nlohmann::json tau = nlohmann::json::array(), rise = nlohmann::json::array();
      for (int i = 0; i < m.n_breakpoints; ++i) {
        tau.push_back(cr.tau_s[static_cast<std::size_t>(i)] / 60.0);
        rise.push_back(cr.steady_rise_K[static_cast<std::size_t>(i)]);
      }
      cj["time_constant_min"] = tau;  // per breakpoint, 0 rpm = the late stop phase
      cj["steady_rise_K"] = rise;
      nlohmann::json st = nlohmann::json::array();
      for (int k = 0; k < kModelEarlyStopPhases; ++k)
        if (m.stop_end_s[k] != 0) st.push_back(cr.stop_tau_s[static_cast<std::size_t>(k)] / 60.0);
      cj["stop_phase_time_constant_min"] = st;
      if (m.carrier[ch] != kModelNoCarrier) {
        cj["carrier_channel"] = m.carrier[ch];  // 1-based, as the channels
        cj["coupling_per_step"] = m.couple[ch];
        cj["coupling_share"] = cr.coupling_share;
        cj["duty_cycle_error_K"] = {{"plain", cr.plain_duty_K}, {"with_carrier", cr.carried_duty_K}};
      }
      const ChannelDetector& d = m.detector[ch];
      cj["detector"] = {{"drift_K", d.drift_K},
                        {"low_drift_K", d.low_drift_K},
                        {"warn_evidence_K_min", d.warn_evidence_K_min},
                        {"alarm_evidence_K_min", d.alarm_evidence_K_min},
                        {"low_warn_evidence_K_min", d.low_warn_evidence_K_min},
                        {"abs_limit_c", d.abs_limit_c},
                        {"max_rise_K_per_min", d.max_rise_K_per_min}};
      cj["deviation_vs_full_K"] = r.deviation.quantized_vs_full_K[c];
    } else if (ch == o.ambient_channel) {
      cj["node"] = "ambient";
      cj["abs_limit_c"] = m.detector[ch].abs_limit_c;
    } else {
      cj["node"] = nullptr;
    }
    chans.push_back(cj);
  }
  sm["channels"] = chans;
  sm["breakpoints"] = nlohmann::json::array();
  for (int i = 0; i < m.n_breakpoints; ++i) {
    nlohmann::json b{{"speed_rpm", m.speed_rpm[i]}};
    b["a"] = std::vector<double>(m.a[i], m.a[i] + 5);
    b["b_K"] = std::vector<double>(m.b_K[i], m.b_K[i] + 5);
    sm["breakpoints"].push_back(b);
  }
  sm["stop_phases"] = nlohmann::json::array();
  for (int k = 0; k < kModelEarlyStopPhases; ++k)
    if (m.stop_end_s[k] != 0) sm["stop_phases"].push_back({{"end_s", m.stop_end_s[k]}, {"a", std::vector<double>(m.stop_a[k], m.stop_a[k] + 5)}});
  j["scheduled_model"] = sm;
  j["quantization"] = {{"status", model_status_name(r.quantize_status.status)}, {"blob_bytes", r.blob.size()}};
  if (!r.blob.empty()) {
    // The blob itself, so `btsm flash-model REDUCED.json` needs no second file.
    std::string h(2 * r.blob.size(), '0');
    hex_encode(r.blob.data(), r.blob.size(), h.data());
    j["blob_hex"] = h;
  }
  j["deviation"] = {{"profile", r.deviation.profile},
                    {"profile_hours", r.deviation.profile_hours},
                    {"quantized_vs_full_max_K", r.deviation.quantized_vs_full_max_K},
                    {"double_vs_full_max_K", r.deviation.double_vs_full_max_K},
                    {"quantized_vs_double_max_K", r.deviation.quantized_vs_double_max_K},
                    {"quantized_vs_full_per_channel_K", r.deviation.quantized_vs_full_K}};
  return j;
}

}  // namespace btsm::thermal
