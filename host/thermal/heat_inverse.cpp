// Inverse heat-source estimation: Kalman filter + RTS smoother formulation of the Tikhonov problem
// (linear in the recording length), alpha rules (GCV, L-curve, discrepancy, Monte-Carlo baseline),
// and the dense stacked formulation of the paper as a reference. See heat_inverse.hpp.
#include "host/thermal/heat_inverse.hpp"

#include "host/io/json_input.hpp"
#include "host/thermal/model_file.hpp"
#include "host/thermal/simulator.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <cmath>
#include <limits>
#include <map>
#include <tuple>
#include <random>
#include <stdexcept>

namespace btsm::thermal {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Discrete step over one sample interval: x+ = A x + B q + a_amb * T_amb + f.
struct DiscreteStep {
  Eigen::MatrixXd A, B;
  Eigen::VectorXd a_amb, f;
  Eigen::MatrixXd a_bnd;   // n x boundaries: the declared boundary columns' gains
};

// Everything the smoother needs, precomputed once per problem (independent of alpha).
struct Prepared {
  int n = 0, m = 0, d = 0, N = 0, P = 0;
  std::vector<DiscreteStep> steps;       // distinct (speed, dt) discretisations
  std::vector<int> step_of_interval;     // N-1
  std::vector<int> piece_of_sample;      // N (last sample uses the last interval's piece)
  std::vector<int> first_sample_of_piece;
  std::vector<double> piece_start_s;
  Eigen::MatrixXd offset;                // n x (N-1): a_amb*T_amb + f per interval
  Eigen::MatrixXd H;                     // n_meas x n
  Eigen::MatrixXd y;                     // N x n_meas
  Eigen::VectorXd x0_mean;
  int n_obs = 0;
};

DiscreteStep discretise(const NodeMatrices& mats, const std::vector<int>& src, double dt, Discretisation scheme,
                        bool keep_model_sources) {
  const int n = static_cast<int>(mats.capacitance.size());
  const int m = static_cast<int>(src.size());
  if (mats.G.rows() != n || mats.G.cols() != n || mats.ambient_conductance.size() != n || mats.heat_w.size() != n)
    throw std::invalid_argument("heat inverse: thermal matrices have inconsistent sizes");
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(n, m);
  for (int j = 0; j < m; ++j) S(src[j], j) = 1.0;
  const Eigen::VectorXd q_model = keep_model_sources ? mats.heat_w : Eigen::VectorXd::Zero(n);
  DiscreteStep st;
  if (scheme == Discretisation::ExactZoh) {
    // The simulator's exact modal ZOH step (the one implementation shared by all areas).
    const StepMatrices sm = step_matrices(modal_form(mats), dt);
    st.A = sm.Phi;
    st.B = sm.Gamma * S;
    st.a_amb = sm.ambient_gain;
    st.a_bnd = sm.boundary_gain;
    st.f = sm.Gamma * q_model;
  } else {
    // Crank-Nicolson on the whole balance (conduction, ambient links and sources):
    // (C + dt/2 G) x+ = (C - dt/2 G) x + dt (g_amb T_amb + q + S u).
    const Eigen::MatrixXd Cd = mats.capacitance.asDiagonal();
    const Eigen::MatrixXd lhs = Cd + 0.5 * dt * mats.G;
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(lhs);
    st.A = lu.solve(Cd - 0.5 * dt * mats.G);
    st.B = lu.solve(dt * S);
    st.a_amb = lu.solve(dt * mats.ambient_conductance);
    st.a_bnd = mats.boundary_conductance.cols() > 0 ? Eigen::MatrixXd(lu.solve(dt * mats.boundary_conductance))
                                                     : Eigen::MatrixXd(n, 0);
    st.f = lu.solve(dt * q_model);
  }
  return st;
}

Prepared prepare(const InverseProblem& p, const HeatInverseOptions& o) {
  Prepared pr;
  pr.N = static_cast<int>(p.time_s.size());
  if (pr.N < 3) throw std::invalid_argument("heat inverse: need at least 3 samples");
  if (p.measured.rows() != pr.N || p.speed_rpm.size() != p.time_s.size() || p.ambient_c.size() != p.time_s.size())
    throw std::invalid_argument("heat inverse: time, speed, ambient and measured rows differ in length");
  if (!p.matrices && !p.matrices_at) throw std::invalid_argument("heat inverse: no thermal matrices provider");
  const bool events = !p.event_mask.empty();
  if (events && p.event_mask.size() != p.time_s.size()) throw std::invalid_argument("heat inverse: event states and time differ in length");
  if (events && !p.matrices_at) throw std::invalid_argument("heat inverse: event states need the matrices_at provider");
  if (p.boundary_c.cols() > 0 && p.boundary_c.rows() != static_cast<Eigen::Index>(p.time_s.size()))
    throw std::invalid_argument("heat inverse: boundary temperatures and time differ in length");
  auto matrices = [&](double speed, unsigned mask) { return p.matrices_at ? p.matrices_at(speed, mask) : p.matrices(speed); };
  if (!(o.step_s > 0)) throw std::invalid_argument("heat inverse: --step must be > 0 s");
  if (p.source_nodes.empty()) throw std::invalid_argument("heat inverse: no source nodes selected");
  const NodeMatrices m0 = matrices(p.speed_rpm[0], events ? p.event_mask[0] : 0u);
  if (m0.boundary_conductance.cols() != p.boundary_c.cols())
    throw std::invalid_argument("heat inverse: the network has " + std::to_string(m0.boundary_conductance.cols()) +
                                " boundary column(s), the problem gives " + std::to_string(p.boundary_c.cols()));
  pr.n = static_cast<int>(m0.capacitance.size());
  pr.m = static_cast<int>(p.source_nodes.size());
  pr.d = pr.n + pr.m;
  for (int s : p.source_nodes)
    if (s < 0 || s >= pr.n) throw std::invalid_argument("heat inverse: source node index out of range");
  if (p.measure_map.cols() != pr.n || p.measure_map.rows() != p.measured.cols())
    throw std::invalid_argument("heat inverse: measurement map does not match the network/recording");
  pr.H = p.measure_map;
  pr.y = p.measured;

  std::map<std::tuple<double, unsigned, double>, int> cache;
  std::map<std::pair<double, unsigned>, NodeMatrices> mats_cache;
  pr.step_of_interval.resize(pr.N - 1);
  pr.offset.resize(pr.n, pr.N - 1);
  std::map<std::pair<long long, long long>, int> piece_ids;  // (operating segment, step): both ascend with time
  long long segment = 0;
  double segment_start_s = p.time_s[0];
  std::vector<int> piece_of_interval(pr.N - 1);
  const double t0 = p.time_s[0];
  for (int k = 0; k + 1 < pr.N; ++k) {
    const double dt = p.time_s[k + 1] - p.time_s[k];
    if (!(dt > 0)) throw std::invalid_argument("heat inverse: time is not strictly increasing at sample " + std::to_string(k + 1));
    if (!std::isfinite(p.speed_rpm[k]) || !std::isfinite(p.ambient_c[k]))
      throw std::invalid_argument("heat inverse: speed or ambient missing at sample " + std::to_string(k));
    const double dt_key = std::round(dt * 1e6) / 1e6;
    const unsigned mask = events ? p.event_mask[static_cast<std::size_t>(k)] : 0u;
    const auto key = std::make_tuple(p.speed_rpm[k], mask, dt_key);
    auto it = cache.find(key);
    if (it == cache.end()) {
      const auto mkey = std::make_pair(p.speed_rpm[k], mask);
      auto mit = mats_cache.find(mkey);
      if (mit == mats_cache.end()) mit = mats_cache.emplace(mkey, matrices(p.speed_rpm[k], mask)).first;
      pr.steps.push_back(discretise(mit->second, p.source_nodes, dt, o.scheme, p.keep_model_sources));
      it = cache.emplace(key, static_cast<int>(pr.steps.size()) - 1).first;
    }
    pr.step_of_interval[k] = it->second;
    const DiscreteStep& st = pr.steps[it->second];
    pr.offset.col(k) = st.a_amb * p.ambient_c[k] + st.f;
    if (p.boundary_c.cols() > 0) pr.offset.col(k) += st.a_bnd * p.boundary_c.row(k).transpose();
    const long long raw = static_cast<long long>(std::floor((p.time_s[k] - t0) / o.step_s + 1e-9));
    if (o.break_at_speed_changes && k > 0 &&
        (p.speed_rpm[k] != p.speed_rpm[k - 1] || (events && p.event_mask[static_cast<std::size_t>(k)] != p.event_mask[static_cast<std::size_t>(k - 1)]))) {
      ++segment;
      segment_start_s = p.time_s[k];
    }
    const auto piece_key = std::make_pair(segment, raw);
    auto pit = piece_ids.find(piece_key);
    if (pit == piece_ids.end()) {
      pit = piece_ids.emplace(piece_key, static_cast<int>(piece_ids.size())).first;
      pr.piece_start_s.push_back(std::max(t0 + static_cast<double>(raw) * o.step_s, segment_start_s));
      pr.first_sample_of_piece.push_back(k);
    }
    piece_of_interval[k] = pit->second;
  }
  pr.P = static_cast<int>(pr.piece_start_s.size());
  pr.piece_of_sample.resize(pr.N);
  for (int k = 0; k + 1 < pr.N; ++k) pr.piece_of_sample[k] = piece_of_interval[k];
  pr.piece_of_sample[pr.N - 1] = piece_of_interval[pr.N - 2];

  pr.x0_mean = p.initial_state_c;
  if (pr.x0_mean.size() != pr.n) throw std::invalid_argument("heat inverse: initial state has the wrong size");
  pr.n_obs = 0;
  for (int k = 0; k < pr.N; ++k)
    for (int c = 0; c < pr.y.cols(); ++c)
      if (std::isfinite(pr.y(k, c))) ++pr.n_obs;
  if (pr.n_obs < pr.d + 1) throw std::invalid_argument("heat inverse: too few measured values");
  return pr;
}

// Result of one smoother run.
struct SmoothOut {
  AlphaPoint point;
  Eigen::MatrixXd q;        // P x m
  Eigen::MatrixXd q_var;    // P x m
  Eigen::MatrixXd x;        // N x n (only when full)
};

// The stacked (dense) solution of one alpha, Li et al. (2022) eq. form: unknowns x0 and every
// piece's sources at once. Exact where the smoother's covariance recursion loses precision (few
// long pieces against fast modes); its cost grows with the unknowns, so only for small problems.
constexpr int kDenseFallbackUnknowns = 400;  // J is n_obs x unknowns: 14,400 rows x 400 = 46 MB

SmoothOut dense_point(const Prepared& pr, const HeatInverseOptions& o, double alpha, double sigma) {
  const int n = pr.n, m = pr.m, P = pr.P, N = pr.N, nu = n + m * P;
  const double r = sigma * sigma;
  // Sensitivity of x_k to theta = [x0; q_0 .. q_{P-1}] and the known part, propagated forward.
  Eigen::MatrixXd X = Eigen::MatrixXd::Zero(n, nu);
  X.leftCols(n).setIdentity();
  Eigen::VectorXd xr = Eigen::VectorXd::Zero(n);
  Eigen::MatrixXd J(pr.n_obs, nu);
  Eigen::VectorXd rhs(pr.n_obs);
  std::vector<std::pair<int, int>> rows;  // (k, channel) of each row of J
  int row = 0;
  for (int k = 0; k < N; ++k) {
    if (k > 0) {
      const DiscreteStep& st = pr.steps[pr.step_of_interval[k - 1]];
      X = st.A * X;
      X.middleCols(n + m * pr.piece_of_sample[k - 1], m) += st.B;
      xr = st.A * xr + pr.offset.col(k - 1);
    }
    for (int c = 0; c < pr.y.cols(); ++c) {
      if (!std::isfinite(pr.y(k, c))) continue;
      J.row(row) = pr.H.row(c) * X;
      rhs(row) = pr.y(k, c) - pr.H.row(c).dot(xr);
      rows.emplace_back(k, c);
      ++row;
    }
  }
  Eigen::MatrixXd A = J.transpose() * J / r;
  Eigen::VectorXd b = J.transpose() * rhs / r;
  const double px = 1.0 / (o.initial_state_sigma_k * o.initial_state_sigma_k);
  A.topLeftCorner(n, n).diagonal().array() += px;
  b.head(n) += px * pr.x0_mean;
  const double w = alpha / r;
  if (o.order == TikhonovOrder::Zero) {
    A.bottomRightCorner(m * P, m * P).diagonal().array() += w;
  } else {
    A.block(n, n, m, m).diagonal().array() += 1.0 / (o.first_source_sigma_w * o.first_source_sigma_w);
    for (int p2 = 0; p2 + 1 < P; ++p2)
      for (int j = 0; j < m; ++j) {
        const int a = n + m * p2 + j, c = n + m * (p2 + 1) + j;
        A(a, a) += w; A(c, c) += w; A(a, c) -= w; A(c, a) -= w;
      }
  }
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(A);
  const Eigen::VectorXd theta = ldlt.solve(b);
  const Eigen::MatrixXd Ainv = ldlt.solve(Eigen::MatrixXd::Identity(nu, nu));
  SmoothOut s;
  s.q.resize(P, m);
  s.q_var.resize(P, m);
  for (int p2 = 0; p2 < P; ++p2)
    for (int j = 0; j < m; ++j) {
      s.q(p2, j) = theta(n + m * p2 + j);
      s.q_var(p2, j) = Ainv(n + m * p2 + j, n + m * p2 + j);
    }
  // Fitted states by forward simulation with the estimate.
  s.x.resize(N, n);
  Eigen::VectorXd x = theta.head(n);
  for (int k = 0; k < N; ++k) {
    if (k > 0) {
      const DiscreteStep& st = pr.steps[pr.step_of_interval[k - 1]];
      x = st.A * x + st.B * s.q.row(pr.piece_of_sample[k - 1]).transpose() + pr.offset.col(k - 1);
    }
    s.x.row(k) = x.transpose();
  }
  const Eigen::VectorXd resid = rhs - J * theta;
  s.point.alpha = alpha;
  s.point.rss_k2 = resid.squaredNorm();
  // trace(J Ainv J^T) / r = sum(Ainv .* J^T J) / r: no n_obs x n_obs product
  s.point.dof = (Ainv.cwiseProduct(J.transpose() * J)).sum() / r;
  double semi = 0;
  if (o.order == TikhonovOrder::One) {
    for (int p2 = 0; p2 + 1 < P; ++p2) semi += (s.q.row(p2 + 1) - s.q.row(p2)).squaredNorm();
  } else {
    semi = s.q.squaredNorm();
  }
  s.point.seminorm_w2 = semi;
  const double denom = pr.n_obs - s.point.dof;
  const bool dof_valid = s.point.dof >= 0 && s.point.dof <= pr.n_obs;
  s.point.gcv = dof_valid && denom > 0 ? pr.n_obs * s.point.rss_k2 / (denom * denom) : std::numeric_limits<double>::infinity();
  return s;
}


SmoothOut smooth(const Prepared& pr, const HeatInverseOptions& o, double alpha, double sigma, bool full) {
  const int n = pr.n, m = pr.m, d = pr.d, N = pr.N;
  const double r = sigma * sigma;
  const double qw = r / alpha;              // process noise of the source at each step boundary [W^2]
  const bool order1 = o.order == TikhonovOrder::One;
  std::vector<Eigen::VectorXd> zf(N);
  std::vector<Eigen::MatrixXd> Pf(N);

  // transition k -> k+1
  auto make_F = [&](int k, Eigen::MatrixXd& F, bool& boundary) {
    const DiscreteStep& st = pr.steps[pr.step_of_interval[k]];
    F.setZero(d, d);
    F.topLeftCorner(n, n) = st.A;
    F.topRightCorner(n, m) = st.B;
    boundary = pr.piece_of_sample[k + 1] != pr.piece_of_sample[k];
    const double rho = (boundary && !order1) ? 0.0 : 1.0;
    F.bottomRightCorner(m, m) = rho * Eigen::MatrixXd::Identity(m, m);
  };
  auto predict = [&](int k, const Eigen::MatrixXd& F, bool boundary, const Eigen::VectorXd& z, const Eigen::MatrixXd& P,
                     Eigen::VectorXd& zp, Eigen::MatrixXd& Pp) {
    zp = F * z;
    zp.head(n) += pr.offset.col(k);
    Pp = F * P * F.transpose();
    if (boundary) Pp.bottomRightCorner(m, m).diagonal().array() += qw;
    Pp = 0.5 * (Pp + Pp.transpose());
  };

  Eigen::VectorXd z = Eigen::VectorXd::Zero(d);
  z.head(n) = pr.x0_mean;
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(d, d);
  P.topLeftCorner(n, n).diagonal().setConstant(o.initial_state_sigma_k * o.initial_state_sigma_k);
  P.bottomRightCorner(m, m).diagonal().setConstant(order1 ? o.first_source_sigma_w * o.first_source_sigma_w : qw);
  Eigen::MatrixXd F;
  bool boundary = false;
  std::vector<int> valid;
  valid.reserve(pr.y.cols());
  for (int k = 0; k < N; ++k) {
    if (k > 0) {
      make_F(k - 1, F, boundary);
      Eigen::VectorXd zp;
      Eigen::MatrixXd Pp;
      predict(k - 1, F, boundary, z, P, zp, Pp);
      z = std::move(zp);
      P = std::move(Pp);
    }
    valid.clear();
    for (int c = 0; c < pr.y.cols(); ++c)
      if (std::isfinite(pr.y(k, c))) valid.push_back(c);
    if (!valid.empty()) {
      const int nv = static_cast<int>(valid.size());
      Eigen::MatrixXd Hv = Eigen::MatrixXd::Zero(nv, d);
      Eigen::VectorXd yv(nv);
      for (int i = 0; i < nv; ++i) {
        Hv.row(i).head(n) = pr.H.row(valid[i]);
        yv(i) = pr.y(k, valid[i]);
      }
      const Eigen::MatrixXd PHt = P * Hv.transpose();
      Eigen::MatrixXd S = Hv * PHt;
      S.diagonal().array() += r;
      const Eigen::LLT<Eigen::MatrixXd> llt(S);
      const Eigen::MatrixXd K = llt.solve(PHt.transpose()).transpose();
      z += K * (yv - Hv * z);
      const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(d, d) - K * Hv;
      P = IKH * P * IKH.transpose() + r * K * K.transpose();
      P = 0.5 * (P + P.transpose());
    }
    zf[k] = z;
    Pf[k] = P;
  }

  SmoothOut out;
  out.q.resize(pr.P, m);
  out.q_var.resize(pr.P, m);
  if (full) out.x.resize(N, n);
  double rss = 0, dof = 0;
  Eigen::VectorXd zs = zf[N - 1];
  Eigen::MatrixXd Ps = Pf[N - 1];
  auto account = [&](int k) {
    for (int c = 0; c < pr.y.cols(); ++c) {
      if (!std::isfinite(pr.y(k, c))) continue;
      const double e = pr.y(k, c) - pr.H.row(c).dot(zs.head(n));
      rss += e * e;
      dof += pr.H.row(c).dot(Ps.topLeftCorner(n, n) * pr.H.row(c).transpose()) / r;
    }
    if (full) out.x.row(k) = zs.head(n).transpose();
    const int piece = pr.piece_of_sample[k];
    if (pr.first_sample_of_piece[piece] == k || k == N - 1) {
      out.q.row(piece) = zs.tail(m).transpose();
      out.q_var.row(piece) = Ps.bottomRightCorner(m, m).diagonal().transpose();
    }
  };
  account(N - 1);
  for (int k = N - 2; k >= 0; --k) {
    make_F(k, F, boundary);
    Eigen::VectorXd zp;
    Eigen::MatrixXd Pp;
    predict(k, F, boundary, zf[k], Pf[k], zp, Pp);
    // G = Pf F^T Pp^{-1}, via a symmetric solve (Pp is SPD).
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(Pp);
    const Eigen::MatrixXd G = ldlt.solve(F * Pf[k]).transpose();
    zs = zf[k] + G * (zs - zp);
    Ps = Pf[k] + G * (Ps - Pp) * G.transpose();
    Ps = 0.5 * (Ps + Ps.transpose());
    account(k);
  }
  double semi = 0;
  if (order1) {
    for (int p = 0; p + 1 < pr.P; ++p) semi += (out.q.row(p + 1) - out.q.row(p)).squaredNorm();
  } else {
    semi = out.q.squaredNorm();
  }
  out.point.alpha = alpha;
  out.point.rss_k2 = rss;
  out.point.seminorm_w2 = semi;
  out.point.dof = dof;
  const double denom = pr.n_obs - dof;
  // The trace of an influence matrix lies in [0, N]. Outside it the smoothed covariance has lost
  // its positive definiteness (long steps against fast modes, a model that does not fit the
  // recording): such a point's GCV says nothing, and a -566,419 "effective parameters" once won it.
  const bool dof_valid = dof >= 0 && dof <= pr.n_obs;
  // The covariance recursion loses precision when few long pieces meet fast modes (heat --step
  // 900 on 5 s rows: "effective parameters 1e29"). Such a problem has few unknowns: solve it
  // stacked, exactly (a 6 h recording at 900 s steps: 52 unknowns).
  if (!dof_valid && pr.n + pr.m * pr.P <= kDenseFallbackUnknowns) return dense_point(pr, o, alpha, sigma);
  out.point.gcv = dof_valid && denom > 0 ? pr.n_obs * rss / (denom * denom) : std::numeric_limits<double>::infinity();
  return out;
}

HeatInverseResult finish(const Prepared& pr, const HeatInverseOptions& o, const SmoothOut& s, double sigma,
                         bool estimated) {
  HeatInverseResult res;
  res.piece_start_s = pr.piece_start_s;
  res.heat_w = s.q;
  res.heat_sigma_w = s.q_var.cwiseMax(0.0).cwiseSqrt();
  res.fitted_c = s.x;
  res.alpha = s.point.alpha;
  res.noise_sigma_k = sigma;
  res.noise_estimated = estimated;
  res.rss_k2 = s.point.rss_k2;
  res.dof = s.point.dof;
  res.residual_rms_k = std::sqrt(s.point.rss_k2 / pr.n_obs);
  const int nm = static_cast<int>(pr.y.cols());
  res.residual_rms_per_channel_k = Eigen::VectorXd::Constant(nm, kNaN);
  for (int c = 0; c < nm; ++c) {
    double ss = 0;
    int cnt = 0;
    for (int k = 0; k < pr.N; ++k) {
      if (!std::isfinite(pr.y(k, c))) continue;
      const double e = pr.y(k, c) - pr.H.row(c).dot(s.x.row(k));
      ss += e * e;
      ++cnt;
    }
    if (cnt > 0) res.residual_rms_per_channel_k(c) = std::sqrt(ss / cnt);
  }
  (void)o;
  return res;
}

double resolve_sigma(const InverseProblem& p, const HeatInverseOptions& o, bool& estimated) {
  estimated = !(o.noise_sigma_k > 0);
  return estimated ? estimate_noise_sigma(p.measured) : o.noise_sigma_k;
}

std::vector<double> log_grid(double lo, double hi, int count) {
  if (!(lo > 0) || !(hi > lo) || count < 3) throw std::invalid_argument("heat inverse: bad alpha grid (need 0 < min < max, >= 3 points)");
  std::vector<double> g(count);
  for (int i = 0; i < count; ++i) g[i] = lo * std::pow(hi / lo, static_cast<double>(i) / (count - 1));
  return g;
}

}  // namespace

