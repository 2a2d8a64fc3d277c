#pragma once
// Exact simulation of a thermal network for piecewise-constant inputs (zero-order hold).
//
// With S = C^-1/2 G C^-1/2 = V diag(lambda) V^T (symmetric, lambda >= 0):
//   Phi(dt)   = C^-1/2 V diag(exp(-lambda dt)) V^T C^1/2
//   Gamma(dt) = C^-1/2 V diag((1 - exp(-lambda dt)) / lambda) V^T C^-1/2     (W -> K)
//   T(t+dt)   = Phi T(t) + Gamma (heat_w + g_amb T_amb + G_bnd T_bnd + extra)
// The modal form is computed once per distinct (speed, event state) and the step matrices once per
// (speed, event state, dt). Declared boundary and event columns (network.hpp) are read from the
// recording like speed and ambient: held over each sample interval.
#include "network.hpp"
#include "recording.hpp"

#include <Eigen/Core>

#include <map>
#include <tuple>
#include <vector>
#include <utility>

namespace btsm::thermal {

// Symmetric modal form of one speed's model. A network whose G is not symmetric (a source driven
// by a temperature difference that does not involve its own node, network.hpp) has no such form:
// `general` is then set, lambda/V stay empty, and the step matrices come from the matrix
// exponential of A = -C^-1 G (exact as well, a little slower).
struct ModalForm {
  NodeMatrices m;
  Eigen::VectorXd lambda;   // 1/s, eigenvalues of S (= -poles)
  Eigen::MatrixXd V;        // orthonormal eigenvectors of S
  Eigen::VectorXd c_sqrt;   // sqrt(C)
  bool general = false;     // G not symmetric: lambda/V unused
};
ModalForm modal_form(const NodeMatrices& m);

// One ZOH step at a given speed and dt.
struct StepMatrices {
  Eigen::MatrixXd Phi;            // state transition
  Eigen::MatrixXd Gamma;          // W per node -> K
  Eigen::VectorXd drive;          // Gamma * heat_w (K)
  Eigen::VectorXd ambient_gain;   // Gamma * g_amb (K per degC of ambient)
  Eigen::MatrixXd boundary_gain;  // Gamma * G_bnd (K per degC of each boundary), nodes x boundaries
};
StepMatrices step_matrices(const ModalForm& f, double dt_s);

class Simulator {
 public:
  Simulator(const Network& net, const Eigen::VectorXd& params);
  void reset(const Eigen::VectorXd& node_temp_c);
  // Advance dt with speed, ambient and an optional extra heat per node (W) held constant; the
  // boundary temperatures (one per Network::boundaries, degC) are required when the network has
  // boundaries; `event_mask` bit k = Network::events[k] on.
  void step(double dt_s, double speed_rpm, double ambient_c, const Eigen::VectorXd* extra_heat_w = nullptr,
            const Eigen::VectorXd* boundary_c = nullptr, unsigned event_mask = 0);
  const Eigen::VectorXd& node_temp_c() const { return x_; }
  const Network& network() const { return net_; }
  const Eigen::VectorXd& parameters() const { return params_; }
  // Cached step matrices (computed on first use).
  const StepMatrices& matrices(double speed_rpm, double dt_s, unsigned event_mask = 0);

 private:
  using Key = std::tuple<double, unsigned, double>;
  Network net_;
  Eigen::VectorXd params_;
  Eigen::VectorXd x_;
  std::map<std::pair<double, unsigned>, ModalForm> modal_;  // by (speed, events)
  std::map<Key, StepMatrices> steps_;                       // by (speed, events, dt)
};

// The declared inputs of a network read from a recording: the event state and the boundary
// temperatures of every row. Throws std::invalid_argument naming the recording and the column when
// a column is missing, a boundary cell is empty or an event cell is not 0 or 1.
struct RecordingInputs {
  std::vector<unsigned> event_mask;  // per row, bit k = Network::events[k]
  Eigen::MatrixXd boundary_c;        // rows x boundaries, degC
  bool empty() const { return event_mask.empty() && boundary_c.size() == 0; }
};
RecordingInputs recording_inputs(const Network& net, const Recording& rec);

// Node temperatures (rows x nodes, degC) at every row time of `rec`, starting from x0 at row 0.
// `extra_heat_w` (rows x nodes, optional) is held over each row's interval.
Eigen::MatrixXd simulate_recording(const Network& net, const Eigen::VectorXd& params, const Recording& rec,
                                   const Eigen::VectorXd& x0_c, const Eigen::MatrixXd* extra_heat_w = nullptr);
// Steady state (degC) at a constant speed and ambient (and boundary temperatures, required when the
// network has boundaries); throws if G is singular (no path to ambient).
Eigen::VectorXd steady_state_c(const Network& net, const Eigen::VectorXd& params, double speed_rpm, double ambient_c,
                               const Eigen::VectorXd* boundary_c = nullptr, unsigned event_mask = 0);
// Continuous-time poles (1/s, ascending = most negative first).
Eigen::VectorXd poles_per_s(const Network& net, const Eigen::VectorXd& params, double speed_rpm);

}  // namespace btsm::thermal
