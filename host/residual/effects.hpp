#pragma once
// The effect library of the residual loop: physically meaningful additions to a thermal network,
// each with few parameters, expressed in the ONE network description and simulated by the ONE
// simulator (host/thermal). Every effect keeps the model linear and exactly simulable:
//
//   heat_source_transient@n      heat at node n that jumps after each speed increase and decays:
//                                Q(t) = a * sum_i (dw_i+ / 1000 rpm) exp(-(t - t_i)/tau)
//                                [a W per 1000 rpm of increase, tau s]. A first-order state driven
//                                by speed increases; a symmetric RC network cannot express a
//                                one-way driven state, so it enters the simulator as its known
//                                extra-heat input (exact interval averages of the exponential).
//   temperature_dependent_heat@n heat at node n grows with its temperature rise while running:
//                                Q = k (w/w0)^e (T_n - T_amb), e = the node's friction-law exponent.
//                                Linear in T: a link to ambient of conductance -k (w/w0)^e.
//   sensor_lag@column            the probe of `column` lags its node with time constant tau: an
//                                extra node "probe_<column>" (C = 1 J/K, fixed) tied to the node
//                                by R = tau / C; the column then measures the probe node.
//   ambient_dynamics             the air/structure around the machine is not at the measured
//                                ambient but follows it through a lag: every ambient link is moved
//                                to an extra node "ambient_lag" (C_amb_lag) that is tied to the
//                                measured ambient by g_amb_lag.
//   extra_heat_input@n           unmodelled heat at node n while running: q0 + q1 (w/w0).
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"

#include <Eigen/Core>

#include <map>
#include <string>
#include <vector>

namespace btsm::residual {

enum class EffectKind { HeatSourceTransient, TemperatureDependentHeat, SensorLag, AmbientDynamics, ExtraHeatInput };
const char* effect_name(EffectKind k);
EffectKind parse_effect_kind(const std::string& name);  // throws std::invalid_argument listing the names
std::vector<EffectKind> all_effect_kinds();

struct EffectSpec {
  EffectKind kind = EffectKind::ExtraHeatInput;
  int node = -1;         // heat effects; for sensor_lag the node of the column
  std::string column;    // sensor_lag only
};
// "extra_heat_input@housing", "sensor_lag@T1", "ambient_dynamics"
std::string effect_label(const EffectSpec& e, const thermal::Network& net);
// The nodes an effect acts on (names), for reports.
std::vector<std::string> effect_nodes(const EffectSpec& e, const thermal::Network& net);

// Transient-heat parameters (not network parameters: the heat enters as a known input).
struct TransientHeat {
  double amplitude_w_per_krpm = 0;  // W per 1000 rpm of speed increase
  double tau_s = 600;               // s
};

// Base network plus one effect.
struct AugmentedModel {
  thermal::Network net;
  Eigen::VectorXd params;                  // base values + effect values (starts or truth)
  std::vector<std::string> effect_params;  // names of the effect's network parameters
  std::string key_param;                   // the parameter whose significance shows the effect exists
  bool transient = false;                  // heat_source_transient: use transient_heat_w()
  TransientHeat transient_values;
};

// Builds base + effect. `values` overrides effect parameter values by name (e.g. to make a "truth"
// for tests, or start values); the defaults are neutral-ish starts for fitting.
// Throws std::invalid_argument if the node/column does not exist or the effect is already present.
AugmentedModel augment(const thermal::Network& base, const Eigen::VectorXd& base_params, const EffectSpec& e,
                       const std::map<std::string, double>& values = {});

// Extra heat (rows x nodes, W) of heat_source_transient at `node` for one recording: the interval
// average over [t_k, t_k+1) of the decaying heat, for the speed history of `rec`.
Eigen::MatrixXd transient_heat_w(const thermal::Network& net, const thermal::Recording& rec, int node,
                                 const TransientHeat& h);

}  // namespace btsm::residual