TikhonovOrder parse_tikhonov_order(const std::string& s) {
  if (s == "tikhonov0") return TikhonovOrder::Zero;
  if (s == "tikhonov1") return TikhonovOrder::One;
  throw std::invalid_argument("unknown method '" + s + "' (expected tikhonov0 or tikhonov1)");
}
AlphaRule parse_alpha_rule(const std::string& s) {
  if (s == "gcv") return AlphaRule::Gcv;
  if (s == "lcurve") return AlphaRule::LCurve;
  if (s == "discrepancy") return AlphaRule::Discrepancy;
  if (s == "montecarlo") return AlphaRule::MonteCarlo;
  if (s == "fixed") return AlphaRule::Fixed;
  throw std::invalid_argument("unknown alpha rule '" + s + "' (expected gcv, lcurve, discrepancy, montecarlo or fixed)");
}
std::string to_string(TikhonovOrder o) { return o == TikhonovOrder::Zero ? "tikhonov0" : "tikhonov1"; }
std::string to_string(AlphaRule r) {
  switch (r) {
    case AlphaRule::Gcv: return "gcv";
    case AlphaRule::LCurve: return "lcurve";
    case AlphaRule::Discrepancy: return "discrepancy";
    case AlphaRule::MonteCarlo: return "montecarlo";
    case AlphaRule::Fixed: return "fixed";
  }
  return "?";
}

