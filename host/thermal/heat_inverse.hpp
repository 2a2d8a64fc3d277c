#pragma once
// Inverse heat-source estimation (after Li et al. 2022, "Thermal error prediction of ball screw feed
// system based on inverse heat transfer analysis"): time-varying heat flows at chosen nodes of a
// thermal network, estimated from measured temperatures with Tikhonov regularisation.
//
// What differs from the paper, and why:
//  * The paper stacks every sample into one dense matrix H (Eq. 30/31) whose size grows as
//    (samples x sources)^2. Here the same least-squares problem
//        min  sum_k |y_k - x_k|^2  +  alpha * |D q|^2
//    (D = identity for order 0, first difference for order 1) is solved as the MAP estimate of a
//    linear Gaussian state-space model (state = node temperatures + current source values, sources
//    follow a white/random-walk prior with variance sigma^2/alpha at each step boundary) with a
//    Kalman filter + Rauch-Tung-Striebel smoother: cost and memory grow LINEARLY with the number
//    of samples. The trace of the influence matrix that GCV needs is exact, from the smoothed
//    covariances (tr S = sum_k tr(H P_k|N H^T) / sigma^2), no stochastic estimator needed.
//  * The paper's T^k / T^(k+1) definitions under Eq. 10 are swapped; we use the standard
//    Crank-Nicolson step (C + dt/2 G) x+ = (C - dt/2 G) x + dt (g_amb T_amb + Q), including the
//    ambient and source terms, or the simulator's exact zero-order-hold step (simulator.hpp).
//  * The paper's Monte-Carlo alpha search ("ICO", Eq. 40-42) drifts to alpha -> 0 when the
//    stopping threshold epsilon is arbitrary; our baseline ties epsilon to the noise level
//    (epsilon = tau * sigma * sqrt(N) / |Z|), which makes it a randomised discrepancy principle.
//  * The paper assumes the system starts at ambient; we estimate the initial state (weak prior
//    centred on the first measured temperatures), so recordings can start warm.
#include "host/thermal/column_map.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"

#include <Eigen/Dense>

#include <functional>
#include <string>
#include <vector>

