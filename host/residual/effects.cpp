// Effect library (see effects.hpp).
#include "host/residual/effects.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace btsm::residual {
namespace th = btsm::thermal;
namespace {

th::Parameter param(const std::string& name, const std::string& unit, double value, double lo, double hi, bool log_scale,
                    const std::string& description, bool fixed = false) {
  th::Parameter p;
  p.name = name;
  p.unit = unit;
  p.initial = std::clamp(value, lo, hi);
  p.initial_auto = false;
  p.nominal = p.initial;
  p.min = lo;
  p.max = hi;
  p.fixed = fixed;
  p.log_scale = log_scale;
  p.description = description;
  return p;
}

double value_or(const std::map<std::string, double>& v, const std::string& key, double def) {
  const auto it = v.find(key);
  return it == v.end() ? def : it->second;
}

// Adds a parameter (its value overridden from `values` by name) and appends the value.
int add(AugmentedModel& m, th::Parameter p, const std::map<std::string, double>& values, bool effect = true) {
  if (const auto it = values.find(p.name); it != values.end()) {
    p.initial = std::clamp(it->second, p.min, p.max);
    p.nominal = p.initial;
  }
  if (m.net.param_index(p.name) >= 0) throw std::invalid_argument("effect parameter '" + p.name + "' already exists in the network");
  const int i = m.net.add_parameter(p);
  m.params.conservativeResize(m.net.param_count());
  m.params(i) = p.initial;
  if (effect && !p.fixed) m.effect_params.push_back(p.name);
  return i;
}

int add_node(AugmentedModel& m, const std::string& name, int capacitance_param) {
  if (m.net.node_index(name) >= 0) throw std::invalid_argument("effect node '" + name + "' already exists in the network");
  th::Node nd;
  nd.name = name;
  nd.capacitance_param = capacitance_param;
  m.net.nodes.push_back(nd);
  return m.net.node_count() - 1;
}

void add_source(AugmentedModel& m, const th::Source& s) {
  for (const auto& existing : m.net.sources)
    if (existing.name == s.name) throw std::invalid_argument("effect source '" + s.name + "' already exists in the network");
  m.net.sources.push_back(s);
}

th::Term term(int p, th::TermKind kind, double exponent = 0.0) {
  th::Term t;
  t.param = p;
  t.kind = kind;
  t.speed_exponent = exponent;
  return t;
}

void add_link(AugmentedModel& m, const std::string& name, int a, int b, const std::vector<th::Term>& operating,
              const std::vector<th::Term>& cooling) {
  // As add_node(): the network reader refuses two links of one name, and a model the loop writes
  // (the demo's final_model.json) must read back.
  for (const auto& existing : m.net.links)
    if (existing.name == name) throw std::invalid_argument("effect link '" + name + "' already exists in the network");
  th::Link l;
  l.name = name;
  l.a = a;
  l.b = b;
  l.operating = operating;
  l.cooling = cooling;
  m.net.links.push_back(l);
}

void check_nodes(const th::Network& net, const EffectSpec& e, const char* what) {
  if (e.nodes.empty()) throw std::invalid_argument(std::string(what) + ": no node given");
  for (int n : e.nodes)
    if (n < 0 || n >= net.node_count()) throw std::invalid_argument(std::string(what) + ": node index out of range");
}

int measurement_of(const th::Network& net, const std::string& column, const char* what) {
  for (std::size_t i = 0; i < net.measurements.size(); ++i)
    if (net.measurements[i].column == column) return static_cast<int>(i);
  throw std::invalid_argument(std::string(what) + ": the network measures no column '" + column + "'");
}

std::string join(const std::vector<std::string>& v, const char* sep) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : sep) + x;
  return s;
}

std::string signed_pct(double v) { return fmt::format("{:+.2g} %", 100 * v); }

}  // namespace

const char* effect_name(EffectKind k) {
  switch (k) {
    case EffectKind::HeatSourceTransient: return "heat_source_transient";
    case EffectKind::TemperatureDependentHeat: return "temperature_dependent_heat";
    case EffectKind::CoupledHeat: return "coupled_heat";
    case EffectKind::ExtraHeatInput: return "extra_heat_input";
    case EffectKind::SensorLag: return "sensor_lag";
    case EffectKind::SensorDrift: return "sensor_drift";
    case EffectKind::AmbientDynamics: return "ambient_dynamics";
    case EffectKind::SecondBoundary: return "second_boundary";
    case EffectKind::EventConductance: return "event_conductance";
    case EffectKind::LatentMass: return "latent_mass";
  }
  return "?";
}

