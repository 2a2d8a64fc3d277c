#include "host/sim/plant/spindle_plant.hpp"

#include <cmath>
#include <filesystem>
#include <stdexcept>

namespace btsm::sim {
namespace {

thermal::Network load(const std::string& name) {
  if (std::filesystem::exists(name)) return thermal::load_network(name);
  return thermal::preset_network(name);
}

}  // namespace

SpindlePlant::SpindlePlant(PlantOptions opts) : opts_(std::move(opts)) {
  if (!(opts_.step_s > 0.0) || opts_.step_s > 60.0)
    throw std::invalid_argument("plant: step_s must be within (0, 60] s");
  if (opts_.ch5_surface_fraction < 0.0 || opts_.ch5_surface_fraction > 1.0)
    throw std::invalid_argument("plant: ch5_surface_fraction must be within 0..1");
  thermal::Network net = load(opts_.network);
  params_ = thermal::default_parameters(net);
  for (int i = 0; i < params_.size(); ++i)
    if (!std::isfinite(params_[i]))
      throw std::invalid_argument("plant: network '" + opts_.network + "' parameter " +
                                  net.params[i].name + " has no value");
  if (net.node_count() < 3) throw std::invalid_argument("plant: network needs at least 3 nodes");
  for (int p : opts_.probe_place)
    if (p < 0 || p > 2) throw std::invalid_argument("plant: probe_place entries must be 0 (rear bearing), 1 (housing) or 2 (front bearing)");
  // Channel j (1..3) is the node measured as "Tj" when the network says so, else node j-1.
  // The shaft (for a ch5 on the shaft end) likewise: "T4", else node 3.
  for (int j = 0; j < 4; ++j) {
    node_[j] = j < net.node_count() ? j : -1;
    for (const auto& m : net.measurements)
      if (m.column == "T" + std::to_string(j + 1)) node_[j] = m.node;
  }
  if (opts_.ch5 == Ch5Mode::ShaftEnd && node_[3] < 0)
    throw std::invalid_argument("plant: ch5 on the shaft end needs a fourth (shaft) node in the network");
  sim_ = std::make_unique<thermal::Simulator>(net, params_);
  const double amb0 = opts_.ambient.celsius_at(0.0);
  Eigen::VectorXd x0 = Eigen::VectorXd::Constant(net.node_count(), amb0);
  if (opts_.start_steady) x0 = thermal::steady_state_c(net, params_, opts_.start_steady_rpm, amb0);
  sim_->reset(x0);
  extra_w_ = Eigen::VectorXd::Zero(net.node_count());
  // A cold machine stood still before t = 0, so a speed at t = 0 is a start.
  effects_ = make_effects(opts_.start_steady ? opts_.start_steady_rpm : 0.0);
}

std::unique_ptr<EffectDynamics> SpindlePlant::make_effects(double rpm0) const {
  ProbeNodes probes;
  probes.rear_bearing = node_[0];
  probes.housing = node_[1];
  probes.front_bearing = node_[2];
  probes.shaft = node_[3];
  return std::make_unique<EffectDynamics>(opts_.effects, sim_->network(), probes, sim_->node_temp_c(), ambient_c(),
                                          rpm0);
}

void SpindlePlant::set_effects(const HiddenEffects& fx) {
  opts_.effects = fx;
  effects_ = make_effects(speed_rpm());
}

double SpindlePlant::source_heat_at_node(int node, double speed_rpm) {
  if (speed_rpm != cached_heat_rpm_) {
    cached_heat_w_ = thermal::assemble(sim_->network(), params_, speed_rpm).heat_w;
    cached_heat_rpm_ = speed_rpm;
  }
  return cached_heat_w_[node];
}

void SpindlePlant::compute_extra_heat(double rpm) {
  extra_w_.setZero();
  const double t = t_s_;
  for (const auto& f : opts_.faults)
    if (f.kind == FaultKind::BearingHeat && f.active_at(t))
      extra_w_[node_[f.place == BearingPlace::Front ? 2 : 0]] += f.heat_w;
  // Hidden effects: Q of the paper's sources at this speed, node temperatures at the step start.
  source_heat_at_node(0, rpm);  // refreshes cached_heat_w_ for this speed
  effects_->add_heat(t, rpm, cached_heat_w_, sim_->node_temp_c(), extra_w_);
}

void SpindlePlant::advance_to(double t_s) {
  const double h = opts_.step_s;
  while (t_s_ + h <= t_s + 1e-9) {
    const double rpm = speed_rpm();
    compute_extra_heat(rpm);
    sim_->step(h, rpm, effects_->network_ambient_c(), extra_w_.isZero() ? nullptr : &extra_w_);
    // Accumulate as an integer step count to avoid drift over long runs.
    t_s_ = std::round((t_s_ + h) / h) * h;
    double points[kChannels];
    for (int ch = 1; ch <= kChannels; ++ch) points[ch - 1] = point_temp_c(ch);
    effects_->advance(h, sim_->node_temp_c(), ambient_c(), points);
  }
}

double SpindlePlant::speed_rpm() const { return opts_.speed.rpm_at(t_s_); }
double SpindlePlant::ambient_c() const { return opts_.ambient.celsius_at(t_s_); }

double SpindlePlant::probe_temp_c(int ch) const {
  return effects_->probe_reading_c(ch, point_temp_c(ch), t_s_);
}

double SpindlePlant::point_temp_c(int ch) const {
  const auto& x = sim_->node_temp_c();
  switch (ch) {
    case 1:
    case 2:
    case 3: return x[node_[opts_.probe_place[static_cast<std::size_t>(ch - 1)]]];
    case 4: return ambient_c();
    case 5:
      if (opts_.ch5 == Ch5Mode::ShaftEnd) return x[node_[3]];
      return ambient_c() + opts_.ch5_surface_fraction * (x[node_[1]] - ambient_c());
    default: throw std::out_of_range("plant: channel must be 1..5");
  }
}

ProbeCondition SpindlePlant::probe_condition(int ch) const {
  if (ch == 5 && opts_.ch5 == Ch5Mode::Disabled) return ProbeCondition::Absent;
  ProbeCondition c = ProbeCondition::Ok;
  for (const auto& f : opts_.faults) {
    if (f.channel != ch || !f.active_at(t_s_)) continue;
    if (f.kind == FaultKind::OpenChain) return ProbeCondition::OpenChain;
    if (f.kind == FaultKind::OpenProbe) c = ProbeCondition::Open;
    if (f.kind == FaultKind::ShortedProbe && c == ProbeCondition::Ok) c = ProbeCondition::Shorted;
  }
  return c;
}

bool SpindlePlant::adc_missing() const {
  for (const auto& f : opts_.faults)
    if (f.kind == FaultKind::MissingAdc && f.active_at(t_s_)) return true;
  return false;
}

bool SpindlePlant::reference_lost() const {
  for (const auto& f : opts_.faults)
    if (f.kind == FaultKind::LostReference && f.active_at(t_s_)) return true;
  return false;
}

void SpindlePlant::replace_speed_from_now(const std::vector<SpeedSegment>& segs) {
  opts_.speed.replace_from(t_s_, segs);
}

void SpindlePlant::queue_speed(const SpeedSegment& seg) { opts_.speed.append(seg); }

}  // namespace btsm::sim
