#pragma once
// Model-order reduction of a fitted network to the module's model: one first-order model per
// diagnosed channel, speed-scheduled, with time-scheduled poles in the first minutes of a stop
// (common/model_blob.hpp defines it).
//
// Analysis at each speed (reported, and the reference toolchain's numbers in the tests):
// A = -C^-1 G, B = C^-1 E (inputs = heat sources, W), outputs = all node rises. Gramians in the
// modal basis of the symmetric form (exact for any N), Hankel singular values = sqrt(eig(P Q)),
// square-root balancing, then the shared 1st-order model by plain balanced truncation (BT) and by
// singular perturbation (DC-matched, MATLAB balred's MatchDC). SCTC time constants C_j / G_jj are
// reported for reference: only the sum of their rates is exact (= -trace(A) = -sum of poles).
//
// The module's model, per channel j measuring node n (why per channel: one state shared by all
// channels follows the slow housing mode, so the bearings' faster response was off by up to 6 K
// and the outputs jumped at speed changes):
//   running at speed s  the first-order step response closest to the full network's response of
//                       node n to the spindle's heat at s (max norm over 5 slowest time constants,
//                       from ambient), with its steady rise matched exactly (DC-matched);
//   stopped             the full network's free response of node n from the stop state (steady
//                       state at the cooling reference speed): the early phases' poles reproduce it
//                       exactly at the phase ends, the last one is the closest (max norm) after.
// The ambient enters every channel through its own pole (a drifting ambient arrives with the
// channel's lag, as in the network, instead of at once).
#include "model_reference.hpp"
#include "network.hpp"

#include "common/model_blob.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <array>
#include <functional>
#include <string>
#include <vector>

