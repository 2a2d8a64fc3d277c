#pragma once
// The effect library of the residual loop: physical additions to a thermal network, each with few
// parameters, expressed in the ONE network description (host/thermal/network.hpp) and simulated by
// the ONE simulator, so an effect is fitted jointly with the base parameters by the ordinary fit.
//
//   heat_source_transient   heat after each start-up or speed change that decays with tau, at one
//                           node or several with one shared decay. A virtual node "transient"
//                           (C = 1 J/K, fixed) receives a known energy impulse at each trigger
//                           (the fit's extra-heat input) and hands heat to each node n through
//                           g_transient_<n> (operating mode only), decaying to ambient through
//                           g_transient_decay: tau = C / (sum g). Triggers: every speed increase
//                           (1 MJ per 1000 rpm of increase, a start counts from 0) or every start or
//                           speed change (1 MJ each). Additive: the coupling is speed independent;
//                           multiplicative: it follows the node's friction law (w/w0)^e, so the
//                           extra heat is a share of that node's friction heat.
//   temperature_dependent_heat  heat at a node that grows (k > 0) or falls (k < 0) with its rise:
//                           k_heat_T_<n> (w/w0)^e (T_n - T_amb) W, e = the node's friction exponent
//                           (a source term driven by [n, ambient]).
//   coupled_heat            heat at node n driven by the difference of two nodes:
//                           k_couple_<n> (w/w0)^e (T_hot - T_cold) W while running (thermally
//                           induced preload: the hotter a bearing runs against its housing, the
//                           more it heats). A source term driven by [hot, cold].
//   extra_heat_input        unmodelled speed-driven heat at any node, with or without a probe:
//                           q_extra_<n> (w/w0)^e W while running, e = 0, 1 or 2.
//   sensor_lag              the probe of a column lags its node: a probe node (C = 1 J/K, fixed)
//                           tied to the node by R = tau; the column measures the probe node.
//   sensor_drift            the probe of a column drifts: d_<column> K/h x hours since the
//                           recording's first sample, plus its offset then, unknown (how long it
//                           drifted before): a nuisance per recording (a drifting measurement,
//                           network.hpp).
//   ambient_dynamics        the air/structure around the machine is not at the measured ambient:
//                           every ambient link moves to a node "ambient_lag" (C_ambient_lag) tied
//                           to the measured ambient by g_ambient_lag.
//   second_boundary         a declared boundary column (coolant, chiller water) exchanges heat with
//                           one node or several: g_<column>_<n> W/K each.
//   event_conductance       while a declared 0/1 event column is 1 (a cover or lid open), one node
//                           or several lose heat to ambient through g_<column>_<n> W/K each.
//   latent_mass             a missing thermal mass: an unmeasured node "latent_<n>" (C_latent_<n>)
//                           tied to node n by g_latent_<n>.
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"

#include <Eigen/Core>

#include <map>
#include <string>
#include <vector>

