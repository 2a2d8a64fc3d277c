#pragma once
// The hidden effects (hidden_effects.hpp) at run time inside one plant: their states (run-in
// transients, the lagging air, latent masses, lagging probes) and what they add in each step.
//
// The plant's network is stepped exactly (ZOH) by the shared simulator; every effect enters it as
// extra heat per node held over one plant step (0.25 s by default). State-dependent effects
// (temperature-dependent and coupled heat, coolant, events, latent masses) are therefore
// evaluated at the start of each step: with the plant's step two to three orders of magnitude
// below the fastest node time constant (the shaft, ~60 s) the splitting error is far below the
// probe noise. The effects' own states (air lag, latent node, probe lag) are advanced exactly
// over the step.
#include "host/sim/plant/hidden_effects.hpp"
#include "host/thermal/network.hpp"

#include "common/channels.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace btsm::sim {

// Where the plant's probes sit, for effects that name channels.
struct ProbeNodes {
  int rear_bearing = 0, housing = 1, front_bearing = 2, shaft = 3;  // node index per channel 1, 2, 3, shaft
};

class EffectDynamics {
 public:
  // Resolves node names against `net` (throws std::invalid_argument naming the effect and the
  // node). `x0_c` = initial node temperatures, `rpm0` = the speed before t = 0 (0 for a cold,
  // stopped machine: a speed at t = 0 then counts as a start).
  EffectDynamics(const HiddenEffects& fx, const thermal::Network& net, const ProbeNodes& probes,
                 const Eigen::VectorXd& x0_c, double ambient0_c, double rpm0);

  // The temperature the network exchanges heat with (the air around the machine), degC.
  double network_ambient_c() const { return air_c_; }
  // Adds the effects' heat for the next step (W per node). `source_w` = the paper's friction
  // sources per node at `rpm`, `x_c` = node temperatures at the start of the step.
  void add_heat(double t_s, double rpm, const Eigen::VectorXd& source_w, const Eigen::VectorXd& x_c,
                Eigen::VectorXd& extra_w);
  // After the network advanced h seconds: advance the effects' own states. `measured_ambient_c`
  // and `point_c` (true temperature at the point of each channel 1..5, index 0..4) are at the end
  // of the step.
  void advance(double h_s, const Eigen::VectorXd& x_c, double measured_ambient_c, const double point_c[kChannels]);
  // What the probe of channel ch (1..5) reads when its point is at `point_c`, at time t.
  double probe_reading_c(int ch, double point_c, double t_s) const;

  // Declared extra columns (coolant temperature degC, events 0/1) at time t.
  std::vector<std::string> declared_columns() const;
  std::vector<double> declared_values(double t_s) const;

 private:
  struct Transient {
    std::vector<int> nodes;
    bool multiplicative = false;
    bool starts_only = false;  // restarted (state = 1) by a start from standstill only
    double amplitude = 0, tau_s = 1;
    double state = 0;  // additive: accumulated 1000-rpm increments; multiplicative or starts_only: 0..1
  };
  struct Scaled { int node; double coeff_per_k; };
  struct Coupled { int node, hot, cold; double g, e; };
  struct Speed { int node; double w, e; };
  struct Latent { int node; double c, g, ga, temp_c; };

  HiddenEffects fx_;
  double w0_rpm_ = 5000.0;                  // rpm, the network's reference speed
  std::vector<Transient> transients_;
  std::vector<Scaled> scaled_;
  std::vector<Coupled> coupled_;
  std::vector<Speed> speed_;
  std::vector<int> boundary_node_;
  std::vector<std::vector<int>> event_nodes_;
  std::vector<Latent> latent_;
  double lag_tau_s_[kChannels] = {};       // s per channel, 0 = no lag
  double lag_c_[kChannels] = {};           // lagging probe readings, degC
  double drift_k_per_h_[kChannels] = {};
  double air_c_ = 20.0;
  double last_rpm_ = 0.0;
};

}  // namespace btsm::sim