double estimate_noise_sigma(const Eigen::MatrixXd& measured) {
  std::vector<double> per_channel;
  for (int c = 0; c < measured.cols(); ++c) {
    std::vector<double> d2;
    for (int k = 1; k + 1 < measured.rows(); ++k) {
      const double a = measured(k - 1, c), b = measured(k, c), e = measured(k + 1, c);
      if (std::isfinite(a) && std::isfinite(b) && std::isfinite(e)) d2.push_back(a - 2 * b + e);
    }
    if (d2.size() < 10) continue;
    auto median = [](std::vector<double> v) {
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      return v[v.size() / 2];
    };
    const double med = median(d2);
    std::vector<double> dev(d2.size());
    for (size_t i = 0; i < d2.size(); ++i) dev[i] = std::abs(d2[i] - med);
    double s = 1.4826 * median(dev) / std::sqrt(6.0);
    if (!(s > 0)) {  // quantised data: MAD can be 0, fall back to the rms
      double ss = 0;
      for (double v : d2) ss += v * v;
      s = std::sqrt(ss / d2.size() / 6.0);
    }
    // A reading quantised to q cannot be known better than q / sqrt(12) (the rms of the rounding).
    // Where the noise is below q most second differences are 0 up to round-off, and the MAD
    // collapses to ~1e-15 K (seen on 1 mK logs); the decision's noise thresholds would then
    // call any residual significant. q = the smallest step between consecutive samples (a step
    // below 1e-9 of the value is round-off of the decimal text, not a reading step).
    double q = std::numeric_limits<double>::infinity();
    for (int k = 1; k < measured.rows(); ++k) {
      const double a = measured(k - 1, c), b = measured(k, c);
      const double d = std::abs(b - a);
      if (std::isfinite(d) && d > 1e-9 * std::max(1.0, std::abs(b))) q = std::min(q, d);
    }
    if (std::isfinite(q)) s = std::max(s, q / std::sqrt(12.0));
    if (s > 0) per_channel.push_back(s);
  }
  if (per_channel.empty())
    throw std::invalid_argument("cannot estimate the noise level: no measured temperature column has 12 consecutive readings "
                                "that vary (" + std::to_string(measured.rows()) + " rows, " + std::to_string(measured.cols()) +
                                " measured columns)");
  std::sort(per_channel.begin(), per_channel.end());
  return per_channel[per_channel.size() / 2];
}

