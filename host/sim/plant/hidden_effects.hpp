#pragma once
// Hidden effects of the simulated spindle: physics the paper's 4-node network lacks, never
// announced to the host. They are the TRUTH side of the undeclared-effect suite; the model side
// (host/residual) must find them from the recordings alone.
//
// One "--effect" spec per effect (several combine). Nodes are the network's node names
// (spindle4: rear_bearing, housing, front_bearing, shaft); several nodes are joined with '+'.
// Durations take units s (default), m/min, h. w0 = the network's reference speed (5000 rpm).
//
//   bearing-tc:K                 rear-bearing friction heat x (1 + K theta1); K in 1/K
//                                (= temp-heat:K@rear_bearing; kept for the demo)
//   run-in:W/TAU                 = transient:W/TAU@rear_bearing+front_bearing (kept for the demo)
//   transient:W/TAU@NODES        run-in transient, additive: every speed increase (a start from
//                                standstill included) adds W watts per 1000 rpm of increase at each
//                                node, decaying with TAU; heat only while the spindle turns
//   transient-gain:A/TAU@NODES   run-in transient, multiplicative: the friction source at each node
//                                (a node with a heat source) is x (1 + A e^-(t - t_c)/TAU) after the
//                                last start or speed change t_c; A is a fraction (0.3 or 30%)
//   transient-start:W/TAU@NODES  run-in after each start from standstill only, additive: W watts at
//                                each node x e^-(t - t_s)/TAU after the last start t_s (W per start,
//                                not per 1000 rpm; a speed change while turning does not restart it)
//   transient-gain-start:A/TAU@NODES  the same as transient-gain, restarted by starts only
//   temp-heat:K@NODES            temperature-dependent friction: the source at each node
//                                x (1 + K theta_node), theta = node - ambient, K in 1/K (negative =
//                                heat falls as the lubricant thins); the factor never goes below 0
//   coupled-heat:G@NODE/HOT-COLD[^E]  heat at NODE driven by the difference of two nodes while
//                                running: G (w/w0)^E (T_HOT - T_COLD), G in W/K, E default 1
//                                (thermally induced preload: friction torque ~ preload ~ the
//                                shaft-housing difference, heat = torque x speed)
//   speed-heat:W@NODE[^E]        extra speed-driven heat at any node while running: W (w/w0)^E,
//                                W in watts at w0, E default 1 (windage, seals, motor losses)
//   sensor-lag:TAU@chN           the probe on channel N (1, 2, 3 or 5) follows its point through a
//                                first-order lag TAU (thermowell, adhesive pad)
//   sensor-drift:RATE@chN        the probe on channel N reads RATE K/h x t too high (offset drift,
//                                t = simulated time since power-on; RATE may be negative)
//   ambient-lag:TAU              boundary dynamics: the air around the machine follows the measured
//                                ambient (channel 4) through a first-order lag TAU
//   coolant:G@NODE=PROFILE       a second boundary: coolant at PROFILE degC (ambient syntax,
//                                "18,30m@19,30m@18") exchanges G W/K with NODE; recorded as the
//                                declared column "coolant_c" (G may be 0: a column with no effect)
//   event:G@NODES=START-END,...  event-switched conductance: while an event is on (cover/door
//                                open) each node gets G W/K more to ambient; recorded as the
//                                declared 0/1 column "lid_open" (G may be 0)
//   latent:C/G@NODE[/GA]         a missing thermal mass: an extra node of C J/K tied to NODE by
//                                G W/K (and to ambient by GA W/K, default 0), never measured
// Errors throw std::invalid_argument naming the spec and the part that is wrong. Node names are
// checked against the network when the plant is built.
#include "host/sim/plant/profile.hpp"

#include <string>
#include <utility>
#include <vector>

namespace btsm::sim {

struct HeatTransient {
  std::vector<std::string> nodes;
  bool multiplicative = false;  // false: additive heat; true: scales the node's friction source
  double amplitude = 0.0;       // additive: W per 1000 rpm of increase (W per start with starts_only); multiplicative: 1 (fraction)
  bool starts_only = false;     // restarted by starts from standstill only, not by speed changes
  double tau_s = 1800.0;        // s, decay time constant
};

struct TemperatureHeat {
  std::vector<std::string> nodes;
  double coeff_per_k = 0.0;     // 1/K
};

struct CoupledHeat {
  std::string node, hot, cold;
  double w_per_k = 0.0;         // W/K at w0
  double speed_exponent = 1.0;  // 1
};

struct SpeedHeat {
  std::string node;
  double w_at_ref = 0.0;        // W at w0
  double speed_exponent = 1.0;  // 1
};

struct SensorLag {
  int channel = 1;              // 1, 2, 3 or 5
  double tau_s = 0.0;           // s
};

struct SensorDrift {
  int channel = 1;              // 1, 2, 3 or 5
  double k_per_h = 0.0;         // K/h
};

struct BoundaryColumn {
  std::string column = "coolant_c";  // declared recording column, degC
  std::string node;
  double w_per_k = 0.0;         // W/K between the coolant and the node (0 = recorded only)
  AmbientProfile temperature{20.0};  // degC over simulated time
};

struct EventConductance {
  std::string column = "lid_open";   // declared recording column, 0/1
  std::vector<std::string> nodes;
  double w_per_k = 0.0;         // W/K added from each node to ambient while on (0 = recorded only)
  std::vector<std::pair<double, double>> on_s;  // s, [start, end) intervals of simulated time
  bool on_at(double t_s) const;
};

struct LatentMass {
  std::string node;
  double c_j_per_k = 0.0;       // J/K
  double g_w_per_k = 0.0;       // W/K to the node
  double g_ambient_w_per_k = 0.0;  // W/K to ambient
};

struct HiddenEffects {
  double bearing_temp_coeff_per_k = 0.0;  // 1/K, bearing-tc: Q1 scaled by (1 + k theta1); 0 = off
  double runin_w_per_krpm = 0.0;          // W per 1000 rpm of speed increase (run-in); 0 = off
  double runin_tau_s = 1800.0;            // s, decay time constant of the run-in heat
  std::vector<HeatTransient> transients;
  std::vector<TemperatureHeat> temperature_heat;
  std::vector<CoupledHeat> coupled_heat;
  std::vector<SpeedHeat> speed_heat;
  std::vector<SensorLag> sensor_lag;
  std::vector<SensorDrift> sensor_drift;
  double ambient_lag_tau_s = 0.0;         // s, 0 = the network sees the measured ambient
  std::vector<BoundaryColumn> boundaries;
  std::vector<EventConductance> events;
  std::vector<LatentMass> latent;
  std::vector<std::string> specs;         // every spec added, canonical, for metadata

  bool any() const;
  // Declared extra columns (never a temperature of a node), in order: boundaries, then events.
  std::vector<std::string> boundary_columns() const;
  std::vector<std::string> event_columns() const;
};

// Adds one "--effect" spec to `fx` (several effects combine).
void parse_effect(const std::string& spec, HiddenEffects& fx);

}  // namespace btsm::sim