std::vector<EffectKind> all_effect_kinds() {
  return {EffectKind::HeatSourceTransient, EffectKind::TemperatureDependentHeat, EffectKind::CoupledHeat,
          EffectKind::ExtraHeatInput,      EffectKind::SensorLag,                EffectKind::SensorDrift,
          EffectKind::AmbientDynamics,     EffectKind::SecondBoundary,           EffectKind::EventConductance,
          EffectKind::LatentMass};
}

EffectKind parse_effect_kind(const std::string& name) {
  std::vector<std::string> names;
  for (EffectKind k : all_effect_kinds()) {
    if (name == effect_name(k)) return k;
    names.push_back(effect_name(k));
  }
  throw std::invalid_argument("unknown effect '" + name + "' (known: " + join(names, ", ") + ")");
}

const char* trigger_name(TransientTrigger t) {
  switch (t) {
    case TransientTrigger::SpeedIncrease: return "every speed increase (per 1000 rpm)";
    case TransientTrigger::StartOrChange: return "every start or speed change (restarting)";
    case TransientTrigger::Start: break;
  }
  return "every start from standstill (restarting; not a speed change while turning)";
}

const char* trigger_phrase(TransientTrigger t) {
  switch (t) {
    case TransientTrigger::SpeedIncrease: return "every speed increase";
    case TransientTrigger::StartOrChange: return "every start or speed change";
    case TransientTrigger::Start: break;
  }
  return "every start from standstill";
}

std::string effect_label(const EffectSpec& e, const th::Network& net) {
  const std::string s = effect_name(e.kind);
  switch (e.kind) {
    case EffectKind::SensorLag:
    case EffectKind::SensorDrift: return s + "@" + e.column;
    case EffectKind::AmbientDynamics: return s;
    default: break;
  }
  std::vector<std::string> names;
  for (int n : e.nodes) names.push_back(n >= 0 && n < net.node_count() ? net.nodes[static_cast<std::size_t>(n)].name : "?");
  return s + "@" + join(names, "+");
}

std::vector<std::string> effect_nodes(const EffectSpec& e, const th::Network& net) {
  std::vector<std::string> out;
  auto push = [&](int n) {
    if (n < 0 || n >= net.node_count()) return;
    const std::string& name = net.nodes[static_cast<std::size_t>(n)].name;
    if (std::find(out.begin(), out.end(), name) == out.end()) out.push_back(name);
  };
  switch (e.kind) {
    case EffectKind::AmbientDynamics:
      for (const auto& l : net.links)
        if (l.b == th::kAmbient) push(l.a);
      return out;
    case EffectKind::SensorLag:
    case EffectKind::SensorDrift:
      for (const auto& m : net.measurements)
        if (m.column == e.column) push(m.node);
      return out;
    default:
      for (int n : e.nodes) push(n);
      return out;
  }
}

double friction_exponent(const th::Network& net, int node) {
  double e = -1;
  for (const auto& s : net.sources)
    if (s.node == node)
      for (const auto& t : s.operating)
        if (!t.driven) e = std::max(e, t.speed_exponent);
  return e >= 0 ? e : 1.0;
}

double source_heat_at_w0(const th::Network& net, const Eigen::VectorXd& params, int node) {
  double q = 0;
  for (const auto& s : net.sources)
    if (s.node == node)
      for (const auto& t : s.operating)
        if (!t.driven && t.event < 0) q += params[t.param];
  return q;
}