ModelWithParameters load_model_with_parameters(const std::string& path_or_preset) {
  ModelWithParameters m;
  m.source = path_or_preset;
  std::error_code ec;
  // Something on disk by that name (a symbolic-link loop or a dangling link too) is read as a file,
  // so the reader names what is wrong with it; a loop was "neither a readable file nor a preset".
  if (!std::filesystem::exists(std::filesystem::symlink_status(path_or_preset, ec))) {
    const std::vector<std::string> presets = preset_names();
    if (std::find(presets.begin(), presets.end(), path_or_preset) == presets.end())
      throw std::invalid_argument("model '" + path_or_preset + "' is neither a readable file nor a preset name");
    m.network = preset_network(path_or_preset);
    m.params = default_parameters(m.network);
  } else {
    // Through the capped, depth-guarded reader like every other input: a JSON nested 100,000 deep
    // overflowed the stack here, and a directory or a device got a stream error, not its name.
    const nlohmann::json j = io::read_json_file(path_or_preset, std::max(kMaxModelBytes, kMaxNetworkBytes), "model or network JSON");
    if (j.is_object() && (j.contains("network") || j.contains("format"))) {
      // the fitted-model JSON written by `btsm fit` (model_file.hpp)
      const FittedModel fm = model_from_json(j, path_or_preset);
      m.network = fm.network;
      m.params = fm.params;
      m.channel_map = fm.channel_map;
    } else {
      m.network = network_from_json(j, path_or_preset);
      m.params = default_parameters(m.network);
    }
  }
  for (int i = 0; i < m.network.param_count(); ++i)
    if (!std::isfinite(m.params(i)))
      throw std::invalid_argument(path_or_preset + ": parameter '" + m.network.params[i].name +
                                  "' has no value (fit the model first and pass the fit result)");
  // A network's nominal values face the same checks as a fitted model's (bounds, capacitances,
  // stability): a resistance of -1 K/W would be used as given otherwise.
  if (const std::string problems = model_problems(m.network, m.params); !problems.empty())
    throw std::invalid_argument(path_or_preset + ": not a usable model: " + problems);
  return m;
}

