#include "host/sim/plant/hidden_effects.hpp"

#include "host/io/decimal_number.hpp"

#include <cmath>
#include <stdexcept>

namespace btsm::sim {
namespace {

struct SpecError {
  std::string spec;
  [[noreturn]] void operator()(const std::string& what) const {
    throw std::invalid_argument("effect '" + spec + "': " + what);
  }
};

// Strict number with an optional unit suffix (e.g. "6W", "0.8W/K", "30%"); the whole text must be
// used. `percent` makes "30%" read as 0.3.
double number(const std::string& text, const std::vector<std::string>& suffixes, const std::string& what,
              const SpecError& fail) {
  std::string t = text;
  double scale = 1.0;
  for (const auto& s : suffixes)
    if (t.size() > s.size() && t.compare(t.size() - s.size(), s.size(), s) == 0) {
      if (s == "%") scale = 0.01;
      t.resize(t.size() - s.size());
      break;
    }
  const auto v = io::decimal_number(t);
  if (!v) fail(what + ": '" + text + "' is not a number");
  return *v * scale;
}

double duration(const std::string& text, const std::string& what, const SpecError& fail) {
  double v = 0.0;
  try {
    v = parse_duration_s(text, what);
  } catch (const std::invalid_argument& e) {
    fail(e.what());
  }
  return v;
}

void check_range(double v, double lo, double hi, const std::string& what, const SpecError& fail) {
  if (!(v >= lo && v <= hi))
    fail(what + " must be within " + std::to_string(lo) + " .. " + std::to_string(hi));
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  size_t b = 0;
  for (;;) {
    const auto e = s.find(sep, b);
    out.push_back(s.substr(b, e == std::string::npos ? std::string::npos : e - b));
    if (e == std::string::npos) break;
    b = e + 1;
  }
  return out;
}

std::vector<std::string> node_list(const std::string& text, const SpecError& fail) {
  if (text.empty()) fail("missing @NODES (e.g. @rear_bearing+front_bearing)");
  auto nodes = split(text, '+');
  for (const auto& n : nodes)
    if (n.empty()) fail("empty node name in '" + text + "'");
  return nodes;
}

std::string one_node(const std::string& text, const SpecError& fail) {
  const auto nodes = node_list(text, fail);
  if (nodes.size() != 1) fail("takes exactly one node, got '" + text + "'");
  return nodes[0];
}

int channel(const std::string& text, const SpecError& fail) {
  if (text.size() != 3 || text.compare(0, 2, "ch") != 0 || (text[2] != '1' && text[2] != '2' && text[2] != '3' &&
                                                            text[2] != '5'))
    fail("channel must be ch1, ch2, ch3 or ch5 (ch4 is the ambient probe), got '" + text + "'");
  return text[2] - '0';
}

// "A/B" -> {A, B}; `form` names the expected shape in the error.
std::pair<std::string, std::string> pair_of(const std::string& text, const std::string& form, const SpecError& fail) {
  const auto slash = text.find('/');
  if (slash == std::string::npos) fail("expected " + form);
  return {text.substr(0, slash), text.substr(slash + 1)};
}

// "X^E" -> {X, E}; E defaults to 1.
std::pair<std::string, double> with_exponent(const std::string& text, const SpecError& fail) {
  const auto hat = text.find('^');
  if (hat == std::string::npos) return {text, 1.0};
  const double e = number(text.substr(hat + 1), {}, "speed exponent", fail);
  check_range(e, 0.0, 3.0, "speed exponent", fail);
  return {text.substr(0, hat), e};
}

}  // namespace

bool EventConductance::on_at(double t_s) const {
  for (const auto& [a, b] : on_s)
    if (t_s >= a && t_s < b) return true;
  return false;
}

bool HiddenEffects::any() const {
  return bearing_temp_coeff_per_k != 0.0 || runin_w_per_krpm != 0.0 || !transients.empty() ||
         !temperature_heat.empty() || !coupled_heat.empty() || !speed_heat.empty() || !sensor_lag.empty() ||
         !sensor_drift.empty() || ambient_lag_tau_s > 0.0 || !boundaries.empty() || !events.empty() || !latent.empty();
}

std::vector<std::string> HiddenEffects::boundary_columns() const {
  std::vector<std::string> out;
  for (const auto& b : boundaries) out.push_back(b.column);
  return out;
}

std::vector<std::string> HiddenEffects::event_columns() const {
  std::vector<std::string> out;
  for (const auto& e : events) out.push_back(e.column);
  return out;
}

void parse_effect(const std::string& spec, HiddenEffects& fx) {
  const SpecError fail{spec};
  const auto colon = spec.find(':');
  const std::string kind = spec.substr(0, colon);
  const std::string arg = colon == std::string::npos ? std::string() : spec.substr(colon + 1);
  if (arg.empty()) fail("missing ':' and parameters");
  // "VALUES@TARGET" for every kind that names nodes or a channel.
  const auto at = arg.find('@');
  const std::string values = arg.substr(0, at);
  const std::string target = at == std::string::npos ? std::string() : arg.substr(at + 1);
  const auto need_target = [&] {
    if (target.empty()) fail("missing @NODE or @chN");
  };

  if (kind == "bearing-tc") {
    fx.bearing_temp_coeff_per_k = number(arg, {}, "coefficient (1/K)", fail);
    if (std::fabs(fx.bearing_temp_coeff_per_k) > 0.2) fail("|K| must be <= 0.2 per kelvin");
  } else if (kind == "run-in") {
    const auto slash = arg.find('/');
    if (slash == std::string::npos) fail("expected run-in:W/TAU, e.g. run-in:6W/20m");
    fx.runin_w_per_krpm = number(arg.substr(0, slash), {"W", "w"}, "heat (W per 1000 rpm)", fail);
    fx.runin_tau_s = duration(arg.substr(slash + 1), "time constant", fail);
    if (fx.runin_w_per_krpm < 0.0 || fx.runin_w_per_krpm > 100.0 || fx.runin_tau_s <= 0.0)
      fail("need 0..100 W per 1000 rpm and TAU > 0");
  } else if (kind == "transient" || kind == "transient-gain" || kind == "transient-start" || kind == "transient-gain-start") {
    need_target();
    HeatTransient t;
    t.multiplicative = kind == "transient-gain" || kind == "transient-gain-start";
    t.starts_only = kind == "transient-start" || kind == "transient-gain-start";
    const auto [amp, tau] = pair_of(values, kind + ":" + (t.multiplicative ? "A/TAU" : "W/TAU") + "@NODES", fail);
    if (t.multiplicative) {
      t.amplitude = number(amp, {"%"}, "gain (fraction)", fail);
      check_range(t.amplitude, -0.9, 5.0, "gain", fail);
    } else {
      const char* what = t.starts_only ? "heat (W per start)" : "heat (W per 1000 rpm)";
      t.amplitude = number(amp, {"W", "w"}, what, fail);
      check_range(t.amplitude, 0.0, 100.0, what, fail);
    }
    t.tau_s = duration(tau, "time constant", fail);
    if (!(t.tau_s > 0.0)) fail("time constant must be > 0");
    t.nodes = node_list(target, fail);
    fx.transients.push_back(t);
  } else if (kind == "temp-heat") {
    need_target();
    TemperatureHeat h;
    h.coeff_per_k = number(values, {"/K"}, "coefficient (1/K)", fail);
    check_range(h.coeff_per_k, -0.2, 0.2, "coefficient (1/K)", fail);
    h.nodes = node_list(target, fail);
    fx.temperature_heat.push_back(h);
  } else if (kind == "coupled-heat") {
    need_target();
    CoupledHeat c;
    c.w_per_k = number(values, {"W/K"}, "coupling (W/K)", fail);
    check_range(c.w_per_k, -20.0, 20.0, "coupling (W/K)", fail);
    const auto [where, e] = with_exponent(target, fail);
    c.speed_exponent = e;
    const auto [node, diff] = pair_of(where, "coupled-heat:G@NODE/HOT-COLD", fail);
    c.node = one_node(node, fail);
    const auto dash = diff.find('-');
    if (dash == std::string::npos) fail("expected the difference as HOT-COLD, e.g. shaft-housing");
    c.hot = one_node(diff.substr(0, dash), fail);
    c.cold = one_node(diff.substr(dash + 1), fail);
    if (c.hot == c.cold) fail("HOT and COLD must be two different nodes");
    fx.coupled_heat.push_back(c);
  } else if (kind == "speed-heat") {
    need_target();
    SpeedHeat s;
    s.w_at_ref = number(values, {"W", "w"}, "heat (W at the reference speed)", fail);
    check_range(s.w_at_ref, -100.0, 500.0, "heat (W)", fail);
    const auto [node, e] = with_exponent(target, fail);
    s.node = one_node(node, fail);
    s.speed_exponent = e;
    fx.speed_heat.push_back(s);
  } else if (kind == "sensor-lag") {
    need_target();
    SensorLag l;
    l.tau_s = duration(values, "time constant", fail);
    if (!(l.tau_s > 0.0) || l.tau_s > 86400.0) fail("time constant must be within (0, 24 h]");
    l.channel = channel(target, fail);
    fx.sensor_lag.push_back(l);
  } else if (kind == "sensor-drift") {
    need_target();
    SensorDrift d;
    d.k_per_h = number(values, {"K/h"}, "drift (K/h)", fail);
    check_range(d.k_per_h, -1.0, 1.0, "drift (K/h)", fail);
    d.channel = channel(target, fail);
    fx.sensor_drift.push_back(d);
  } else if (kind == "ambient-lag") {
    fx.ambient_lag_tau_s = duration(arg, "time constant", fail);
    if (!(fx.ambient_lag_tau_s > 0.0) || fx.ambient_lag_tau_s > 86400.0) fail("time constant must be within (0, 24 h]");
  } else if (kind == "coolant" || kind == "event") {
    need_target();
    const auto eq = target.find('=');
    if (eq == std::string::npos)
      fail(kind == "coolant" ? "expected coolant:G@NODE=PROFILE, e.g. coolant:0.8@housing=18,30m@19"
                             : "expected event:G@NODES=START-END,..., e.g. event:0.6@housing=2h-2.2h");
    const double g = number(values, {"W/K"}, "conductance (W/K)", fail);
    check_range(g, 0.0, 50.0, "conductance (W/K)", fail);
    const std::string nodes = target.substr(0, eq), rest = target.substr(eq + 1);
    if (kind == "coolant") {
      BoundaryColumn b;
      b.w_per_k = g;
      b.node = one_node(nodes, fail);
      try {
        b.temperature = AmbientProfile::parse(rest);
      } catch (const std::invalid_argument& e) {
        fail(std::string("coolant profile: ") + e.what());
      }
      for (const auto& o : fx.boundaries)
        if (o.column == b.column) fail("only one coolant boundary (column " + b.column + ") per plant");
      fx.boundaries.push_back(b);
    } else {
      EventConductance e;
      e.w_per_k = g;
      e.nodes = node_list(nodes, fail);
      for (const auto& item : split(rest, ',')) {
        const auto dash = item.find('-');
        if (item.empty() || dash == std::string::npos) fail("event interval '" + item + "' must be START-END");
        const double a = duration(item.substr(0, dash), "event start", fail);
        const double b = duration(item.substr(dash + 1), "event end", fail);
        if (!(b > a)) fail("event interval '" + item + "': end must be after start");
        e.on_s.emplace_back(a, b);
      }
      for (const auto& o : fx.events)
        if (o.column == e.column) fail("only one event column (" + e.column + ") per plant");
      fx.events.push_back(e);
    }
  } else if (kind == "latent") {
    need_target();
    LatentMass m;
    const auto [c, g] = pair_of(values, "latent:C/G@NODE[/GA]", fail);
    m.c_j_per_k = number(c, {}, "capacity (J/K)", fail);
    m.g_w_per_k = number(g, {}, "conductance (W/K)", fail);
    check_range(m.c_j_per_k, 1.0, 1e6, "capacity (J/K)", fail);
    check_range(m.g_w_per_k, 1e-3, 1e3, "conductance (W/K)", fail);
    const auto slash = target.find('/');
    m.node = one_node(target.substr(0, slash), fail);
    if (slash != std::string::npos) {
      m.g_ambient_w_per_k = number(target.substr(slash + 1), {}, "conductance to ambient (W/K)", fail);
      check_range(m.g_ambient_w_per_k, 0.0, 1e3, "conductance to ambient (W/K)", fail);
    }
    fx.latent.push_back(m);
  } else {
    fail("unknown kind '" + kind +
         "' (bearing-tc, run-in, transient, transient-gain, transient-start, transient-gain-start, temp-heat, coupled-heat, speed-heat, sensor-lag, "
         "sensor-drift, ambient-lag, coolant, event, latent)");
  }
  fx.specs.push_back(spec);
}

}  // namespace btsm::sim