AugmentedModel augment(const th::Network& base, const Eigen::VectorXd& base_params, const EffectSpec& e,
                       const std::map<std::string, double>& values) {
  if (base_params.size() != base.param_count()) throw std::invalid_argument("augment: parameter vector does not match the network");
  AugmentedModel m;
  m.net = base;
  m.params = base_params;
  const auto node_name = [&](int n) { return base.nodes[static_cast<std::size_t>(n)].name; };
  switch (e.kind) {
    case EffectKind::HeatSourceTransient: {
      check_nodes(base, e, "heat_source_transient");
      const double tau = value_or(values, "tau_transient", e.tau_s > 0 ? e.tau_s : 900.0);
      m.trigger = e.trigger;
      const int pc = add(m, param("C_transient", "J/K", kTransientCapacitance, 1e-3, 1e7, true,
                                  "capacity of the virtual transient state (fixed: the impulse scale)", true),
                         values, false);
      const int v = add_node(m, "transient", pc);
      double g_sum = 0;
      for (int n : e.nodes) {
        const std::string nn = node_name(n);
        const double ex = e.multiplicative ? friction_exponent(base, n) : 0.0;
        // amplitude -> coupling: heat right after one trigger unit = g (E/C) at w0
        double a = value_or(values, "a_transient_" + nn, e.multiplicative ? 0.3 : 2.0);
        if (e.multiplicative) a *= std::max(source_heat_at_w0(base, base_params, n), 1e-3);
        // (bounds: 1e-7 .. 1e5 W right after one trigger unit)
        const double w_to_g = kTransientCapacitance / kTransientImpulse;
        const double g = std::max(a, 1e-6) * w_to_g;
        g_sum += g;
        const int pg = add(m, param("g_transient_" + nn, "W/K", g, 1e-7 * w_to_g, 1e5 * w_to_g, true,
                                    std::string("coupling transient state -> ") + nn + (e.multiplicative ? " (x friction law)" : "")),
                           values);
        add_link(m, "g_transient_" + nn, n, v, {term(pg, th::TermKind::Conductance, ex)}, {});
        m.key_params.push_back("g_transient_" + nn);
      }
      // (bounds: a decay time of 0.1 s .. 1e9 s)
      const double g_decay = std::max(kTransientCapacitance / std::max(tau, 1.0) - g_sum, kTransientCapacitance / 1e9);
      const int pd = add(m, param("g_transient_decay", "W/K", g_decay, kTransientCapacitance / 1e9, kTransientCapacitance / 0.1, true,
                                  "decay path of the transient state"),
                         values);
      add_link(m, "g_transient_decay", v, th::kAmbient, {term(pd, th::TermKind::Conductance)}, {term(pd, th::TermKind::Conductance)});
      if (std::isfinite(m.net.sum_capacitance_J_per_K)) m.net.sum_capacitance_J_per_K += kTransientCapacitance;
      m.transient_node = v;
      m.rest_nodes = {v};
      break;
    }
    case EffectKind::TemperatureDependentHeat: {
      check_nodes(base, e, "temperature_dependent_heat");
      for (int n : e.nodes) {
        const std::string nn = node_name(n);
        const int p = add(m, param("k_heat_T_" + nn, "W/K at w0", 0.0, -1e3, 1e3, false,
                                   "growth of the heat at " + nn + " per K of its rise (negative: falls)"),
                          values);
        th::Source s;
        s.name = "heat_T_" + nn;
        s.node = n;
        th::Term t = term(p, th::TermKind::Power, friction_exponent(base, n));
        t.driven = true;
        t.hot = n;
        t.cold = th::kAmbient;
        s.operating.push_back(t);
        add_source(m, s);
        m.key_params.push_back("k_heat_T_" + nn);
      }
      break;
    }
    case EffectKind::CoupledHeat: {
      check_nodes(base, e, "coupled_heat");
      if (e.hot < 0 || e.cold < 0 || e.hot >= base.node_count() || e.cold >= base.node_count() || e.hot == e.cold)
        throw std::invalid_argument("coupled_heat: needs two different driving nodes");
      for (int n : e.nodes) {
        const std::string nn = node_name(n);
        const int p = add(m, param("k_couple_" + nn, "W/K at w0", 0.0, -1e3, 1e3, false,
                                   "heat at " + nn + " per K of " + node_name(e.hot) + " - " + node_name(e.cold)),
                          values);
        th::Source s;
        s.name = "coupled_" + nn;
        s.node = n;
        th::Term t = term(p, th::TermKind::Power, e.speed_exponent);
        t.driven = true;
        t.hot = e.hot;
        t.cold = e.cold;
        s.operating.push_back(t);
        add_source(m, s);
        m.key_params.push_back("k_couple_" + nn);
      }
      break;
    }
    case EffectKind::ExtraHeatInput: {
      check_nodes(base, e, "extra_heat_input");
      for (int n : e.nodes) {
        const std::string nn = node_name(n);
        const int p = add(m, param("q_extra_" + nn, "W at w0", 0.0, -1e4, 1e4, false,
                                   fmt::format("unmodelled heat at {} while running, x (w/w0)^{:g}", nn, e.speed_exponent)),
                          values);
        th::Source s;
        s.name = "extra_" + nn;
        s.node = n;
        s.operating.push_back(term(p, th::TermKind::Power, e.speed_exponent));
        add_source(m, s);
        m.key_params.push_back("q_extra_" + nn);
      }
      break;
    }
    case EffectKind::SensorLag: {
      const int mi = measurement_of(base, e.column, "sensor_lag");
      const int node = base.measurements[static_cast<std::size_t>(mi)].node;
      const std::string probe = "probe_" + e.column;
      const int pc = add(m, param("C_" + probe, "J/K", kProbeCapacitance, 0.5, 2.0, true, "nominal heat capacity of the probe model", true),
                         values, false);
      const int pr = add(m, param("tau_" + probe, "s", e.tau_s > 0 ? e.tau_s : 60.0, 0.01, 1e5, true,
                                  "time constant of the probe of " + e.column + " (R in K/W at C = 1 J/K)"),
                         values);
      const int v = add_node(m, probe, pc);
      add_link(m, "R_" + probe, node, v, {term(pr, th::TermKind::Resistance)}, {term(pr, th::TermKind::Resistance)});
      m.net.measurements[static_cast<std::size_t>(mi)].node = v;
      if (std::isfinite(m.net.sum_capacitance_J_per_K)) m.net.sum_capacitance_J_per_K += kProbeCapacitance;
      m.key_params.push_back("tau_" + probe);
      break;
    }
    case EffectKind::SensorDrift: {
      const int mi = measurement_of(base, e.column, "sensor_drift");
      if (base.measurements[static_cast<std::size_t>(mi)].drift_param >= 0)
        throw std::invalid_argument("sensor_drift: column '" + e.column + "' drifts already");
      const int p = add(m, param("d_" + e.column, "K/h", 0.0, -10.0, 10.0, false,
                                 "drift of the probe of " + e.column + " (its offset: one nuisance per recording)"),
                        values);
      m.net.measurements[static_cast<std::size_t>(mi)].drift_param = p;
      m.key_params.push_back("d_" + e.column);
      break;
    }
    case EffectKind::AmbientDynamics: {
      if (base.node_index("ambient_lag") >= 0) throw std::invalid_argument("ambient_dynamics: node 'ambient_lag' already exists");
      const th::NodeMatrices nm = th::assemble(base, base_params, base.speed_ref_rpm);
      const double g_amb = std::max(nm.ambient_conductance.sum(), 1e-3);
      const double tau = e.tau_s > 0 ? e.tau_s : 1800.0;
      // a lag that the machine's own heat barely warms: g well above the machine's conductance
      const double g = value_or(values, "g_ambient_lag", 20.0 * g_amb);
      const int pc = add(m, param("C_ambient_lag", "J/K", value_or(values, "C_ambient_lag", g * tau), 1.0, 1e10, true,
                                  "heat capacity of the air/structure between the machine and the measured ambient"),
                         values);
      const int pg = add(m, param("g_ambient_lag", "W/K", g, 1e-4, 1e7, true, "conductance from that lagged ambient to the measured ambient"),
                         values);
      const int v = add_node(m, "ambient_lag", pc);
      for (auto& l : m.net.links)
        if (l.b == th::kAmbient) l.b = v;
      for (auto& s : m.net.sources)
        for (auto* ts : {&s.operating, &s.cooling})
          for (auto& t : *ts)
            if (t.driven) {
              if (t.hot == th::kAmbient) t.hot = v;
              if (t.cold == th::kAmbient) t.cold = v;
            }
      add_link(m, "g_ambient_lag", v, th::kAmbient, {term(pg, th::TermKind::Conductance)}, {term(pg, th::TermKind::Conductance)});
      m.net.sum_capacitance_J_per_K = std::numeric_limits<double>::quiet_NaN();  // the caller holds a base capacitance
      // The effect exists when the air lags the measured ambient: its time constant C/g differs from
      // zero. C and g alone are not the evidence: a lag node tied tightly to the room (g well above the
      // machine's conductance, as the start above) shows only C/g, so C and g can each be weak while
      // the lag itself is determined to a fraction of a percent.
      m.key_params = {"C_ambient_lag/g_ambient_lag"};
      m.adds_free_capacitance = true;
      break;
    }
    case EffectKind::SecondBoundary: {
      check_nodes(base, e, "second_boundary");
      if (e.column.empty()) throw std::invalid_argument("second_boundary: no boundary column given");
      int b = -1;
      for (std::size_t k = 0; k < m.net.boundaries.size(); ++k)
        if (m.net.boundaries[k] == e.column) b = static_cast<int>(k);
      if (b < 0) {
        m.net.boundaries.push_back(e.column);
        b = static_cast<int>(m.net.boundaries.size()) - 1;
      }
      for (int n : e.nodes) {
        const std::string nn = node_name(n);
        const int p = add(m, param("g_" + e.column + "_" + nn, "W/K", 0.5, 1e-6, 1e4, true,
                                   "conductance " + nn + " - boundary column " + e.column),
                          values);
        add_link(m, e.column + "_" + nn, n, th::boundary_end(b), {term(p, th::TermKind::Conductance)},
                 {term(p, th::TermKind::Conductance)});
        m.key_params.push_back("g_" + e.column + "_" + nn);
      }
      break;
    }
    case EffectKind::EventConductance: {
      check_nodes(base, e, "event_conductance");
      if (e.column.empty()) throw std::invalid_argument("event_conductance: no event column given");
      int ev = -1;
      for (std::size_t k = 0; k < m.net.events.size(); ++k)
        if (m.net.events[k] == e.column) ev = static_cast<int>(k);
      if (ev < 0) {
        m.net.events.push_back(e.column);
        ev = static_cast<int>(m.net.events.size()) - 1;
      }
      for (int n : e.nodes) {
        const std::string nn = node_name(n);
        const int p = add(m, param("g_" + e.column + "_" + nn, "W/K", 0.5, 1e-6, 1e4, true,
                                   "conductance " + nn + " - ambient while " + e.column + " is 1"),
                          values);
        th::Term t = term(p, th::TermKind::Conductance);
        t.event = ev;
        add_link(m, e.column + "_" + nn, n, th::kAmbient, {t}, {t});
        m.key_params.push_back("g_" + e.column + "_" + nn);
      }
      break;
    }
    case EffectKind::LatentMass: {
      check_nodes(base, e, "latent_mass");
      for (int n : e.nodes) {
        const std::string nn = node_name(n);
        const double tau = e.tau_s > 0 ? e.tau_s : 1800.0;
        const double g = value_or(values, "g_latent_" + nn, 2.0);
        const int pc = add(m, param("C_latent_" + nn, "J/K", value_or(values, "C_latent_" + nn, g * tau), 1.0, 1e9, true,
                                    "missing heat capacity tied to " + nn),
                           values);
        const int pg = add(m, param("g_latent_" + nn, "W/K", g, 1e-4, 1e5, true, "conductance " + nn + " - its missing mass"), values);
        const int v = add_node(m, "latent_" + nn, pc);
        add_link(m, "g_latent_" + nn, n, v, {term(pg, th::TermKind::Conductance)}, {term(pg, th::TermKind::Conductance)});
        m.key_params.push_back("g_latent_" + nn);
        m.key_params.push_back("C_latent_" + nn);
      }
      m.net.sum_capacitance_J_per_K = std::numeric_limits<double>::quiet_NaN();  // the caller holds a base capacitance
      m.adds_free_capacitance = true;
      break;
    }
  }
  m.net.validate();
  return m;
}