std::vector<std::string> measured_columns(const Network& net, const Recording& rec) {
  std::vector<std::string> cols;
  for (const Measurement& m : net.measurements)
    if (rec.channel_index(m.column) >= 0) cols.push_back(m.column);
  return cols;
}

InverseProblem make_inverse_problem(const Network& net, const Eigen::VectorXd& params, const Recording& rec,
                                    std::vector<int> source_nodes, bool keep_model_sources) {
  if (params.size() != net.param_count())
    throw std::invalid_argument("heat inverse: " + std::to_string(params.size()) + " parameter values for a network with " +
                                std::to_string(net.param_count()) + " parameters");
  InverseProblem p;
  p.time_s = rec.time_s;
  p.speed_rpm = rec.speed_rpm;
  p.ambient_c = rec.ambient_c;
  const int n = net.node_count();
  std::vector<int> rec_col, node_of;
  std::vector<double> drift_k_per_h;
  for (const Measurement& m : net.measurements) {
    const int c = rec.channel_index(m.column);
    if (c < 0) continue;
    rec_col.push_back(c);
    node_of.push_back(m.node);
    drift_k_per_h.push_back(m.drift_param >= 0 ? params[m.drift_param] : 0.0);
  }
  if (rec_col.empty())
    throw std::invalid_argument("heat inverse: none of the network's measured columns is in " + rec.source);
  const int nm = static_cast<int>(rec_col.size());
  p.measured.resize(static_cast<Eigen::Index>(rec.rows()), nm);
  p.measure_map = Eigen::MatrixXd::Zero(nm, n);
  for (int j = 0; j < nm; ++j) {
    p.measured.col(j) = rec.temp_c.col(rec_col[j]);
    p.measure_map(j, node_of[j]) = 1.0;
    // a drifting probe (network.hpp): its node's temperature is the reading minus the drift
    if (drift_k_per_h[static_cast<std::size_t>(j)] != 0.0)
      for (Eigen::Index k = 0; k < p.measured.rows(); ++k)
        p.measured(k, j) -= drift_k_per_h[static_cast<std::size_t>(j)] * (rec.time_s[static_cast<std::size_t>(k)] - rec.time_s.front()) / 3600.0;
  }
  if (source_nodes.empty()) {
    for (const Source& s : net.sources)
      if (std::find(source_nodes.begin(), source_nodes.end(), s.node) == source_nodes.end()) source_nodes.push_back(s.node);
    std::sort(source_nodes.begin(), source_nodes.end());
  }
  if (source_nodes.empty()) throw std::invalid_argument("heat inverse: the network has no heat sources; name the nodes to estimate");
  for (int s : source_nodes)
    if (s < 0 || s >= n) throw std::invalid_argument("heat inverse: source node index " + std::to_string(s) + " out of range");
  p.source_nodes = source_nodes;
  p.keep_model_sources = keep_model_sources;
  p.matrices = [net, params](double speed) { return assemble(net, params, speed); };
  if (net.has_inputs()) {
    const RecordingInputs in = recording_inputs(net, rec);
    p.event_mask = in.event_mask;
    p.boundary_c = in.boundary_c;
    p.matrices_at = [net, params](double speed, unsigned mask) { return assemble(net, params, speed, mask); };
  }
  // Prior mean of the initial state: first measured value per node, the mean of those elsewhere.
  Eigen::VectorXd x0 = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::quiet_NaN());
  double sum = 0;
  int cnt = 0;
  for (int j = 0; j < nm; ++j) {
    for (Eigen::Index k = 0; k < p.measured.rows() && k < 20; ++k)
      if (std::isfinite(p.measured(k, j))) { x0(node_of[j]) = p.measured(k, j); sum += p.measured(k, j); ++cnt; break; }
  }
  const double fill = cnt > 0 ? sum / cnt : rec.ambient_c.front();
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(x0(i))) x0(i) = fill;
  p.initial_state_c = x0;
  return p;
}

