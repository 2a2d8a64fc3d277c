#pragma once
// Start values for the fit's output-error stages, found without an initial guess: the integral
// equation-error solve (stages 1 and 3), fills for unmeasured nodes, starts from peers for
// parameters the data cannot reach, the neutral start of the operating parameters, and initial
// states from a recording row.
#include "network.hpp"
#include "recording.hpp"
#include "simulator.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <string>
#include <vector>

namespace btsm::thermal::fitting {

// How a parameter enters the heat balances: v = p, v = 1/p (a resistance), or not linearly.
enum class LinearForm { Value, Inverse, None };
std::vector<LinearForm> linear_forms(const Network& net);

struct EquationErrorInput {
  const Recording* rec;
  Eigen::MatrixXd temps;                // rows x nodes (measured or filled), NaN = unknown
  const Eigen::MatrixXd* extra = nullptr;
  const RecordingInputs* inputs = nullptr;  // declared boundary/event columns (simulator.hpp), when the network has them
};

// Equation-error (integral) start for a set of parameters that enter linearly: solves for
// `unknown` (parameter indices) from the integral heat balances
//   C_i (T_i(t) - T_i(t0)) = sum_l g_l int (T_j - T_i) dt + int Q_i dt
// of every segment of `mode`, with sum C = sum_c when finite. Returns the indices that could be
// determined (positive); writes them into p. A parameter that comes out non-positive is started
// at a neutral value (10 % of its peers, no heat for a source) and said so in `warnings`.
std::vector<int> equation_error_start(const Network& net, const std::vector<EquationErrorInput>& data, Mode mode,
                                      std::vector<int> unknown, double sum_c, Eigen::VectorXd& p,
                                      std::vector<std::string>& warnings);

// Fills unmeasured node temperatures quasi-statically from neighbours (weights = the mode's
// internal conductances), rescaled in rise above ambient to the measured values at the ends of each gap.
Eigen::MatrixXd filled_temperatures(const Network& net, const Eigen::VectorXd& p, const Recording& rec,
                                    const std::vector<int>& cols);

// For the equation-error start only: a node no probe measures gets, row by row, the mean of its
// measured neighbours (links to ambient do not count). In natural cooling the nodes of a spindle
// converge on one another, so this is a fair first guess; nothing after stage 1 uses it. Returns
// whether any column was filled.
bool fill_unmeasured_from_neighbours(const Network& net, Eigen::MatrixXd& temps);

// A parameter whose equation-error row needs an unmeasured node (the shaft of a spindle whose
// probes all sit on the housing, say) cannot be started from the data directly. It starts at the
// geometric mean of the started parameters of the same unit (a capacitance: an equal share of what
// the capacitance gauge leaves), and the output-error stages that follow fit it like any other. The
// fit says so in its warnings, because such a parameter's estimate rests on the output error alone.
// The same holds for a parameter the equation-error solve left unsettled (a value in p on entry but
// not in `got`: its passes ended with others still non-positive, as when a drifting probe makes the
// cooling heat balances of one node disagree between recordings); that value is not trusted.
// Where the rule has nothing to share out (the gauge used up, no started peer) the start falls
// back to the geometric mean of the parameters of its unit, then to the network's nominal value;
// only without either does it throw, naming the parameter.
void start_unreached_from_peers(const Network& net, const std::vector<int>& wanted, const std::vector<int>& got,
                                double sum_c, Eigen::VectorXd& p, std::vector<std::string>& warnings);

// A start for the operating-only parameters that uses no derivative of the data: every
// resistance at the geometric mean of the resistances stage 2 fitted (same unit family, K/W), and
// the heat sources sharing what holds the warm-ups' largest final rise above ambient across that
// resistance. Crude, but on the output-error surface it lies in the basin of the physical minimum
// for any spindle-like network (heat and resistance scales within a decade converge alike).
Eigen::VectorXd neutral_operating_start(const Network& net, const std::vector<Recording>& recs,
                                        const std::vector<std::vector<int>>& cols, const std::vector<int>& op_auto,
                                        const Eigen::VectorXd& p);

// Node temperatures at `row` of a recording: measured where a column measures the node, else
// ambient + the mean measured rise.
Eigen::VectorXd state_from_row(const Network& net, const Recording& rec, const std::vector<int>& cols, std::size_t row);

}  // namespace btsm::thermal::fitting
