// Exact ZOH simulator in the symmetric modal form (see simulator.hpp for the formulas).
#include "simulator.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <unsupported/Eigen/MatrixFunctions>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace btsm::thermal {

ModalForm modal_form(const NodeMatrices& m) {
  ModalForm f;
  f.m = m;
  const Eigen::Index n = m.capacitance.size();
  for (Eigen::Index i = 0; i < n; ++i)
    if (!(m.capacitance[i] > 0) || !std::isfinite(m.capacitance[i]))
      throw std::invalid_argument("thermal network: node capacitance must be positive and finite");
  if (!m.G.allFinite()) throw std::invalid_argument("thermal network: a conductance is not finite (zero resistance?)");
  f.c_sqrt = m.capacitance.cwiseSqrt();
  const double gscale = std::max(m.G.cwiseAbs().maxCoeff(), 1e-300);
  if ((m.G - m.G.transpose()).cwiseAbs().maxCoeff() > 1e-14 * gscale) {
    f.general = true;
    return f;
  }
  const Eigen::VectorXd inv = f.c_sqrt.cwiseInverse();
  const Eigen::MatrixXd S = inv.asDiagonal() * m.G * inv.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(S);
  if (es.info() != Eigen::Success) throw std::runtime_error("thermal network: eigen decomposition failed");
  f.lambda = es.eigenvalues();
  f.V = es.eigenvectors();
  return f;
}

namespace {
// Phi = exp(A dt) and Gamma = int_0^dt exp(A s) ds C^-1 from one exponential of the block matrix
// [[A, I], [0, 0]] dt (Van Loan), for a non-symmetric G.
StepMatrices general_step_matrices(const ModalForm& f, double dt) {
  const Eigen::Index n = f.m.capacitance.size();
  const Eigen::VectorXd cinv = f.m.capacitance.cwiseInverse();
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  M.topLeftCorner(n, n) = -(cinv.asDiagonal() * f.m.G) * dt;
  M.topRightCorner(n, n) = Eigen::MatrixXd::Identity(n, n) * dt;
  const Eigen::MatrixXd E = M.exp();
  StepMatrices s;
  s.Phi = E.topLeftCorner(n, n);
  s.Gamma = E.topRightCorner(n, n) * cinv.asDiagonal();
  s.drive = s.Gamma * f.m.heat_w;
  s.ambient_gain = s.Gamma * f.m.ambient_conductance;
  s.boundary_gain = s.Gamma * f.m.boundary_conductance;
  return s;
}
}  // namespace

StepMatrices step_matrices(const ModalForm& f, double dt) {
  if (f.general) return general_step_matrices(f, dt);
  const Eigen::Index n = f.lambda.size();
  Eigen::VectorXd e(n), g(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double l = f.lambda[i];
    e[i] = std::exp(-l * dt);
    // (1 - exp(-l dt)) / l, accurate also for l -> 0 (an isolated network keeps integrating heat).
    g[i] = std::abs(l * dt) < 1e-12 ? dt : -std::expm1(-l * dt) / l;
  }
  const Eigen::VectorXd inv = f.c_sqrt.cwiseInverse();
  const Eigen::MatrixXd left = inv.asDiagonal() * f.V;  // C^-1/2 V
  StepMatrices s;
  s.Phi = left * e.asDiagonal() * (f.V.transpose() * f.c_sqrt.asDiagonal());
  s.Gamma = left * g.asDiagonal() * left.transpose();
  s.drive = s.Gamma * f.m.heat_w;
  s.ambient_gain = s.Gamma * f.m.ambient_conductance;
  s.boundary_gain = s.Gamma * f.m.boundary_conductance;
  return s;
}

Simulator::Simulator(const Network& net, const Eigen::VectorXd& params) : net_(net), params_(params) {
  if (params.size() != net.param_count())
    throw std::invalid_argument("Simulator: " + std::to_string(params.size()) + " parameter values for " +
                                std::to_string(net.param_count()) + " parameters");
  if (!params.allFinite()) throw std::invalid_argument("Simulator: a parameter value is not finite");
  x_ = Eigen::VectorXd::Zero(net.node_count());
}

void Simulator::reset(const Eigen::VectorXd& x) {
  if (x.size() != net_.node_count()) throw std::invalid_argument("Simulator::reset: wrong state size");
  x_ = x;
}

const StepMatrices& Simulator::matrices(double speed, double dt, unsigned events) {
  const Key key{speed, events, dt};
  auto it = steps_.find(key);
  if (it != steps_.end()) return it->second;
  const auto mkey = std::make_pair(speed, events);
  auto mit = modal_.find(mkey);
  if (mit == modal_.end()) mit = modal_.emplace(mkey, modal_form(assemble(net_, params_, speed, events))).first;
  if (steps_.size() > 4096) steps_.clear();  // jittery time stamps: do not grow without bound
  return steps_.emplace(key, step_matrices(mit->second, dt)).first->second;
}

void Simulator::step(double dt, double speed, double ambient, const Eigen::VectorXd* extra, const Eigen::VectorXd* boundary,
                     unsigned events) {
  if (!(dt > 0) || !std::isfinite(dt)) throw std::invalid_argument("Simulator::step: dt must be > 0");
  const StepMatrices& s = matrices(speed, dt, events);
  Eigen::VectorXd next = s.Phi * x_ + s.drive + s.ambient_gain * ambient;
  if (!net_.boundaries.empty()) {
    if (!boundary || boundary->size() != static_cast<Eigen::Index>(net_.boundaries.size()))
      throw std::invalid_argument("Simulator::step: the network has " + std::to_string(net_.boundaries.size()) +
                                  " boundary column(s); give one temperature each");
    next.noalias() += s.boundary_gain * *boundary;
  }
  if (extra) {
    if (extra->size() != x_.size()) throw std::invalid_argument("Simulator::step: extra heat has wrong size");
    next.noalias() += s.Gamma * *extra;
  }
  x_ = next;
}