HeatInverseResult solve_heat_inverse_fixed(const InverseProblem& p, const HeatInverseOptions& o, double alpha) {
  if (!(alpha > 0)) throw std::invalid_argument("heat inverse: alpha must be > 0");
  const Prepared pr = prepare(p, o);
  bool est = false;
  const double sigma = resolve_sigma(p, o, est);
  HeatInverseResult res = finish(pr, o, smooth(pr, o, alpha, sigma, true), sigma, est);
  res.rule = "fixed";
  return res;
}

HeatInverseResult solve_heat_inverse(const InverseProblem& p, const HeatInverseOptions& o) {
  if (o.rule == AlphaRule::Fixed) return solve_heat_inverse_fixed(p, o, o.alpha_fixed);
  const Prepared pr = prepare(p, o);
  bool est = false;
  const double sigma = resolve_sigma(p, o, est);
  const auto started = std::chrono::steady_clock::now();
  auto last_report = started;
  int evaluated = 0;
  const std::string of_total = o.rule == AlphaRule::MonteCarlo ? std::string() : " of " + std::to_string(o.alpha_points);
  auto eval = [&](double a) {
    const AlphaPoint pt = smooth(pr, o, a, sigma, false).point;
    ++evaluated;
    const auto now = std::chrono::steady_clock::now();
    if (o.progress && now - last_report > std::chrono::seconds(5)) {
      last_report = now;
      o.progress("alpha scan: " + std::to_string(evaluated) + of_total + " points, " +
                 std::to_string(std::chrono::duration_cast<std::chrono::seconds>(now - started).count()) + " s");
    }
    return pt;
  };
  std::vector<AlphaPoint> scan;
  double chosen = 0;
  int mc_evals = 0;
  const double target = o.discrepancy_tau * o.discrepancy_tau * pr.n_obs * sigma * sigma;

  if (o.rule == AlphaRule::MonteCarlo) {
    // Li et al. 2022 ICO search (Eq. 40-42) with the stopping threshold tied to the noise level:
    // W = |Z_alpha - Z| / |Z| <= eps, eps = tau * sigma * sqrt(N) / |Z|  <=>  RSS <= tau^2 N sigma^2.
    std::mt19937 rng(o.mc_seed);
    double lo = o.alpha_min, hi = o.alpha_max;
    double best_alpha = hi, best_rss = std::numeric_limits<double>::infinity();
    bool met = false;
    for (int round = 0; round < o.mc_max_rounds && !met; ++round) {
      const double delta = hi - lo;
      std::uniform_real_distribution<double> u(0.0, delta);
      double round_alpha = hi, round_rss = std::numeric_limits<double>::infinity();
      for (int s = 0; s < o.mc_samples_per_round; ++s) {
        const double a = std::max(lo + u(rng), std::numeric_limits<double>::min());
        const AlphaPoint pt = eval(a);
        ++mc_evals;
        scan.push_back(pt);
        if (pt.rss_k2 < round_rss) { round_rss = pt.rss_k2; round_alpha = a; }
        // Of the samples meeting the threshold, keep the most regularised one.
        if (pt.rss_k2 <= target && (!met || a > best_alpha)) { met = true; best_alpha = a; best_rss = pt.rss_k2; }
      }
      if (!met) {
        if (round_rss < best_rss) { best_rss = round_rss; best_alpha = round_alpha; }
        if (round_alpha - lo < 0.5 * delta) hi -= 0.5 * delta; else lo += 0.5 * delta;
      }
    }
    chosen = best_alpha;
  } else {
    const std::vector<double> grid = log_grid(o.alpha_min, o.alpha_max, o.alpha_points);
    for (double a : grid) scan.push_back(eval(a));
    const int G = static_cast<int>(grid.size());
    if (o.rule == AlphaRule::Gcv) {
      int best = 0;
      for (int i = 1; i < G; ++i) if (scan[i].gcv < scan[best].gcv) best = i;
      // golden-section refinement in log(alpha) inside the neighbouring grid points
      double a = std::log(grid[std::max(best - 1, 0)]), b = std::log(grid[std::min(best + 1, G - 1)]);
      const double gr = 0.5 * (std::sqrt(5.0) - 1.0);
      double c = b - gr * (b - a), dd = a + gr * (b - a);
      AlphaPoint pc = eval(std::exp(c)), pd = eval(std::exp(dd));
      for (int it = 0; it < 14; ++it) {
        if (pc.gcv < pd.gcv) { b = dd; dd = c; pd = pc; c = b - gr * (b - a); pc = eval(std::exp(c)); }
        else { a = c; c = dd; pc = pd; dd = a + gr * (b - a); pd = eval(std::exp(dd)); }
      }
      const AlphaPoint& pm = pc.gcv < pd.gcv ? pc : pd;
      chosen = pm.gcv < scan[best].gcv ? pm.alpha : grid[best];
    } else if (o.rule == AlphaRule::LCurve) {
      // Corner = maximum curvature of (log RSS, log seminorm) parametrised by log alpha.
      int best = -1;
      double best_k = -std::numeric_limits<double>::infinity();
      for (int i = 1; i + 1 < G; ++i) {
        auto X = [&](int j) { return std::log(std::max(scan[j].rss_k2, 1e-300)); };
        auto Y = [&](int j) { return std::log(std::max(scan[j].seminorm_w2, 1e-300)); };
        const double h = std::log(grid[i + 1]) - std::log(grid[i]);
        const double x1 = (X(i + 1) - X(i - 1)) / (2 * h), y1 = (Y(i + 1) - Y(i - 1)) / (2 * h);
        const double x2 = (X(i + 1) - 2 * X(i) + X(i - 1)) / (h * h), y2 = (Y(i + 1) - 2 * Y(i) + Y(i - 1)) / (h * h);
        const double den = std::pow(x1 * x1 + y1 * y1, 1.5);
        if (!(den > 0)) continue;
        const double kappa = (x1 * y2 - y1 * x2) / den;
        if (kappa > best_k) { best_k = kappa; best = i; }
      }
      chosen = best >= 0 ? grid[best] : grid[G / 2];
    } else {  // discrepancy: the largest alpha whose RSS does not exceed tau^2 N sigma^2
      int last_ok = -1;
      for (int i = 0; i < G; ++i) if (scan[i].rss_k2 <= target) last_ok = i;
      if (last_ok < 0) chosen = grid.front();
      else if (last_ok == G - 1) chosen = grid.back();
      else {
        double a = std::log(grid[last_ok]), b = std::log(grid[last_ok + 1]);
        for (int it = 0; it < 20; ++it) {
          const double mid = 0.5 * (a + b);
          if (eval(std::exp(mid)).rss_k2 <= target) a = mid; else b = mid;
        }
        chosen = std::exp(a);
      }
    }
  }
  HeatInverseResult res = finish(pr, o, smooth(pr, o, chosen, sigma, true), sigma, est);
  std::sort(scan.begin(), scan.end(), [](const AlphaPoint& a, const AlphaPoint& b) { return a.alpha < b.alpha; });
  res.scan = std::move(scan);
  res.rule = to_string(o.rule);
  res.monte_carlo_evaluations = mc_evals;
  return res;
}

HeatInverseResult solve_heat_inverse_dense(const InverseProblem& p, const HeatInverseOptions& o, double alpha) {
  const Prepared pr = prepare(p, o);
  bool est = false;
  const double sigma = resolve_sigma(p, o, est);
  const SmoothOut s = dense_point(pr, o, alpha, sigma);
  HeatInverseResult res = finish(pr, o, s, sigma, est);
  res.rule = "fixed (dense)";
  res.scan = {s.point};
  return res;
}

}  // namespace btsm::thermal
