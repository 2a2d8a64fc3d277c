// Effect library (see effects.hpp).
#include "host/residual/effects.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace btsm::residual {
namespace th = btsm::thermal;
namespace {

th::Parameter param(const std::string& name, const std::string& unit, double value, double lo, double hi, bool log_scale,
                    const std::string& description, bool fixed = false) {
  th::Parameter p;
  p.name = name;
  p.unit = unit;
  p.initial = value;
  p.initial_auto = false;
  p.nominal = value;
  p.min = lo;
  p.max = hi;
  p.fixed = fixed;
  p.log_scale = log_scale;
  p.description = description;
  return p;
}

// Adds a parameter and appends its value to `values`.
int add(AugmentedModel& m, const th::Parameter& p, const std::map<std::string, double>& overrides, bool effect = true) {
  th::Parameter q = p;
  const auto it = overrides.find(p.name);
  if (it != overrides.end()) { q.initial = it->second; q.nominal = it->second; }
  if (m.net.param_index(q.name) >= 0) throw std::invalid_argument("effect parameter '" + q.name + "' already exists in the network");
  const int i = m.net.add_parameter(q);
  m.params.conservativeResize(m.net.param_count());
  m.params(i) = q.initial;
  if (effect && !q.fixed) m.effect_params.push_back(q.name);
  return i;
}

double friction_exponent(const th::Network& net, int node) {
  double e = -1;
  for (const auto& s : net.sources)
    if (s.node == node)
      for (const auto& t : s.operating) e = std::max(e, t.speed_exponent);
  return e >= 0 ? e : 1.0;
}

void check_node(const th::Network& net, int node, const char* what) {
  if (node < 0 || node >= net.node_count()) throw std::invalid_argument(std::string(what) + ": node index out of range");
}

}  // namespace

const char* effect_name(EffectKind k) {
  switch (k) {
    case EffectKind::HeatSourceTransient: return "heat_source_transient";
    case EffectKind::TemperatureDependentHeat: return "temperature_dependent_heat";
    case EffectKind::SensorLag: return "sensor_lag";
    case EffectKind::AmbientDynamics: return "ambient_dynamics";
    case EffectKind::ExtraHeatInput: return "extra_heat_input";
  }
  return "?";
}

std::vector<EffectKind> all_effect_kinds() {
  return {EffectKind::HeatSourceTransient, EffectKind::TemperatureDependentHeat, EffectKind::SensorLag,
          EffectKind::AmbientDynamics, EffectKind::ExtraHeatInput};
}

EffectKind parse_effect_kind(const std::string& name) {
  for (EffectKind k : all_effect_kinds())
    if (name == effect_name(k)) return k;
  throw std::invalid_argument("unknown effect '" + name +
                              "' (known: heat_source_transient, temperature_dependent_heat, sensor_lag, ambient_dynamics, extra_heat_input)");
}

std::string effect_label(const EffectSpec& e, const th::Network& net) {
  std::string s = effect_name(e.kind);
  if (e.kind == EffectKind::SensorLag) return s + "@" + e.column;
  if (e.kind == EffectKind::AmbientDynamics) return s;
  return s + "@" + (e.node >= 0 && e.node < net.node_count() ? net.nodes[e.node].name : std::string("?"));
}

std::vector<std::string> effect_nodes(const EffectSpec& e, const th::Network& net) {
  if (e.kind == EffectKind::AmbientDynamics) {
    std::vector<std::string> out;
    for (const auto& l : net.links)
      if (l.b == th::kAmbient && std::find(out.begin(), out.end(), net.nodes[l.a].name) == out.end()) out.push_back(net.nodes[l.a].name);
    return out;
  }
  if (e.node >= 0 && e.node < net.node_count()) return {net.nodes[e.node].name};
  return {};
}