namespace btsm::residual {

enum class EffectKind {
  HeatSourceTransient,
  TemperatureDependentHeat,
  CoupledHeat,
  ExtraHeatInput,
  SensorLag,
  SensorDrift,
  AmbientDynamics,
  SecondBoundary,
  EventConductance,
  LatentMass,
};
const char* effect_name(EffectKind k);
EffectKind parse_effect_kind(const std::string& name);  // throws std::invalid_argument listing the names
std::vector<EffectKind> all_effect_kinds();

// SpeedIncrease: every increase adds its 1000-rpm units (several pile up); StartOrChange: every
// start or speed change restarts the transient; Start: only a start from standstill restarts it.
enum class TransientTrigger { SpeedIncrease, StartOrChange, Start };
const char* trigger_name(TransientTrigger t);
// The trigger in a variant's words: "every speed increase", "every start or speed change", "every start from standstill".
const char* trigger_phrase(TransientTrigger t);

struct EffectSpec {
  EffectKind kind = EffectKind::ExtraHeatInput;
  std::vector<int> nodes;          // nodes acted on (node indices of the base network)
  std::string column;              // sensor_lag / sensor_drift: the measured column; second_boundary /
                                   // event_conductance: the declared column
  int hot = -1, cold = -1;         // coupled_heat: the driving pair (node indices)
  TransientTrigger trigger = TransientTrigger::SpeedIncrease;  // heat_source_transient
  bool multiplicative = false;     // heat_source_transient: coupling follows the node's friction law
  double speed_exponent = 1.0;     // extra_heat_input, coupled_heat: (w/w0)^e
  double tau_s = 0;                // start of the family's time constant [s]; 0 = the family's default
};

// "heat_source_transient@rear_bearing+front_bearing", "sensor_lag@T1", "coupled_heat@front_bearing",
// "second_boundary@housing", "ambient_dynamics".
std::string effect_label(const EffectSpec& e, const thermal::Network& net);
// Names of the nodes an effect acts on (ambient_dynamics: every node linked to ambient; sensor
// families: the node the column measures).
std::vector<std::string> effect_nodes(const EffectSpec& e, const thermal::Network& net);

// The virtual node's coupling g (T_transient - T_n) also carries -g (T_n - T_ambient) once the
// state has decayed: a leak the plant's run-in heat does not have. It is g T_n against the
// impulse's E/C, so C is small: 1 J/K puts the state 1e9 K above the ambient per trigger unit and
// the leak at 1e-9 of the amplitude per kelvin (at C = 1000 J/K it was 1e-3: a 5.6 W/1000 rpm
// transient then lost 0.1-0.2 W at a 20-30 K bearing rise, and with the plant's own base values
// the family fitted seed 99's recordings to 0.013 K instead of 0.0019 K). The heat the coupling
// carries also drains the state, so its decay was C / (g_decay + g (w/w0)^e), faster at high
// speed: a ~ tau / E of the decay. At E = 1e6 J a 10 W, 37 min run-in drained 2 % and the plant's
// own values fitted its recordings to 5.5 mK where the noise is 5.0 mK; the joint refit then
// bought those 2 mK with base values that missed the check run by 58 mK. E = 1e9 J: 2e-5.
constexpr double kTransientCapacitance = 1.0;      // J/K of the virtual transient node
constexpr double kTransientImpulse = 1.0e9;        // J per trigger unit (1000 rpm of increase, or one start/change)
constexpr double kProbeCapacitance = 1.0;          // J/K of a sensor_lag probe node (R in K/W = tau in s)

// Base network plus one effect.
struct AugmentedModel {
  thermal::Network net;
  Eigen::VectorXd params;                  // base values + effect values (starts, or a truth)
  std::vector<std::string> effect_params;  // the effect's free network parameters
  // those whose significance shows the effect exists; "a/b" names the ratio of two parameters
  // (its sigma from their covariance), for an effect whose existence is a time constant C/g
  std::vector<std::string> key_params;
  int transient_node = -1;                 // heat_source_transient: the virtual node fed by transient_impulses_w()
  std::vector<int> rest_nodes;             // start every recording at the ambient (the transient state: at rest)
  TransientTrigger trigger = TransientTrigger::SpeedIncrease;
  bool adds_free_capacitance = false;      // ambient_dynamics, latent_mass: the caller fixes the gauge otherwise
};

// Builds base + effect. `values` overrides effect parameter values by network name (starts, or a
// truth for tests); heat_source_transient also takes "tau_transient" [s] and
// "a_transient_<node>" (W per trigger unit for an additive coupling, a fraction of the node's
// friction heat at w0 for a multiplicative one). Throws std::invalid_argument if a node or column
// does not exist, the effect is already present, or the family needs what the network lacks.
AugmentedModel augment(const thermal::Network& base, const Eigen::VectorXd& base_params, const EffectSpec& e,
                       const std::map<std::string, double>& values = {});

// Known extra heat (rows x nodes, W) that drives the virtual transient node: kTransientImpulse per
// trigger unit, delivered over the sample interval in which the trigger happens (a recording is
// taken to start from standstill). `params` gives the decay a StartOrChange trigger restarts from.
Eigen::MatrixXd transient_impulses_w(const thermal::Network& net, const Eigen::VectorXd& params, const thermal::Recording& rec,
                                     int node, TransientTrigger trigger);
// The trigger units of one recording per row (what the impulses are made of). SpeedIncrease adds
// one unit per 1000 rpm of every increase (the extra heat of several piles up); StartOrChange and
// Start restart the transient at one unit: with restart_tau_s > 0 a trigger adds only what the decay
// (time constant restart_tau_s) took since the last one, so the extra heat after each start or
// change is a e^(-t/tau) with t since that trigger (0: every trigger one unit, for counting).
std::vector<double> transient_triggers(const thermal::Network& net, const thermal::Recording& rec, TransientTrigger trigger,
                                       double restart_tau_s = 0.0);
// The decay time [s] of the transient state in an augmented network: C / (g_decay + couplings); 0 without one.
double transient_tau_s(const thermal::Network& net, const Eigen::VectorXd& params);

// The friction-law exponent of a node's own heat sources (the largest), 1 when it has none.
double friction_exponent(const thermal::Network& net, int node);
// The node's own source heat at w0 [W] (0 when it has none).
double source_heat_at_w0(const thermal::Network& net, const Eigen::VectorXd& params, int node);

// One physical quantity of a fitted effect, with its sign, in the user's terms.
struct EffectQuantity {
  std::string name;          // e.g. "heat_per_K_rear_bearing"
  std::string unit;          // e.g. "W/K at w0"
  double value = 0, sigma = 0;
  std::string meaning;       // e.g. "+1.2 % of the rear_bearing heat per K (heat grows with temperature)"
};
// The effect's parameters as physical quantities (covariance over the network's parameters).
std::vector<EffectQuantity> effect_quantities(const AugmentedModel& m, const EffectSpec& e, const thermal::Network& base,
                                              const Eigen::VectorXd& values, const Eigen::MatrixXd& covariance);

}  // namespace btsm::residual