std::vector<double> transient_triggers(const th::Network& net, const th::Recording& rec, TransientTrigger trigger, double restart_tau_s) {
  std::vector<double> u(rec.rows(), 0.0);
  double prev = 0;    // a recording starts from standstill
  double left = 0.0;  // StartOrChange: the share of the last restart still decaying
  for (std::size_t k = 0; k < rec.rows(); ++k) {
    if (k > 0 && restart_tau_s > 0) left *= std::exp(-(rec.time_s[k] - rec.time_s[k - 1]) / restart_tau_s);
    const double w = rec.speed_rpm[k];
    const bool running = net.mode_at(w) == th::Mode::Operating;
    const bool was_running = net.mode_at(prev) == th::Mode::Operating;
    if (running && w != prev && (trigger != TransientTrigger::Start || !was_running)) {
      if (trigger == TransientTrigger::SpeedIncrease) {
        u[k] = std::max(0.0, w - (was_running ? prev : 0.0)) / 1000.0;
      } else {
        // a restart, not a second helping: the extra heat is back at its full size however much
        // of the last one was left (1 - left tops the state up to one trigger unit)
        u[k] = restart_tau_s > 0 ? 1.0 - left : 1.0;
        left = 1.0;
      }
    }
    prev = w;
  }
  return u;
}

