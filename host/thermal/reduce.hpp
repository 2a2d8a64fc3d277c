#pragma once
// Model-order reduction of a fitted network to the firmware's speed-scheduled 1st-order model.
//
// At each speed: A = -C^-1 G, B = C^-1 E (inputs = heat sources, W), outputs = all node rises.
// Gramians are solved in the modal basis of the symmetric form (exact for any N), Hankel singular
// values = sqrt(eig(P Q)), square-root balancing, then a 1st-order model by plain balanced
// truncation (BT) and by singular perturbation (DC-matched, MATLAB balred's MatchDC). Only the
// DC-matched one keeps the steady state; it is the one scheduled into the firmware.
// SCTC time constants C_j / G_jj are reported for reference: only the sum of their rates is exact
// (= -trace(A) = -sum of poles).
#include "network.hpp"

#include "common/reduced_model.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <array>
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
  FirstOrder bt, dc;                   // balanced truncation / DC-matched
  Eigen::VectorXd sctc_s;              // C_j / G_jj
  double sctc_rate_sum = 0;            // sum 1/tau_j (1/s) = -trace(A)
  Eigen::VectorXd source_w;            // heat inputs at this speed (W)
  Eigen::VectorXd steady_rise_K;       // full model
  Eigen::VectorXd bt_steady_rise_K;    // plain truncation (shows its DC error)
};

// Reduction at one operating speed (inputs = the network's sources).
SpeedReduction reduce_at_speed(const Network& net, const Eigen::VectorXd& params, double speed_rpm);
// Reduction of an arbitrary (A, B, C) with A = -C^-1 G symmetric-izable: used for the cooling mode
// where the "input" is the stop state (impulse). Exposed for tests.
SpeedReduction reduce_with_inputs(const Network& net, const Eigen::VectorXd& params, double speed_rpm,
                                  const Eigen::MatrixXd& input_to_node);

struct ReduceOptions {
  std::vector<double> speeds_rpm;                 // operating breakpoints (ascending, > 0)
  double dt_s = 5.0;                              // firmware sample period
  std::array<int, kModelChannels> channel_node{{0, 1, 2, -1, -1}};  // node per firmware channel (-1 = none)
  int ambient_channel = 3;                        // 0-based; -1 = none
  int reference_channel = 0;                      // channel whose c is 1 at every breakpoint
  double cooling_reference_rpm = 0;               // stop state used for the cooling reduction (0 = highest speed)
  double warn_K = 1.0, alarm_K = 2.0;             // residual bands
  double abs_limit_c = 70.0;                      // absolute limit
  double max_rise_K_per_min = 5.0;
  double test_ambient_c = 25.0;                   // deviation test profile
};

struct DeviationSummary {
  double quantized_vs_full_max_K = 0;     // firmware fixed point vs full network, worst channel
  double double_vs_full_max_K = 0;        // reduced double vs full network
  double quantized_vs_double_max_K = 0;   // quantisation alone
  double profile_hours = 0;
  std::string profile;                    // description
};

struct ScheduledReduction {
  std::vector<SpeedReduction> speeds;     // one per operating breakpoint
  SpeedReduction cooling;                 // cooling mode, stop state as input
  ReducedModelF64 model;                  // double scheduled model
  ReducedModel quantized;                 // fixed point
  ModelCheck quantize_status{};
  std::vector<uint8_t> blob;              // kReducedModelBlobSize bytes (empty if quantisation failed)
  DeviationSummary deviation;
};

ScheduledReduction build_scheduled_model(const Network& net, const Eigen::VectorXd& params, const ReduceOptions& opts);
nlohmann::json reduction_to_json(const Network& net, const ScheduledReduction& r, const ReduceOptions& opts);

}  // namespace btsm::thermal
