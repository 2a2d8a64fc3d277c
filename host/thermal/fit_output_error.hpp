#pragma once
// The output-error problem of the fit and its evaluator.
//
// Unknowns u = the free parameters, transformed (log or linear, see Transform), then optionally one
// initial state per run. Residual = simulated - measured temperature for every measured cell of
// every run, plus one stiff residual on log(sum C) when the capacitance gauge is in force. The
// evaluator returns the sum of squares and, on request, J^T J and J^T r, with J from forward
// sensitivity propagation: dx_k/dp recursed with the step matrices, whose parameter derivatives are
// central differences per (speed, dt) key. Runs are independent given the parameters and are
// spread over the cores.
#include "network.hpp"
#include "recording.hpp"
#include "fit_support.hpp"
#include "simulator.hpp"

#include <Eigen/Core>

#include <cmath>
#include <cstddef>
#include <map>
#include <tuple>
#include <utility>
#include <vector>

namespace btsm::thermal::fitting {

// A contiguous row range [begin, end] (inclusive) of a recording used as one experiment.
struct Run {
  const Recording* rec = nullptr;
  std::size_t begin = 0, end = 0;
  std::vector<int> cols;               // recording channel per measurement
  const Eigen::MatrixXd* extra = nullptr;
  const RecordingInputs* inputs = nullptr;  // declared boundary/event columns of the whole recording (or null)
  int recording_index = -1;            // index into the caller's recordings (-1 = sub-range)
};

// How a parameter is fitted: z = log(p) (log_scale) or z = p, within the bounds [zmin, zmax].
struct Transform {
  bool log = true;
  double zmin = 0, zmax = 0;
  double to_p(double z) const { return log ? std::exp(z) : z; }
  double dp_dz(double z) const { return log ? std::exp(z) : 1.0; }
  double to_z(double p) const { return log ? std::log(p) : p; }
};
Transform transform_of(const Parameter& par);

// Which parameters a mode uses (capacitances are used by both).
std::vector<bool> params_used(const Network& net, Mode mode);

// Output-error problem: free parameters (transformed) + optional per-run initial states.
struct OutputErrorProblem {
  const Network* net = nullptr;
  std::vector<Run> runs;
  std::vector<int> free;               // parameter indices
  std::vector<Transform> tf;
  Eigen::VectorXd p;                   // all parameter values
  bool estimate_x0 = true;
  std::vector<bool> x0_held;           // per node: its initial state is not estimated (empty = none held)
  std::vector<Eigen::VectorXd> x0;
  double sum_c = kNaN;                 // J/K, capacitance gauge; NaN = none in this problem
  int n() const { return net->node_count(); }
  int nf() const { return static_cast<int>(free.size()); }
  int unknowns() const { return nf() + (estimate_x0 ? static_cast<int>(runs.size()) * n() : 0); }
};

struct Evaluation {
  double ssr = 0;        // data residuals only
  double cost = 0;       // 0.5 (ssr + gauge^2)
  std::size_t count = 0;
  Eigen::MatrixXd H;     // J^T J
  Eigen::VectorXd g;     // J^T r
};

class OutputErrorEvaluator {
 public:
  explicit OutputErrorEvaluator(OutputErrorProblem& pr);

  // Sets parameters from u and evaluates; with_jacobian fills H and g.
  Evaluation evaluate(const Eigen::VectorXd& u, bool with_jacobian);
  // Writes u into the problem's parameter values and initial states.
  void apply(const Eigen::VectorXd& u);
  // The score of every row of run `ri` at u: g_t = sum over the row's measured cells of
  // residual * d residual / d (free parameters, then the run's initial state when estimated),
  // rows x (nf [+ n]). Its autocorrelation over rows is what the parameter covariance needs when
  // the residuals are not white (fit_uncertainty.hpp).
  Eigen::MatrixXd row_scores(std::size_t ri, const Eigen::VectorXd& u);

  static constexpr double kGaugeWeight = 1e4;

 private:
  struct KeyData {
    StepMatrices base;
    Eigen::MatrixXd dphi_stack;   // (n*nf) x n, block j = dPhi/dz_j
    Eigen::MatrixXd dgamma_stack; // (n*nf) x n, only when extra heat is used
    Eigen::MatrixXd ddrive;       // n x nf
    Eigen::MatrixXd damb;         // n x nf
    std::vector<Eigen::MatrixXd> dbnd;  // per declared boundary: n x nf
  };
  using Key = std::tuple<double, unsigned, double>;  // speed, event state, dt
  static Key key_of(const Run& run, std::size_t k);
  // Simulates run ri with its forward sensitivities; calls sink(row within the run, measurement
  // index, residual, d residual / d params (1 x nf), d residual / d x0 (1 x n)) for every measured
  // cell (the derivatives only meaningful when with_jacobian). A drifting measurement's residual
  // still holds its per-recording offset: the callers eliminate it.
  template <class Sink>
  void simulate_run(std::size_t ri, bool with_jacobian, Sink&& sink) const;
  // simulate_run with the node count known at compile time (N > 0) or not (N = Eigen::Dynamic)
  template <int N, class Sink>
  void simulate_run_n(std::size_t ri, bool with_jacobian, Sink&& sink) const;
  void evaluate_run(std::size_t ri, bool with_jacobian, int local, Evaluation& ev) const;
  // Scale gauge as a stiff residual on log(sum C).
  void gauge(const Eigen::VectorXd& u, bool with_jacobian, Evaluation& ev) const;
  void build_keys(bool with_jacobian);

  OutputErrorProblem& pr_;
  std::vector<bool> used_[2];
  bool uses_extra_ = false;
  // The (speed, event state, dt) keys depend on the recordings only: numbered once, their data
  // rebuilt per evaluation (they depend on the parameters).
  std::vector<Key> key_list_;
  std::vector<std::vector<int>> step_key_;  // per run, per step from its begin: index into key_list_
  std::vector<KeyData> keys_;               // per key_list_ entry
  std::vector<int> drift_free_;   // per measurement: index into free of its drift parameter, -1 = none
};

// The unknowns u of the problem's current parameter values and initial states, and u clamped to
// the parameter bounds.
Eigen::VectorXd pack(const OutputErrorProblem& pr);
void clamp_to_bounds(const OutputErrorProblem& pr, Eigen::VectorXd& u);

}  // namespace btsm::thermal::fitting
