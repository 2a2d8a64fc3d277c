#include "host/sim/plant/effect_dynamics.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace btsm::sim {
namespace {

int resolve(const thermal::Network& net, const std::string& name, const std::string& what) {
  const int i = net.node_index(name);
  if (i >= 0) return i;
  std::string names;
  for (const auto& n : net.nodes) names += (names.empty() ? "" : ", ") + n.name;
  throw std::invalid_argument(what + ": no node '" + name + "' in network '" + net.name + "' (nodes: " + names + ")");
}

// Nodes that carry one of the paper's friction sources: the only ones a multiplicative or
// temperature-dependent effect on "the existing source" can act on.
std::vector<bool> source_nodes(const thermal::Network& net) {
  std::vector<bool> has(size_t(net.node_count()), false);
  for (const auto& s : net.sources) has[size_t(s.node)] = true;
  return has;
}

}  // namespace

EffectDynamics::EffectDynamics(const HiddenEffects& fx, const thermal::Network& net, const ProbeNodes& probes,
                               const Eigen::VectorXd& x0_c, double ambient0_c, double rpm0)
    : fx_(fx), w0_rpm_(net.speed_ref_rpm), air_c_(ambient0_c), last_rpm_(rpm0) {
  const auto has_source = source_nodes(net);
  const auto source_node = [&](const std::string& name, const std::string& what) {
    const int i = resolve(net, name, what);
    if (!has_source[size_t(i)])
      throw std::invalid_argument(what + ": node '" + name + "' has no friction source to scale (use transient or speed-heat)");
    return i;
  };
  // The demo's two historic specs, expressed in the general families.
  if (fx.bearing_temp_coeff_per_k != 0.0) scaled_.push_back({probes.rear_bearing, fx.bearing_temp_coeff_per_k});
  if (fx.runin_w_per_krpm != 0.0)
    transients_.push_back({{probes.rear_bearing, probes.front_bearing}, false, false, fx.runin_w_per_krpm, fx.runin_tau_s, 0.0});
  for (const auto& t : fx.transients) {
    Transient r;
    const std::string what = std::string("effect ") + (t.multiplicative ? "transient-gain" : "transient") + (t.starts_only ? "-start" : "");
    for (const auto& n : t.nodes) r.nodes.push_back(t.multiplicative ? source_node(n, what) : resolve(net, n, what));
    r.multiplicative = t.multiplicative;
    r.starts_only = t.starts_only;
    r.amplitude = t.amplitude;
    r.tau_s = t.tau_s;
    transients_.push_back(r);
  }
  for (const auto& h : fx.temperature_heat)
    for (const auto& n : h.nodes) scaled_.push_back({source_node(n, "effect temp-heat"), h.coeff_per_k});
  for (const auto& c : fx.coupled_heat)
    coupled_.push_back({resolve(net, c.node, "effect coupled-heat"), resolve(net, c.hot, "effect coupled-heat"),
                        resolve(net, c.cold, "effect coupled-heat"), c.w_per_k, c.speed_exponent});
  for (const auto& s : fx.speed_heat) speed_.push_back({resolve(net, s.node, "effect speed-heat"), s.w_at_ref, s.speed_exponent});
  for (const auto& b : fx.boundaries) boundary_node_.push_back(resolve(net, b.node, "effect coolant"));
  for (const auto& e : fx.events) {
    std::vector<int> nodes;
    for (const auto& n : e.nodes) nodes.push_back(resolve(net, n, "effect event"));
    event_nodes_.push_back(nodes);
  }
  for (const auto& m : fx.latent) {
    const int i = resolve(net, m.node, "effect latent");
    // The missing mass starts in equilibrium with its node and the air.
    const double t0 = (m.g_w_per_k * x0_c[i] + m.g_ambient_w_per_k * ambient0_c) / (m.g_w_per_k + m.g_ambient_w_per_k);
    latent_.push_back({i, m.c_j_per_k, m.g_w_per_k, m.g_ambient_w_per_k, t0});
  }
  // Probe points at t = 0 (lagging probes start settled).
  const int point_node[kChannels] = {probes.rear_bearing, probes.housing, probes.front_bearing, -1, probes.shaft};
  for (const auto& l : fx.sensor_lag) {
    lag_tau_s_[l.channel - 1] = l.tau_s;
    const int n = point_node[l.channel - 1];
    lag_c_[l.channel - 1] = n >= 0 && n < x0_c.size() ? x0_c[n] : ambient0_c;
  }
  for (const auto& d : fx.sensor_drift) drift_k_per_h_[d.channel - 1] += d.k_per_h;
}