namespace btsm::thermal {

struct FirstOrder {
  double pole = 0;            // 1/s
  Eigen::RowVectorXd b;       // per input
  Eigen::VectorXd c;          // per node
  Eigen::MatrixXd d;          // nodes x inputs (0 for plain truncation)
};

struct SpeedReduction {
  double speed_rpm = 0;
  Eigen::VectorXd hsv;                 // Hankel singular values (K/W), descending
  Eigen::VectorXd poles;               // full model, 1/s ascending
  FirstOrder bt, dc;                   // shared state: balanced truncation / DC-matched
  Eigen::VectorXd sctc_s;              // C_j / G_jj
  double sctc_rate_sum = 0;            // sum 1/tau_j (1/s) = -trace(A)
  Eigen::VectorXd source_w;            // heat inputs at this speed (W)
  Eigen::VectorXd steady_rise_K;       // full model
  Eigen::VectorXd bt_steady_rise_K;    // plain truncation (shows its DC error)
};

// Reduction at one operating speed (inputs = the network's sources); assembles the network once.
SpeedReduction reduce_at_speed(const Network& net, const Eigen::VectorXd& params, double speed_rpm);
// Reduction with arbitrary inputs (node x input matrix, W): used for the cooling mode where the
// "input" is the stop state (impulse). Exposed for tests.
SpeedReduction reduce_with_inputs(const Network& net, const Eigen::VectorXd& params, double speed_rpm,
                                  const Eigen::MatrixXd& input_to_node);

struct ReduceOptions {
  std::vector<double> speeds_rpm;                 // rpm, operating breakpoints (ascending, > 0)
  double dt_s = 5.0;                              // s, the module's sample period
  std::array<int, 5> channel_node{{0, 1, 2, -1, -1}};  // node per module channel (-1 = none)
  int ambient_channel = 3;                        // 0-based; -1 = none
  // Channel map into the blob: the module role of each channel's node (model_blob.hpp codes);
  // -1 = derive from the node's name (a role name, else kModelRoleUnchecked).
  std::array<int, 5> channel_role{{-1, -1, -1, -1, -1}};
  double cooling_reference_rpm = 0;               // rpm, stop state of the stop fit (0 = the middle breakpoint)
  std::array<double, kModelEarlyStopPhases> stop_phase_end_s{{600.0, 2400.0}};  // s, 0 = phase unused
  ChannelDetector detector;                       // every diagnosed channel (calibrate_detector() refines)
  double test_ambient_c = 25.0;                   // degC, deviation test profile
  double duty_max_rpm = 0;                        // rpm, highest speed of the duty cycle (0 = the highest breakpoint)
  double design_heat_w = 10.0;                    // W, the extra heat the detector is designed to catch soonest
  bool carriers = true;                           // let a channel ride on a slower channel's model where that
                                                  // lowers its duty-cycle error by >= 10 % (reduce_carrier.cpp)
  // Told where a long reduction is ("carriers: channel pair 3 of 12", "checking the module model
  // over the deviation profile: 40 %") at most every ~5 s; a small dt_s makes these minutes long.
  // Nothing for a reduction that ends sooner.
  std::function<void(const std::string&)> progress;
};

// A channel's first-order model in physical terms (what `reduce` prints and the JSON holds).
struct ChannelReduction {
  int node = -1;                                  // network node, -1 = none
  std::vector<double> tau_s;                      // s, per breakpoint (0 = stopped, late phase)
  std::vector<double> steady_rise_K;              // K, per breakpoint (0 when stopped)
  std::array<double, kModelEarlyStopPhases> stop_tau_s{};  // s, early stop phases
  int carrier = -1;                               // channel (0-based) this one rides on, -1 = none
  double coupling_share = 0;                      // 1, c_j / (1 - a_j) at the middle breakpoint of the plain model
  double plain_duty_K = 0;                        // K, worst duty-cycle deviation without / with the carrier
  double carried_duty_K = 0;
};

struct DeviationSummary {
  double quantized_vs_full_max_K = 0;     // module fixed point vs full network, worst channel
  double double_vs_full_max_K = 0;        // reduced double vs full network
  double quantized_vs_double_max_K = 0;   // quantisation alone
  std::array<double, 5> quantized_vs_full_K{};  // per channel (0 where none)
  std::array<double, 5> double_vs_full_K{};
  std::array<std::vector<double>, 5> residual_K;  // per step: full network - module model (as measured - predicted)
  double profile_hours = 0;
  std::string profile;                    // description
};

// The module model against the network over a generic duty cycle -- from cold, at each breakpoint
// speed and midpoint up to duty_max_rpm (and that speed): 2 h, then stops of 15, 30 and 60 min each
// followed by 1 h running again; steps down and up through those speeds (1 h each); restarts after
// a 30-minute stop at another speed (lowest <-> top); an 8 h stop followed by the top and the
// lowest speed; the ambient drifting by +-1 K (period 8 h) -- the transients the module meets in
// production that identification recordings may lack. The detector calibration covers them.
struct DutyCycle {
  std::string profile;                            // description
  double hours = 0;
  std::array<std::vector<double>, 5> residual_K;  // per step: network - module model
  std::array<double, 5> max_abs_K{};              // per channel
};

// Per channel, the network's response of its node to design_heat_w more at that node (at the
// middle breakpoint speed, from its steady state): the residual such a fault leaves, per step, 2 h.
struct FaultSignature {
  double heat_w = 0;
  double speed_rpm = 0;
  std::array<std::vector<double>, 5> rise_K;
};

struct ScheduledReduction {
  std::vector<SpeedReduction> speeds;     // one per operating breakpoint
  SpeedReduction cooling;                 // cooling mode, stop state as input
  std::array<ChannelReduction, 5> channels;
  ReducedModelF64 model;                  // double model
  ReducedModel quantized;                 // fixed point
  ModelCheck quantize_status{};
  std::vector<uint8_t> blob;              // kReducedModelBlobSize bytes (empty if quantisation failed)
  DeviationSummary deviation;
  DutyCycle duty;
  FaultSignature design_fault;
};

// The duty cycle's segments (speed rpm, seconds) and its top speed (DutyCycle's profile).
std::vector<std::pair<double, double>> duty_segments(const ReduceOptions& o, double& top_rpm);
// Gives channels a carrier where the rule of reduce_carrier.cpp finds one (fm: the plain model,
// its running and stop poles already fitted); records the choice in `channels`.
void fit_carriers(const Network& net, const Eigen::VectorXd& params, const ReduceOptions& o, ReducedModelF64& fm,
                  std::array<ChannelReduction, 5>& channels);

ScheduledReduction build_scheduled_model(const Network& net, const Eigen::VectorXd& params, const ReduceOptions& opts);
// Re-quantizes r.model (e.g. after its detector changed) into r.quantized and r.blob.
void requantize(ScheduledReduction& r);
nlohmann::json reduction_to_json(const Network& net, const ScheduledReduction& r, const ReduceOptions& opts);

}  // namespace btsm::thermal