AugmentedModel augment(const th::Network& base, const Eigen::VectorXd& base_params, const EffectSpec& e,
                       const std::map<std::string, double>& values) {
  if (base_params.size() != base.param_count()) throw std::invalid_argument("augment: parameter vector does not match the network");
  AugmentedModel m;
  m.net = base;
  m.params = base_params;
  switch (e.kind) {
    case EffectKind::HeatSourceTransient: {
      check_node(base, e.node, "heat_source_transient");
      const std::string n = base.nodes[e.node].name;
      double a = 1.0, tau = 600.0;  // start: 1 W per 1000 rpm, 10 min
      if (auto it = values.find("a_transient_" + n); it != values.end()) a = it->second;
      if (auto it = values.find("tau_transient_" + n); it != values.end()) tau = it->second;
      const auto [gt, gta] = transient_conductances(a, tau);
      const std::string v = "transient_" + n;
      if (base.node_index(v) >= 0) throw std::invalid_argument("heat_source_transient: node '" + v + "' already exists");
      const int pc = add(m, param("C_" + v, "J/K", kTransientCapacitance, 1.0, 1e7, true, "capacity of the virtual transient state", true),
                         values, false);
      const int pg = add(m, param("g_" + v, "W/K", gt, 1e-9, 1e3, true, "coupling transient state -> " + n + " (operating)"), values);
      const int pa = add(m, param("g_" + v + "_ambient", "W/K", gta, 1e-6, 1e4, true, "decay path of the transient state"), values);
      th::Node nd;
      nd.name = v;
      nd.capacitance_param = pc;
      m.net.nodes.push_back(nd);
      const int vi = m.net.node_count() - 1;
      th::Term tg;
      tg.param = pg;
      tg.kind = th::TermKind::Conductance;
      th::Link l1;
      l1.name = "g_" + v;
      l1.a = e.node;
      l1.b = vi;
      l1.operating.push_back(tg);  // no friction heat reaches the bearing at standstill
      th::Term ta = tg;
      ta.param = pa;
      th::Link l2;
      l2.name = "g_" + v + "_ambient";
      l2.a = vi;
      l2.b = th::kAmbient;
      l2.operating.push_back(ta);
      l2.cooling.push_back(ta);
      m.net.links.push_back(l1);
      m.net.links.push_back(l2);
      if (std::isfinite(m.net.sum_capacitance_J_per_K)) m.net.sum_capacitance_J_per_K += kTransientCapacitance;
      m.transient_node = vi;
      m.key_param = "g_" + v;
      break;
    }
    case EffectKind::TemperatureDependentHeat: {
      check_node(base, e.node, "temperature_dependent_heat");
      const std::string n = base.nodes[e.node].name;
      // heat = k (w/w0)^e theta  ==  link to ambient with conductance g = -k (w/w0)^e; the
      // parameter is g itself (negative = heat grows with temperature) so the term stays linear.
      const int p = add(m, param("g_heat_T_" + n, "W/K at w0", 0.0, -100.0, 100.0, false,
                                 "minus the growth of the heat at " + n + " per K of its temperature rise (at w0)"),
                        values);
      th::Link l;
      l.name = "heat_T_" + n;
      l.a = e.node;
      l.b = th::kAmbient;
      th::Term t;
      t.param = p;
      t.kind = th::TermKind::Conductance;
      t.speed_exponent = friction_exponent(base, e.node);
      l.operating.push_back(t);
      m.net.links.push_back(l);
      m.key_param = "g_heat_T_" + n;
      break;
    }
    case EffectKind::SensorLag: {
      int mi = -1;
      for (size_t i = 0; i < base.measurements.size(); ++i)
        if (base.measurements[i].column == e.column) mi = static_cast<int>(i);
      if (mi < 0) throw std::invalid_argument("sensor_lag: the network measures no column '" + e.column + "'");
      const int node = base.measurements[mi].node;
      const std::string probe = "probe_" + e.column;
      if (base.node_index(probe) >= 0) throw std::invalid_argument("sensor_lag: node '" + probe + "' already exists");
      const int pc = add(m, param("C_" + probe, "J/K", 1.0, 0.5, 2.0, true, "nominal heat capacity of the probe model", true), values, false);
      // With C = 1 J/K the resistance in K/W equals the time constant in s.
      const int pr = add(m, param("tau_" + probe, "s (= K/W at C 1 J/K)", 60.0, 0.01, 1e5, true,
                                  "time constant of the probe of " + e.column),
                         values);
      th::Node nd;
      nd.name = probe;
      nd.capacitance_param = pc;
      m.net.nodes.push_back(nd);
      th::Link l;
      l.name = "R_" + probe;
      l.a = node;
      l.b = m.net.node_count() - 1;
      th::Term t;
      t.param = pr;
      t.kind = th::TermKind::Resistance;
      l.operating.push_back(t);
      l.cooling.push_back(t);
      m.net.links.push_back(l);
      m.net.measurements[mi].node = m.net.node_count() - 1;
      // the probe node adds 1 J/K to the sum of capacitances the gauge uses
      if (std::isfinite(m.net.sum_capacitance_J_per_K)) m.net.sum_capacitance_J_per_K += 1.0;
      m.key_param = "tau_" + probe;
      break;
    }
    case EffectKind::AmbientDynamics: {
      if (base.node_index("ambient_lag") >= 0) throw std::invalid_argument("ambient_dynamics: node 'ambient_lag' already exists");
      double g_amb = 0;  // total conductance to ambient at the reference speed, for a start value
      const th::NodeMatrices nm = th::assemble(base, base_params, base.speed_ref_rpm);
      g_amb = nm.ambient_conductance.sum();
      double sum_c = 0;
      for (const auto& nd : base.nodes) sum_c += base_params(nd.capacitance_param);
      const int pc = add(m, param("C_ambient_lag", "J/K", 0.5 * sum_c, 1.0, 1e9, true,
                                  "heat capacity of the air/structure between the machine and the measured ambient"),
                         values);
      const int pg = add(m, param("g_ambient_lag", "W/K", 4.0 * std::max(g_amb, 1e-3), 1e-4, 1e6, true,
                                  "conductance from that lagged ambient to the measured ambient"),
                         values);
      th::Node nd;
      nd.name = "ambient_lag";
      nd.capacitance_param = pc;
      m.net.nodes.push_back(nd);
      const int v = m.net.node_count() - 1;
      for (auto& l : m.net.links)
        if (l.b == th::kAmbient) l.b = v;
      th::Link l;
      l.name = "g_ambient_lag";
      l.a = v;
      l.b = th::kAmbient;
      th::Term t;
      t.param = pg;
      t.kind = th::TermKind::Conductance;
      l.operating.push_back(t);
      l.cooling.push_back(t);
      m.net.links.push_back(l);
      // the gauge (if any) is the sum over the ORIGINAL nodes; the caller holds a base capacitance
      m.net.sum_capacitance_J_per_K = std::numeric_limits<double>::quiet_NaN();
      m.key_param = "C_ambient_lag";
      break;
    }
    case EffectKind::ExtraHeatInput: {
      check_node(base, e.node, "extra_heat_input");
      const std::string n = base.nodes[e.node].name;
      const int p0 = add(m, param("q_extra_" + n, "W", 0.0, -1e4, 1e4, false, "unmodelled constant heat at " + n + " while running"), values);
      const int p1 = add(m, param("q_extra_speed_" + n, "W at w0", 0.0, -1e4, 1e4, false,
                                  "unmodelled speed-proportional heat at " + n + " (x w/w0)"),
                         values);
      th::Source s;
      s.name = "extra_" + n;
      s.node = e.node;
      th::Term t0;
      t0.param = p0;
      t0.kind = th::TermKind::Power;
      th::Term t1 = t0;
      t1.param = p1;
      t1.speed_exponent = 1.0;
      s.operating = {t0, t1};
      m.net.sources.push_back(s);
      m.key_param = "q_extra_" + n;
      break;
    }
  }
  m.net.validate();
  return m;
}

