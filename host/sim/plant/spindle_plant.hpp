#pragma once
// The simulated spindle: the paper's 4-node thermal network (preset "spindle4" with the Table 2/3
// values, through the ONE shared simulator btsm::thermal::Simulator), driven by a speed profile and
// an ambient profile, with injectable faults and optional hidden effects (faults.hpp).
//
// Probe placement (five PT1000 channels of the module):
//   ch1 rear bearing  = network node measured as "T1" (node 1)
//   ch2 housing       = node 2 ("T2")
//   ch3 front bearing = node 3 ("T3")
//   ch4 ambient       = the ambient temperature
//   ch5 spare         = a probe on the housing SURFACE (default): ambient + ch5_surface_fraction x
//                       (housing - ambient). The surface runs cooler than the housing midpoint, and
//                       a probe there is what a technician would add as a fifth sensor. The
//                       fraction is a plant parameter, not part of the paper's model.
//                       Ch5Mode::ShaftEnd puts it on the shaft instead: a spring-loaded probe on
//                       the stationary rear end of the shaft assembly (rotary-union housing),
//                       idealised as reading the shaft node ("T4" of the network). That is the
//                       placement the closed-loop demo uses, because without it the shaft node is
//                       not observable enough to identify the paper's network.
//                       Ch5Mode::Disabled instead leaves AIN5 open (the firmware must then report
//                       SENSOR_FAULT on ch5, or have the channel disabled in its configuration).
//
// Time advances in fixed ZOH steps of `step_s` (inputs held constant within a step; segment
// boundaries are honoured at step resolution). Not thread-safe: the runner serialises access.
#include "common/channels.hpp"
#include "host/sim/plant/effect_dynamics.hpp"
#include "host/sim/plant/faults.hpp"
#include "host/sim/plant/profile.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/simulator.hpp"

#include <Eigen/Core>

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace btsm::sim {

enum class Ch5Mode { HousingSurface, ShaftEnd, Disabled };

struct PlantOptions {
  std::string network = "spindle4";   // preset name, or path of a network JSON file
  double step_s = 0.25;               // s, ZOH step of the thermal simulation
  SpeedProfile speed = SpeedProfile::parse("1h@0");
  AmbientProfile ambient{20.0};       // degC
  std::vector<FaultSpec> faults;
  HiddenEffects effects;
  Ch5Mode ch5 = Ch5Mode::HousingSurface;
  double ch5_surface_fraction = 0.5;  // 1, share of the housing rise seen on the surface
  // Which place probes 1..3 are mounted at (0 rear bearing, 1 housing, 2 front bearing): {0, 1, 2}
  // as labelled; e.g. {2, 1, 0} puts the probe of channel 1 on the front bearing and channel 3's
  // on the rear one (probes swapped on the machine). Faults and effects keep their places.
  std::array<int, 3> probe_place{{0, 1, 2}};
  // Initial node temperatures: ambient (cold machine) unless steady state at this speed is asked.
  bool start_steady = false;
  double start_steady_rpm = 0.0;      // rpm
};

enum class ProbeCondition { Ok, Open, OpenChain, Shorted, Absent };

class SpindlePlant {
 public:
  explicit SpindlePlant(PlantOptions opts);

  // Advances the simulation to t (>= time_s()) in whole steps; t is rounded down to a step.
  void advance_to(double t_s);
  double time_s() const { return t_s_; }

  double speed_rpm() const;     // in force now
  double ambient_c() const;
  // True temperature at the probe of channel ch (1..5), degC.
  double probe_temp_c(int ch) const;
  ProbeCondition probe_condition(int ch) const;
  bool adc_missing() const;
  bool reference_lost() const;
  // Heat added to each node in the current step beyond the paper's model (faults + effects), W.
  const Eigen::VectorXd& extra_heat_w() const { return extra_w_; }
  // The air temperature the network exchanges heat with (differs from ambient_c() only with the
  // hidden effect ambient-lag), degC.
  double network_ambient_c() const { return effects_->network_ambient_c(); }
  // Declared extra columns of the hidden effects (coolant_c degC, lid_open 0/1) and their values now.
  std::vector<std::string> declared_columns() const { return effects_->declared_columns(); }
  std::vector<double> declared_values() const { return effects_->declared_values(t_s_); }
  const Eigen::VectorXd& node_temp_c() const { return sim_->node_temp_c(); }
  const thermal::Network& network() const { return sim_->network(); }

  // Run-time control (the demo and the CLI use these through SimModule).
  void replace_speed_from_now(const std::vector<SpeedSegment>& segs);
  void queue_speed(const SpeedSegment& seg);
  void add_fault(const FaultSpec& f) { opts_.faults.push_back(f); }
  // Replaces the hidden effects from now on (their states start settled at the present state).
  void set_effects(const HiddenEffects& fx);
  const SpeedProfile& speed_profile() const { return opts_.speed; }
  const PlantOptions& options() const { return opts_; }

 private:
  int node_of_channel(int ch) const;  // network node index for ch1..ch3
  double point_temp_c(int ch) const;  // true temperature at the point a probe sits on, degC
  std::unique_ptr<EffectDynamics> make_effects(double rpm0) const;
  void compute_extra_heat(double speed_rpm);
  double source_heat_at_node(int node, double speed_rpm);

  PlantOptions opts_;
  std::unique_ptr<thermal::Simulator> sim_;
  Eigen::VectorXd params_;
  Eigen::VectorXd extra_w_;
  int node_[4] = {0, 1, 2, 3};  // rear bearing, housing, front bearing, shaft
  double t_s_ = 0.0;
  std::unique_ptr<EffectDynamics> effects_;
  double cached_heat_rpm_ = -1.0;
  Eigen::VectorXd cached_heat_w_;
};

}  // namespace btsm::sim
