#pragma once
// Exact simulation of a thermal network for piecewise-constant inputs (zero-order hold).
//
// With S = C^-1/2 G C^-1/2 = V diag(lambda) V^T (symmetric, lambda >= 0):
//   Phi(dt)   = C^-1/2 V diag(exp(-lambda dt)) V^T C^1/2
//   Gamma(dt) = C^-1/2 V diag((1 - exp(-lambda dt)) / lambda) V^T C^-1/2     (W -> K)
//   T(t+dt)   = Phi T(t) + Gamma (heat_w + g_amb T_amb + extra)
// The modal form is computed once per distinct speed and the step matrices once per (speed, dt).
#include "network.hpp"
#include "recording.hpp"

#include <Eigen/Core>

#include <map>
#include <utility>

namespace btsm::thermal {

// Symmetric modal form of one speed's model.
struct ModalForm {
  NodeMatrices m;
  Eigen::VectorXd lambda;   // 1/s, eigenvalues of S (= -poles)
  Eigen::MatrixXd V;        // orthonormal eigenvectors of S
  Eigen::VectorXd c_sqrt;   // sqrt(C)
};
ModalForm modal_form(const NodeMatrices& m);

// One ZOH step at a given speed and dt.
struct StepMatrices {
  Eigen::MatrixXd Phi;            // state transition
  Eigen::MatrixXd Gamma;          // W per node -> K
  Eigen::VectorXd drive;          // Gamma * heat_w (K)
  Eigen::VectorXd ambient_gain;   // Gamma * g_amb (K per degC of ambient)
};
StepMatrices step_matrices(const ModalForm& f, double dt_s);

class Simulator {
 public:
  Simulator(const Network& net, const Eigen::VectorXd& params);
  void reset(const Eigen::VectorXd& node_temp_c);
  // Advance dt with speed, ambient and an optional extra heat per node (W) held constant.
  void step(double dt_s, double speed_rpm, double ambient_c, const Eigen::VectorXd* extra_heat_w = nullptr);
  const Eigen::VectorXd& node_temp_c() const { return x_; }
  const Network& network() const { return net_; }
  const Eigen::VectorXd& parameters() const { return params_; }
  // Cached step matrices (computed on first use).
  const StepMatrices& matrices(double speed_rpm, double dt_s);

 private:
  Network net_;
  Eigen::VectorXd params_;
  Eigen::VectorXd x_;
  std::map<double, ModalForm> modal_;                      // by speed
  std::map<std::pair<double, double>, StepMatrices> steps_; // by (speed, dt)
};

// Node temperatures (rows x nodes, degC) at every row time of `rec`, starting from x0 at row 0.
// `extra_heat_w` (rows x nodes, optional) is held over each row's interval.
Eigen::MatrixXd simulate_recording(const Network& net, const Eigen::VectorXd& params, const Recording& rec,
                                   const Eigen::VectorXd& x0_c, const Eigen::MatrixXd* extra_heat_w = nullptr);
// Steady state (degC) at a constant speed and ambient; throws if G is singular (no path to ambient).
Eigen::VectorXd steady_state_c(const Network& net, const Eigen::VectorXd& params, double speed_rpm, double ambient_c);
// Continuous-time poles (1/s, ascending = most negative first).
Eigen::VectorXd poles_per_s(const Network& net, const Eigen::VectorXd& params, double speed_rpm);

}  // namespace btsm::thermal
