#pragma once
// The effect library of the residual loop: physically meaningful additions to a thermal network,
// each with few parameters, expressed in the ONE network description and simulated by the ONE
// simulator (host/thermal). Every effect keeps the model linear and exactly simulable:
//
//   heat_source_transient@n      heat at node n that jumps after each speed increase and decays:
//                                Q(t) ~ a * sum_i (dw_i+ / 1000 rpm) exp(-(t - t_i)/tau)
//                                [a W per 1000 rpm of increase, tau s]. Realised as a first-order
//                                state: a virtual node "transient_<n>" (C = 1000 J/K, fixed) that
//                                receives a known energy impulse E_ref = 1 MJ per 1000 rpm at every
//                                speed increase (the simulator's extra-heat input, over one sample)
//                                and passes heat to n through g_t (operating mode only) and to
//                                ambient through g_ta: a = E_ref g_t / C, tau = C / (g_t + g_ta).
//                                Because E_ref is large, the side effects of the tiny coupling
//                                (g_t ~ 1e-3 W/K) on n are negligible; both g are fitted jointly
//                                with the base model.
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

constexpr double kTransientCapacitance = 1000.0;   // J/K of the virtual transient node
constexpr double kTransientImpulse = 1.0e6;        // J per 1000 rpm of speed increase

// Base network plus one effect.
struct AugmentedModel {
  thermal::Network net;
  Eigen::VectorXd params;                  // base values + effect values (starts or truth)
  std::vector<std::string> effect_params;  // names of the effect's network parameters
  std::string key_param;                   // the parameter whose significance shows the effect exists
  int transient_node = -1;                 // heat_source_transient: index of the virtual node fed by
                                           // transient_impulses_w(); -1 for the other effects
};

// Converts a transient amplitude [W per 1000 rpm] and time constant [s] to the two conductances
// (g_t, g_ta) of the virtual node, and back (with 1-sigma from their covariance).
std::pair<double, double> transient_conductances(double amplitude_w_per_krpm, double tau_s);
struct TransientValues {
  double amplitude_w_per_krpm = 0, amplitude_sigma = 0, tau_s = 0, tau_sigma = 0;
};
TransientValues transient_values(double g_t, double g_ta, double var_gt, double var_gta, double cov);

// Builds base + effect. `values` overrides effect parameter values by name (e.g. to make a "truth"
// for tests, or start values); the defaults are neutral-ish starts for fitting. For
// heat_source_transient the keys "a_transient_<node>" [W per 1000 rpm] and "tau_transient_<node>" [s]
// are accepted too and converted to the conductances.
// Throws std::invalid_argument if the node/column does not exist or the effect is already present.
AugmentedModel augment(const thermal::Network& base, const Eigen::VectorXd& base_params, const EffectSpec& e,
                       const std::map<std::string, double>& values = {});

// Known extra heat (rows x nodes, W) that drives the virtual transient node `node`: E_ref per 1000
// rpm of each speed increase, delivered over the sample interval in which the speed rises (a
// recording is taken to start from standstill).
Eigen::MatrixXd transient_impulses_w(const thermal::Network& net, const thermal::Recording& rec, int node);

}  // namespace btsm::residual