double transient_tau_s(const th::Network& net, const Eigen::VectorXd& params) {
  double g = 0;
  for (int i = 0; i < net.param_count(); ++i)
    if (net.params[static_cast<std::size_t>(i)].name.rfind("g_transient_", 0) == 0 && i < params.size()) g += params[i];
  return g > 0 ? kTransientCapacitance / g : 0.0;
}

Eigen::MatrixXd transient_impulses_w(const th::Network& net, const Eigen::VectorXd& params, const th::Recording& rec, int node,
                                     TransientTrigger trigger) {
  if (node < 0 || node >= net.node_count()) throw std::invalid_argument("heat_source_transient: node index out of range");
  const std::vector<double> u = transient_triggers(net, rec, trigger, transient_tau_s(net, params));
  const auto rows = static_cast<Eigen::Index>(rec.rows());
  Eigen::MatrixXd q = Eigen::MatrixXd::Zero(rows, net.node_count());
  for (Eigen::Index k = 0; k + 1 < rows; ++k)
    if (u[static_cast<std::size_t>(k)] > 0)
      q(k, node) = kTransientImpulse * u[static_cast<std::size_t>(k)] / (rec.time_s[static_cast<std::size_t>(k) + 1] - rec.time_s[static_cast<std::size_t>(k)]);
  return q;
}