namespace btsm::thermal {

enum class TikhonovOrder { Zero, One };
enum class AlphaRule { Gcv, LCurve, Discrepancy, MonteCarlo, Fixed };
enum class Discretisation { ExactZoh, CrankNicolson };

TikhonovOrder parse_tikhonov_order(const std::string& s);  // "tikhonov0" | "tikhonov1"
AlphaRule parse_alpha_rule(const std::string& s);          // "gcv" | "lcurve" | "discrepancy" | "montecarlo" | "fixed"
std::string to_string(TikhonovOrder o);
std::string to_string(AlphaRule r);

struct HeatInverseOptions {
  double step_s = 60.0;                            // s, sources are piecewise constant over this
  // A step also begins where the speed (or an event) changes: friction heat jumps there, and a
  // step straddling a stop rings (a 300 s step over a stop gave -5 W after it). Off: fixed steps.
  bool break_at_speed_changes = false;
  TikhonovOrder order = TikhonovOrder::One;
  AlphaRule rule = AlphaRule::Gcv;
  Discretisation scheme = Discretisation::CrankNicolson;
  double alpha_fixed = 1e-4;                       // K^2/W^2, used by AlphaRule::Fixed
  double alpha_min = 1e-10;                        // K^2/W^2, grid lower end
  double alpha_max = 1e3;                          // K^2/W^2, grid upper end
  int alpha_points = 40;                           // log-spaced grid points (GCV, L-curve, discrepancy)
  double noise_sigma_k = 0.0;                      // K, measurement noise; 0 = estimate from the data
  double discrepancy_tau = 1.0;                    // RSS target = tau^2 * N * sigma^2
  double initial_state_sigma_k = 30.0;             // K, prior spread of the unknown initial state
  double first_source_sigma_w = 1000.0;            // W, prior spread of the first source value (order 1)
  // Monte-Carlo alpha search (the paper's ICO baseline)
  int mc_samples_per_round = 8;
  int mc_max_rounds = 60;
  unsigned mc_seed = 20220506u;
  // Told "alpha scan: 12 of 40 points, 31 s" every ~5 s while a scan runs long (a 128-node network
  // takes seconds per point); nothing for a scan that ends sooner.
  std::function<void(const std::string&)> progress;
};

// One point of the alpha scan.
struct AlphaPoint {
  double alpha = 0;          // K^2/W^2
  double rss_k2 = 0;         // sum of squared residuals [K^2]
  double seminorm_w2 = 0;    // |D q|^2 [W^2]
  double dof = 0;            // trace of the influence matrix
  double gcv = 0;            // N * RSS / (N - dof)^2
};

// The estimation problem in discrete, model-independent form.
struct InverseProblem {
  std::vector<double> time_s;            // N sample times, strictly increasing
  Eigen::MatrixXd measured;              // N x n_meas [degC], NaN = missing
  Eigen::MatrixXd measure_map;           // n_meas x n_state (usually selection rows)
  std::vector<double> speed_rpm;         // N, held over [t_k, t_k+1)
  std::vector<double> ambient_c;         // N, held over [t_k, t_k+1)
  std::vector<int> source_nodes;         // state indices receiving the unknown heat
  // Continuous matrices at a given speed (network.hpp assemble(); called once per distinct speed).
  std::function<NodeMatrices(double speed_rpm)> matrices;
  // Declared inputs of the network (network.hpp boundaries/events), empty when it has none: the
  // event state and boundary temperatures per sample, and the matrices per (speed, event state),
  // used instead of `matrices` when set.
  std::vector<unsigned> event_mask;
  Eigen::MatrixXd boundary_c;            // N x boundaries [degC]
  std::function<NodeMatrices(double speed_rpm, unsigned event_mask)> matrices_at;
  bool keep_model_sources = false;       // true: unknown heat is added to the model's own sources
  Eigen::VectorXd initial_state_c;       // prior mean of x_0 [degC] (size n_state)
};

struct HeatInverseResult {
  std::vector<std::string> source_names;   // filled by the caller (node names)
  std::vector<double> piece_start_s;       // P step starts [s]
  Eigen::MatrixXd heat_w;                  // P x m estimated heat per step [W]
  Eigen::MatrixXd heat_sigma_w;            // P x m posterior 1-sigma [W] (at the chosen alpha)
  Eigen::MatrixXd fitted_c;                // N x n_state smoothed node temperatures [degC]
  double alpha = 0;                        // chosen regularisation parameter [K^2/W^2]
  std::string rule;                        // rule that chose it
  double noise_sigma_k = 0;                // noise level used (given or estimated) [K]
  bool noise_estimated = false;
  double rss_k2 = 0, dof = 0;
  double residual_rms_k = 0;               // rms of measured - fitted over all valid samples
  Eigen::VectorXd residual_rms_per_channel_k;
  std::vector<AlphaPoint> scan;            // alpha scan (empty for Fixed)
  int monte_carlo_evaluations = 0;         // number of smoother runs the Monte-Carlo search used
};

// A network with a value for every parameter.
struct ModelWithParameters {
  Network network;
  Eigen::VectorXd params;
  std::string source;   // file or preset it came from
  std::vector<FittedChannel> channel_map;  // a fitted model's "channel_map" (empty for a network or preset)
};
// Loads `path_or_preset`: (1) the fitted-model JSON of `btsm fit` (model_file.hpp: "network" +
// "parameters" {name: value});
// (2) a plain network JSON whose parameters all have values (initial/nominal); (3) a preset name.
// Throws std::invalid_argument naming the file and the parameter without a value.
ModelWithParameters load_model_with_parameters(const std::string& path_or_preset);

// Builds the problem for a network and a recording: the measured channels are the network's
// measurements whose column exists in the recording; `source_nodes` empty = the nodes carrying the
// network's own sources. keep_model_sources = false estimates the TOTAL heat at those nodes (the
// model's source laws are dropped); true estimates the heat the model does not explain.
// Throws std::invalid_argument naming the problem (no measured column, unknown node, ...).
InverseProblem make_inverse_problem(const Network& net, const Eigen::VectorXd& params, const Recording& rec,
                                    std::vector<int> source_nodes, bool keep_model_sources);
// Names of the measured channels make_inverse_problem used, in column order.
std::vector<std::string> measured_columns(const Network& net, const Recording& rec);

// Robust per-problem noise estimate: MAD of second differences of each channel / sqrt(6), pooled
// (median over channels). Steps and kinks in the signal barely move it. A channel's estimate is
// never below its quantisation's rms, q / sqrt(12) (q = its smallest step between samples): on a
// reading quantised coarser than its noise the MAD collapses to round-off.
double estimate_noise_sigma(const Eigen::MatrixXd& measured);

// Solve for a given alpha (no alpha selection). Linear in N.
HeatInverseResult solve_heat_inverse_fixed(const InverseProblem& p, const HeatInverseOptions& o, double alpha);

// Full estimation: alpha chosen by o.rule, then the solution at that alpha.
HeatInverseResult solve_heat_inverse(const InverseProblem& p, const HeatInverseOptions& o);

// Dense reference (the paper's stacked formulation, Eq. 30-39, plus the same weak priors on the
// initial state and first source as the smoother): builds the full sensitivity matrix and solves the
// normal equations. Cost O(N * (n + mP)^2 + (n + mP)^3); only for tests and the benchmark baseline.
HeatInverseResult solve_heat_inverse_dense(const InverseProblem& p, const HeatInverseOptions& o, double alpha);

}  // namespace btsm::thermal
