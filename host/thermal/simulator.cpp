// Exact ZOH simulator in the symmetric modal form (see simulator.hpp for the formulas).
#include "simulator.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

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
  const Eigen::VectorXd inv = f.c_sqrt.cwiseInverse();
  const Eigen::MatrixXd S = inv.asDiagonal() * m.G * inv.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(S);
  if (es.info() != Eigen::Success) throw std::runtime_error("thermal network: eigen decomposition failed");
  f.lambda = es.eigenvalues();
  f.V = es.eigenvectors();
  return f;
}

StepMatrices step_matrices(const ModalForm& f, double dt) {
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

const StepMatrices& Simulator::matrices(double speed, double dt) {
  const auto key = std::make_pair(speed, dt);
  auto it = steps_.find(key);
  if (it != steps_.end()) return it->second;
  auto mit = modal_.find(speed);
  if (mit == modal_.end()) mit = modal_.emplace(speed, modal_form(assemble(net_, params_, speed))).first;
  if (steps_.size() > 4096) steps_.clear();  // jittery time stamps: do not grow without bound
  return steps_.emplace(key, step_matrices(mit->second, dt)).first->second;
}

void Simulator::step(double dt, double speed, double ambient, const Eigen::VectorXd* extra) {
  if (!(dt > 0) || !std::isfinite(dt)) throw std::invalid_argument("Simulator::step: dt must be > 0");
  const StepMatrices& s = matrices(speed, dt);
  Eigen::VectorXd next = s.Phi * x_ + s.drive + s.ambient_gain * ambient;
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
  Simulator sim(net, params);
  sim.reset(x0);
  Eigen::MatrixXd out(rows, net.node_count());
  for (Eigen::Index k = 0; k < rows; ++k) {
    out.row(k) = sim.node_temp_c().transpose();
    if (k + 1 < rows) {
      const auto ku = static_cast<std::size_t>(k);
      Eigen::VectorXd q;
      if (extra) q = extra->row(k).transpose();
      sim.step(rec.time_s[ku + 1] - rec.time_s[ku], rec.speed_rpm[ku], rec.ambient_c[ku], extra ? &q : nullptr);
    }
  }
  return out;
}

Eigen::VectorXd steady_state_c(const Network& net, const Eigen::VectorXd& params, double speed, double ambient) {
  const NodeMatrices m = assemble(net, params, speed);
  Eigen::FullPivLU<Eigen::MatrixXd> lu(m.G);
  if (!lu.isInvertible()) throw std::runtime_error("steady state undefined: the network has no path to ambient");
  return lu.solve(m.heat_w + m.ambient_conductance * ambient);
}

Eigen::VectorXd poles_per_s(const Network& net, const Eigen::VectorXd& params, double speed) {
  const ModalForm f = modal_form(assemble(net, params, speed));
  Eigen::VectorXd p = -f.lambda;
  std::sort(p.data(), p.data() + p.size());
  return p;
}

}  // namespace btsm::thermal