std::vector<EffectQuantity> effect_quantities(const AugmentedModel& m, const EffectSpec& e, const th::Network& base,
                                              const Eigen::VectorXd& v, const Eigen::MatrixXd& cov) {
  std::vector<EffectQuantity> out;
  const auto idx = [&](const std::string& name) { return m.net.param_index(name); };
  const auto var = [&](int i) { return i >= 0 && i < cov.rows() ? std::max(cov(i, i), 0.0) : 0.0; };
  const auto sd = [&](int i) { return std::sqrt(var(i)); };
  const auto node_name = [&](int n) { return base.nodes[static_cast<std::size_t>(n)].name; };
  switch (e.kind) {
    case EffectKind::HeatSourceTransient: {
      const int id = idx("g_transient_decay");
      double s = v[id], s_var = var(id);
      for (int n : e.nodes) {
        const int ig = idx("g_transient_" + node_name(n));
        s += v[ig];
        s_var += var(ig) + 2 * (id < cov.rows() && ig < cov.rows() ? cov(id, ig) : 0.0);
      }
      const double tau = kTransientCapacitance / s;
      out.push_back({"tau_transient", "s", tau, kTransientCapacitance / (s * s) * std::sqrt(std::max(s_var, 0.0)),
                     fmt::format("the extra heat decays with {:.0f} min after {}", tau / 60, trigger_name(e.trigger))});
      for (int n : e.nodes) {
        const int ig = idx("g_transient_" + node_name(n));
        const double a = v[ig] * kTransientImpulse / kTransientCapacitance, as = sd(ig) * kTransientImpulse / kTransientCapacitance;
        if (e.multiplicative) {
          const double q0 = source_heat_at_w0(base, v.head(base.param_count()), n);
          const double share = q0 > 0 ? a / q0 : std::numeric_limits<double>::quiet_NaN();
          out.push_back({"a_transient_" + node_name(n), "W at w0", a, as,
                         fmt::format("{} of the {} friction heat right after {}", signed_pct(share), node_name(n),
                                     e.trigger == TransientTrigger::SpeedIncrease   ? "each 1000 rpm of increase"
                                     : e.trigger == TransientTrigger::StartOrChange ? "each start or speed change"
                                                                                     : "each start from standstill")});
        } else {
          out.push_back({"a_transient_" + node_name(n),
                         e.trigger == TransientTrigger::SpeedIncrease   ? "W per 1000 rpm of increase"
                         : e.trigger == TransientTrigger::StartOrChange ? "W per start/change"
                                                                         : "W per start",
                         a, as, fmt::format("{:+.3g} W at {} right after {}", a, node_name(n), trigger_name(e.trigger))});
        }
      }
      break;
    }
    case EffectKind::TemperatureDependentHeat:
      for (int n : e.nodes) {
        const int i = idx("k_heat_T_" + node_name(n));
        const double q0 = source_heat_at_w0(base, v.head(base.param_count()), n);
        std::string meaning = fmt::format("{:+.3g} W per K of the {} rise at w0", v[i], node_name(n));
        if (q0 > 0) meaning = fmt::format("{} of the {} heat per K ({:+.3g} W/K at w0): heat {} with temperature", signed_pct(v[i] / q0),
                                          node_name(n), v[i], v[i] >= 0 ? "grows" : "falls");
        out.push_back({"heat_per_K_" + node_name(n), "W/K at w0", v[i], sd(i), meaning});
      }
      break;
    case EffectKind::CoupledHeat:
      for (int n : e.nodes) {
        const int i = idx("k_couple_" + node_name(n));
        out.push_back({"coupled_heat_" + node_name(n), "W/K at w0", v[i], sd(i),
                       fmt::format("{:+.3g} W at {} per K of {} - {} (x (w/w0)^{:g})", v[i], node_name(n), node_name(e.hot),
                                   node_name(e.cold), e.speed_exponent)});
      }
      break;
    case EffectKind::ExtraHeatInput:
      for (int n : e.nodes) {
        const int i = idx("q_extra_" + node_name(n));
        out.push_back({"extra_heat_" + node_name(n), "W at w0", v[i], sd(i),
                       fmt::format("{:+.3g} W at {} at w0 while running, x (w/w0)^{:g}", v[i], node_name(n), e.speed_exponent)});
      }
      break;
    case EffectKind::SensorLag: {
      const int i = idx("tau_probe_" + e.column);
      out.push_back({"tau_probe_" + e.column, "s", v[i], sd(i), fmt::format("the probe of {} lags its node by {:.3g} s", e.column, v[i])});
      break;
    }
    case EffectKind::SensorDrift: {
      const int i = idx("d_" + e.column);
      out.push_back({"drift_" + e.column, "K/h", v[i], sd(i),
                     fmt::format("the probe of {} reads {:+.3g} K per hour of recording too {}", e.column, v[i], v[i] >= 0 ? "high" : "low")});
      break;
    }
    case EffectKind::AmbientDynamics: {
      const int ic = idx("C_ambient_lag"), ig = idx("g_ambient_lag");
      const double tau = v[ic] / v[ig];
      const double rel = std::sqrt(var(ic) / (v[ic] * v[ic]) + var(ig) / (v[ig] * v[ig]) -
                                   2 * (ic < cov.rows() && ig < cov.rows() ? cov(ic, ig) : 0.0) / (v[ic] * v[ig]));
      out.push_back({"tau_ambient_lag", "s", tau, tau * (std::isfinite(rel) ? rel : 0.0),
                     fmt::format("the air around the machine follows the measured ambient with {:.0f} min", tau / 60)});
      out.push_back({"C_ambient_lag", "J/K", v[ic], sd(ic), "heat capacity of that air/structure"});
      out.push_back({"g_ambient_lag", "W/K", v[ig], sd(ig), "its conductance to the measured ambient"});
      break;
    }
    case EffectKind::SecondBoundary:
    case EffectKind::EventConductance:
      for (int n : e.nodes) {
        const int i = idx("g_" + e.column + "_" + node_name(n));
        out.push_back({"g_" + e.column + "_" + node_name(n), "W/K", v[i], sd(i),
                       e.kind == EffectKind::SecondBoundary
                           ? fmt::format("{:.3g} W/K between {} and the boundary column {}", v[i], node_name(n), e.column)
                           : fmt::format("{:.3g} W/K more from {} to ambient while {} is 1", v[i], node_name(n), e.column)});
      }
      break;
    case EffectKind::LatentMass:
      for (int n : e.nodes) {
        const int ic = idx("C_latent_" + node_name(n)), ig = idx("g_latent_" + node_name(n));
        out.push_back({"C_latent_" + node_name(n), "J/K", v[ic], sd(ic), fmt::format("a missing mass of {:.3g} J/K at {}", v[ic], node_name(n))});
        out.push_back({"g_latent_" + node_name(n), "W/K", v[ig], sd(ig),
                       fmt::format("tied by {:.3g} W/K (time constant {:.0f} min)", v[ig], v[ic] / v[ig] / 60)});
      }
      break;
  }
  return out;
}

}  // namespace btsm::residual
