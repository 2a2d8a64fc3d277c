// Balanced reduction in the modal basis and the speed-scheduled firmware model.
#include "reduce.hpp"

#include "simulator.hpp"

#include "common/hex_text.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace btsm::thermal {
namespace {

// Symmetric square root factor L (P = L L^T) of a PSD matrix.
Eigen::MatrixXd psd_factor(const Eigen::MatrixXd& P) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(P);
  Eigen::VectorXd d = es.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return es.eigenvectors() * d.asDiagonal();
}

}  // namespace

namespace {

// One speed's reduction from its assembled matrices (A = -C^-1 G, inputs E), so that each speed's
// network is assembled once.
SpeedReduction reduce_assembled(const Network& net, const NodeMatrices& m, double speed, const Eigen::MatrixXd& E) {
  const ModalForm f = modal_form(m);
  const int n = net.node_count();
  SpeedReduction r;
  r.speed_rpm = speed;
  for (int i = 0; i < n; ++i)
    if (!(f.lambda[i] > 0)) throw std::runtime_error("reduction: the network is not stable at " + std::to_string(speed) + " rpm (no path to ambient)");
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
  // descending order
  Eigen::VectorXd sig(n);
  Eigen::MatrixXd U(n, n);
  for (int i = 0; i < n; ++i) {
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

}  // namespace

SpeedReduction reduce_with_inputs(const Network& net, const Eigen::VectorXd& params, double speed,
                                  const Eigen::MatrixXd& E) {
  return reduce_assembled(net, assemble(net, params, speed), speed, E);
}

SpeedReduction reduce_at_speed(const Network& net, const Eigen::VectorXd& params, double speed) {
  const NodeMatrices m = assemble(net, params, speed);
  if (m.source_to_node.cols() == 0) throw std::runtime_error("reduction: the network has no heat sources (inputs)");
  SpeedReduction r = reduce_assembled(net, m, speed, m.source_to_node);
  r.source_w = m.source_w;
  // The steady rise over ambient (ambient at 0, no boundaries: reduce refuses them), as
  // steady_state_c computes it, from the same matrices.
  r.steady_rise_K = Eigen::FullPivLU<Eigen::MatrixXd>(m.G).solve(m.heat_w);
  r.bt_steady_rise_K = r.bt.c * (-(r.bt.b * m.source_w)(0) / r.bt.pole);
  return r;
}

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
    throw std::invalid_argument("reduce: at most " + std::to_string(kModelMaxBreakpoints - 1) + " operating speeds fit the firmware blob");
  for (std::size_t i = 0; i < o.speeds_rpm.size(); ++i) {
    const double s = o.speeds_rpm[i];
    if (!(s > net.operating_above_rpm) || s > 65535 || s != std::round(s))
      throw std::invalid_argument("reduce: speed " + std::to_string(s) + " must be a whole rpm above the operating threshold and <= 65535");
    if (i > 0 && !(s > o.speeds_rpm[i - 1])) throw std::invalid_argument("reduce: speeds must be strictly ascending");
  }
  if (o.reference_channel < 0 || o.reference_channel >= kModelChannels || o.channel_node[static_cast<std::size_t>(o.reference_channel)] < 0)
    throw std::invalid_argument("reduce: the reference channel must map to a node");
  for (int ch = 0; ch < kModelChannels; ++ch) {
    const int nd = o.channel_node[static_cast<std::size_t>(ch)];
    if (nd >= net.node_count()) throw std::invalid_argument("reduce: channel " + std::to_string(ch + 1) + " maps to a missing node");
    if (nd >= 0 && ch == o.ambient_channel) throw std::invalid_argument("reduce: the ambient channel cannot also map to a node");
  }
  ScheduledReduction out;
  ReducedModelF64& fm = out.model;
  fm.dt_ms = static_cast<uint16_t>(std::lround(o.dt_s * 1000.0));
  fm.n_breakpoints = static_cast<uint8_t>(o.speeds_rpm.size() + 1);
  fm.ambient_channel = o.ambient_channel < 0 ? kModelAmbientNone : static_cast<uint8_t>(o.ambient_channel);
  fm.enabled_mask = 0;
  for (int ch = 0; ch < kModelChannels; ++ch)
    if (o.channel_node[static_cast<std::size_t>(ch)] >= 0 || ch == o.ambient_channel) fm.enabled_mask |= static_cast<uint8_t>(1u << ch);
  for (int ch = 0; ch < kModelChannels; ++ch) {
    fm.warn_band_k[ch] = o.warn_K;
    fm.alarm_band_k[ch] = o.alarm_K;
    fm.abs_limit_c[ch] = o.abs_limit_c;
    fm.max_rise_k_per_min[ch] = o.max_rise_K_per_min;
  }
  const int ref_node = o.channel_node[static_cast<std::size_t>(o.reference_channel)];
  const double dt = o.dt_s;
  // operating breakpoints: DC-matched, u = 1 drives Q(w); state scaled so c_ref = 1
  for (std::size_t i = 0; i < o.speeds_rpm.size(); ++i) {
    SpeedReduction r = reduce_at_speed(net, params, o.speeds_rpm[i]);
    const double scale = r.dc.c[ref_node];
    if (!(std::abs(scale) > 0)) throw std::runtime_error("reduce: the reference node is not observable in the 1st-order model");
    const double a = std::exp(r.dc.pole * dt);
    const double bc = (r.dc.b * r.source_w)(0);
    const std::size_t bp = i + 1;
    fm.speed_rpm[bp] = static_cast<uint16_t>(o.speeds_rpm[i]);
    fm.a[bp] = a;
    fm.b[bp] = scale * bc * (a - 1.0) / r.dc.pole;
    const Eigen::VectorXd d = r.dc.d * r.source_w;
    for (int ch = 0; ch < kModelChannels; ++ch) {
      const int nd = o.channel_node[static_cast<std::size_t>(ch)];
      fm.c[bp][ch] = nd >= 0 ? r.dc.c[nd] / scale : 0.0;
      fm.d[bp][ch] = nd >= 0 ? d[nd] : 0.0;
    }
    out.speeds.push_back(std::move(r));
  }
  // cooling breakpoint: the stop state at the reference speed as an impulse input
  const double ref_speed = o.cooling_reference_rpm > 0 ? o.cooling_reference_rpm : o.speeds_rpm.back();
  const Eigen::VectorXd x_stop = steady_state_c(net, params, ref_speed, 0.0);
  const double cool_speed = 0.0;
  const NodeMatrices mc = assemble(net, params, cool_speed);
  // impulse of B = C x_stop through A = -C^-1 G starts the free response at x_stop
  out.cooling = reduce_assembled(net, mc, cool_speed, mc.capacitance.asDiagonal() * x_stop);
  out.cooling.source_w = Eigen::VectorXd::Zero(1);
  out.cooling.steady_rise_K = Eigen::VectorXd::Zero(net.node_count());
  {
    const double scale = out.cooling.dc.c[ref_node];
    fm.speed_rpm[0] = 0;
    fm.a[0] = std::exp(out.cooling.dc.pole * dt);
    fm.b[0] = 0.0;
    // Output gains = the stop-state shape (continuous at the stop; the 1st-order model cannot
    // follow the ~1000 s equalisation after it, which the deviation figures show). The pole is the
    // DC-matched one of the free response (it preserves the integral of the decay).
    (void)scale;
    for (int ch = 0; ch < kModelChannels; ++ch) {
      const int nd = o.channel_node[static_cast<std::size_t>(ch)];
      fm.c[0][ch] = nd >= 0 ? x_stop[nd] / x_stop[ref_node] : 0.0;
      fm.d[0][ch] = 0.0;
    }
  }
  out.quantize_status = quantize(fm, out.quantized);
  if (out.quantize_status.status == ModelStatus::kOk) {
    out.blob.assign(kReducedModelBlobSize, 0);
    encode(out.quantized, out.blob.data());
  }
  // deviation over a test profile: each breakpoint speed for 2 h (ascending), midway speeds, 3 h stop
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
    out.deviation.profile = "each breakpoint speed 2 h and the midpoints 1 h (ascending), stop 3 h, lowest speed 1 h, stop 1 h; ambient " +
                            std::to_string(o.test_ambient_c) + " degC, dt " + std::to_string(dt) + " s";
    Simulator full(net, params);
    full.reset(Eigen::VectorXd::Constant(net.node_count(), o.test_ambient_c));
    ReducedModelF64State sd;
    ReducedModelState sq;
    reset(sq);
    const auto amb_mk = static_cast<int32_t>(std::lround(o.test_ambient_c * 1000.0));
    const bool quantized_ok = out.quantize_status.status == ModelStatus::kOk;
    for (const auto& seg : profile) {
      const long steps = std::lround(seg.second / dt);
      for (long k = 0; k < steps; ++k) {
        double pd[kModelChannels];
        int32_t pq[kModelChannels];
        step(fm, sd, seg.first, o.test_ambient_c, pd);
        if (quantized_ok) step(out.quantized, sq, static_cast<uint16_t>(seg.first), amb_mk, pq);
        const Eigen::VectorXd& xf = full.node_temp_c();
        for (int ch = 0; ch < kModelChannels; ++ch) {
          const int nd = o.channel_node[static_cast<std::size_t>(ch)];
          if (nd < 0) continue;
          out.deviation.double_vs_full_max_K = std::max(out.deviation.double_vs_full_max_K, std::abs(pd[ch] - xf[nd]));
          if (quantized_ok) {
            const double q = pq[ch] / 1000.0;
            out.deviation.quantized_vs_full_max_K = std::max(out.deviation.quantized_vs_full_max_K, std::abs(q - xf[nd]));
            out.deviation.quantized_vs_double_max_K = std::max(out.deviation.quantized_vs_double_max_K, std::abs(q - pd[ch]));
          }
        }
        full.step(dt, seg.first, o.test_ambient_c);
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
}  // namespace

nlohmann::json reduction_to_json(const Network& net, const ScheduledReduction& r, const ReduceOptions& o) {
  nlohmann::json j;
  j["format"] = "btsm-reduced-model-1";
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
  sm["reduction"] = "DC-matched (singular perturbation) balanced 1st order; state scaled so the reference channel's c = 1";
  sm["reference_channel"] = o.reference_channel + 1;
  sm["ambient_channel"] = o.ambient_channel < 0 ? nlohmann::json(nullptr) : nlohmann::json(o.ambient_channel + 1);
  sm["enabled_mask"] = m.enabled_mask;
  nlohmann::json chmap = nlohmann::json::array();
  for (int ch = 0; ch < kModelChannels; ++ch) {
    const int nd = o.channel_node[static_cast<std::size_t>(ch)];
    chmap.push_back(nd >= 0 ? nlohmann::json(net.nodes[static_cast<std::size_t>(nd)].name)
                            : (ch == o.ambient_channel ? nlohmann::json("ambient") : nlohmann::json(nullptr)));
  }
  sm["channels"] = chmap;
  sm["breakpoints"] = nlohmann::json::array();
  for (int i = 0; i < m.n_breakpoints; ++i) {
    nlohmann::json b{{"speed_rpm", m.speed_rpm[i]}, {"a", m.a[i]}, {"b", m.b[i]}};
    b["c"] = std::vector<double>(m.c[i], m.c[i] + kModelChannels);
    b["d"] = std::vector<double>(m.d[i], m.d[i] + kModelChannels);
    sm["breakpoints"].push_back(b);
  }
  j["scheduled_model"] = sm;
  j["diagnosis"] = {{"warn_band_K", o.warn_K}, {"alarm_band_K", o.alarm_K}, {"abs_limit_c", o.abs_limit_c},
                    {"max_rise_K_per_min", o.max_rise_K_per_min}};
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
                    {"quantized_vs_double_max_K", r.deviation.quantized_vs_double_max_K}};
  return j;
}

}  // namespace btsm::thermal