std::pair<double, double> transient_conductances(double amplitude_w_per_krpm, double tau_s) {
  if (!(tau_s > 0) || !(amplitude_w_per_krpm > 0)) throw std::invalid_argument("heat_source_transient: amplitude and tau must be > 0");
  const double gt = amplitude_w_per_krpm * kTransientCapacitance / kTransientImpulse;
  const double total = kTransientCapacitance / tau_s;
  if (!(total > gt)) throw std::invalid_argument("heat_source_transient: amplitude x tau exceeds the impulse energy scale");
  return {gt, total - gt};
}

TransientValues transient_values(double gt, double gta, double var_gt, double var_gta, double cov) {
  TransientValues v;
  v.amplitude_w_per_krpm = kTransientImpulse * gt / kTransientCapacitance;
  v.amplitude_sigma = kTransientImpulse * std::sqrt(std::max(var_gt, 0.0)) / kTransientCapacitance;
  const double s = gt + gta;
  v.tau_s = kTransientCapacitance / s;
  v.tau_sigma = kTransientCapacitance / (s * s) * std::sqrt(std::max(var_gt + var_gta + 2 * cov, 0.0));
  return v;
}

Eigen::MatrixXd transient_impulses_w(const th::Network& net, const th::Recording& rec, int node) {
  check_node(net, node, "heat_source_transient");
  const Eigen::Index rows = static_cast<Eigen::Index>(rec.rows());
  Eigen::MatrixXd q = Eigen::MatrixXd::Zero(rows, net.node_count());
  double prev = 0;
  for (Eigen::Index k = 0; k + 1 < rows; ++k) {
    const double w = rec.speed_rpm[k];
    const double inc = std::max(0.0, w - prev);
    prev = w;
    if (inc > 0 && net.mode_at(w) == th::Mode::Operating) q(k, node) = kTransientImpulse * inc / 1000.0 / (rec.time_s[k + 1] - rec.time_s[k]);
  }
  return q;
}

}  // namespace btsm::residual