void EffectDynamics::add_heat(double t_s, double rpm, const Eigen::VectorXd& source_w, const Eigen::VectorXd& x_c,
                              Eigen::VectorXd& extra_w) {
  const bool running = rpm > 0.0;
  const double w = rpm / w0_rpm_;
  // Run-in transients: an additive one accumulates every speed increase (a start included); a
  // multiplicative one re-arms at every start or speed change; a starts-only one (either kind)
  // re-arms at a start from standstill only. Friction heat needs rotation.
  for (auto& tr : transients_) {
    if (tr.starts_only) {
      if (running && !(last_rpm_ > 0.0)) tr.state = 1.0;
    } else if (tr.multiplicative) {
      if (rpm != last_rpm_ && running) tr.state = 1.0;
    } else if (rpm > last_rpm_) {
      tr.state += (rpm - last_rpm_) / 1000.0;
    }
    if (running)
      for (int n : tr.nodes) extra_w[n] += tr.amplitude * tr.state * (tr.multiplicative ? source_w[n] : 1.0);
  }
  last_rpm_ = rpm;
  for (const auto& s : scaled_) {
    const double factor = std::max(0.0, 1.0 + s.coeff_per_k * (x_c[s.node] - air_c_));
    extra_w[s.node] += (factor - 1.0) * source_w[s.node];
  }
  if (running) {
    for (const auto& c : coupled_) extra_w[c.node] += c.g * std::pow(w, c.e) * (x_c[c.hot] - x_c[c.cold]);
    for (const auto& s : speed_) extra_w[s.node] += s.w * std::pow(w, s.e);
  }
  for (size_t i = 0; i < boundary_node_.size(); ++i) {
    const int n = boundary_node_[i];
    extra_w[n] += fx_.boundaries[i].w_per_k * (fx_.boundaries[i].temperature.celsius_at(t_s) - x_c[n]);
  }
  for (size_t i = 0; i < event_nodes_.size(); ++i)
    if (fx_.events[i].on_at(t_s))
      for (int n : event_nodes_[i]) extra_w[n] += fx_.events[i].w_per_k * (air_c_ - x_c[n]);
  for (const auto& m : latent_) extra_w[m.node] += m.g * (m.temp_c - x_c[m.node]);
}

void EffectDynamics::advance(double h_s, const Eigen::VectorXd& x_c, double measured_ambient_c, const double point_c[kChannels]) {
  for (auto& tr : transients_) tr.state *= std::exp(-h_s / tr.tau_s);
  for (auto& m : latent_) {
    // Exact over the step with the node and the air held.
    const double g = m.g + m.ga;
    const double target = (m.g * x_c[m.node] + m.ga * air_c_) / g;
    m.temp_c = target + (m.temp_c - target) * std::exp(-g * h_s / m.c);
  }
  if (fx_.ambient_lag_tau_s > 0.0)
    air_c_ = measured_ambient_c + (air_c_ - measured_ambient_c) * std::exp(-h_s / fx_.ambient_lag_tau_s);
  else
    air_c_ = measured_ambient_c;
  for (int i = 0; i < kChannels; ++i)
    if (lag_tau_s_[i] > 0.0) lag_c_[i] = point_c[i] + (lag_c_[i] - point_c[i]) * std::exp(-h_s / lag_tau_s_[i]);
}

double EffectDynamics::probe_reading_c(int ch, double point_c, double t_s) const {
  const int i = ch - 1;
  const double seen = lag_tau_s_[i] > 0.0 ? lag_c_[i] : point_c;
  return seen + drift_k_per_h_[i] * t_s / 3600.0;
}

std::vector<std::string> EffectDynamics::declared_columns() const {
  auto cols = fx_.boundary_columns();
  for (const auto& e : fx_.event_columns()) cols.push_back(e);
  return cols;
}

std::vector<double> EffectDynamics::declared_values(double t_s) const {
  std::vector<double> v;
  for (const auto& b : fx_.boundaries) v.push_back(b.temperature.celsius_at(t_s));
  for (const auto& e : fx_.events) v.push_back(e.on_at(t_s) ? 1.0 : 0.0);
  return v;
}

}  // namespace btsm::sim