Eigen::MatrixXd simulate_recording(const Network& net, const Eigen::VectorXd& params, const Recording& rec,
                                   const Eigen::VectorXd& x0, const Eigen::MatrixXd* extra) {
  const auto rows = static_cast<Eigen::Index>(rec.rows());
  if (extra && (extra->rows() != rows || extra->cols() != net.node_count()))
    throw std::invalid_argument("simulate_recording: extra heat must be rows x nodes");
  const RecordingInputs in = recording_inputs(net, rec);
  Simulator sim(net, params);
  sim.reset(x0);
  Eigen::MatrixXd out(rows, net.node_count());
  Eigen::VectorXd q, b;
  for (Eigen::Index k = 0; k < rows; ++k) {
    out.row(k) = sim.node_temp_c().transpose();
    if (k + 1 < rows) {
      const auto ku = static_cast<std::size_t>(k);
      if (extra) q = extra->row(k).transpose();
      if (in.boundary_c.cols() > 0) b = in.boundary_c.row(k).transpose();
      sim.step(rec.time_s[ku + 1] - rec.time_s[ku], rec.speed_rpm[ku], rec.ambient_c[ku], extra ? &q : nullptr,
               in.boundary_c.cols() > 0 ? &b : nullptr, in.event_mask.empty() ? 0u : in.event_mask[ku]);
    }
  }
  return out;
}

RecordingInputs recording_inputs(const Network& net, const Recording& rec) {
  RecordingInputs in;
  if (!net.has_inputs()) return in;
  auto column = [&](const std::string& name, const char* what) {
    const int c = rec.channel_index(name);
    if (c < 0)
      throw std::invalid_argument(rec.source + ": the network's " + what + " column '" + name + "' is not in the recording");
    return c;
  };
  const auto rows = static_cast<Eigen::Index>(rec.rows());
  in.boundary_c.resize(rows, static_cast<Eigen::Index>(net.boundaries.size()));
  for (std::size_t j = 0; j < net.boundaries.size(); ++j) {
    const int c = column(net.boundaries[j], "boundary");
    for (Eigen::Index k = 0; k < rows; ++k) {
      const double v = rec.temp_c(k, c);
      if (!std::isfinite(v))
        throw std::invalid_argument(rec.source + ": boundary column '" + net.boundaries[j] + "' has no value at time_s " +
                                    std::to_string(rec.time_s[static_cast<std::size_t>(k)]) + " (row " + std::to_string(k + 1) +
                                    "); a boundary is needed on every row");
      in.boundary_c(k, static_cast<Eigen::Index>(j)) = v;
    }
  }
  if (!net.events.empty()) {
    in.event_mask.assign(rec.rows(), 0u);
    for (std::size_t j = 0; j < net.events.size(); ++j) {
      const int c = column(net.events[j], "event");
      for (Eigen::Index k = 0; k < rows; ++k) {
        const double v = rec.temp_c(k, c);
        if (v == 1.0)
          in.event_mask[static_cast<std::size_t>(k)] |= 1u << j;
        else if (v != 0.0)
          throw std::invalid_argument(rec.source + ": event column '" + net.events[j] + "' must be 0 or 1, found " +
                                      (std::isfinite(v) ? std::to_string(v) : std::string("an empty cell")) + " at time_s " +
                                      std::to_string(rec.time_s[static_cast<std::size_t>(k)]) + " (row " + std::to_string(k + 1) + ")");
      }
    }
  }
  return in;
}

Eigen::VectorXd steady_state_c(const Network& net, const Eigen::VectorXd& params, double speed, double ambient,
                               const Eigen::VectorXd* boundary, unsigned events) {
  const NodeMatrices m = assemble(net, params, speed, events);
  Eigen::FullPivLU<Eigen::MatrixXd> lu(m.G);
  if (!lu.isInvertible()) throw std::runtime_error("steady state undefined: the network has no path to ambient");
  Eigen::VectorXd rhs = m.heat_w + m.ambient_conductance * ambient;
  if (!net.boundaries.empty()) {
    if (!boundary || boundary->size() != m.boundary_conductance.cols())
      throw std::invalid_argument("steady state: the network has boundary columns; give their temperatures");
    rhs += m.boundary_conductance * *boundary;
  }
  return lu.solve(rhs);
}

Eigen::VectorXd poles_per_s(const Network& net, const Eigen::VectorXd& params, double speed) {
  const ModalForm f = modal_form(assemble(net, params, speed));
  Eigen::VectorXd p;
  if (f.general) {
    // real parts of the eigenvalues of A = -C^-1 G
    const Eigen::MatrixXd A = -(f.m.capacitance.cwiseInverse().asDiagonal() * f.m.G);
    p = Eigen::EigenSolver<Eigen::MatrixXd>(A, false).eigenvalues().real();
  } else {
    p = -f.lambda;
  }
  std::sort(p.data(), p.data() + p.size());
  return p;
}

}  // namespace btsm::thermal
