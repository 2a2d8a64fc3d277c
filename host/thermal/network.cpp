// Network description: JSON codec, validation, presets and assembly of the node matrices.
#include "network.hpp"

#include "spindle4_preset.hpp"  // generated: kSpindle4Json (presets/spindle4.json)

#include "host/io/input_error.hpp"
#include "host/io/json_input.hpp"
#include "host/io/utf8_text.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <tuple>
#include <utility>

namespace btsm::thermal {
namespace {

using nlohmann::json;

[[noreturn]] void bad(const std::string& src, const std::string& where, const std::string& what) {
  throw std::invalid_argument(src + ": " + where + ": " + what);
}

// An absent field takes its default; one given as null is refused. null was read as absent, so
// "min": null silently became 1e-9 and "nominal": null no value: a null is a value left out by a
// script or an edit, never a request for the default.
double get_number(const json& j, const char* key, double def, const std::string& src, const std::string& where) {
  if (!j.contains(key)) return def;
  const json& v = j.at(key);
  if (v.is_null()) bad(src, where, std::string("field '") + key + "' is null, expected a number (leave the field out for its default)");
  if (!v.is_number()) bad(src, where, std::string("field '") + key + "' must be a number, found " + io::json_excerpt(v));
  const double d = v.get<double>();
  if (!std::isfinite(d)) bad(src, where, std::string("field '") + key + "' is not finite");
  return d;
}

std::string get_string(const json& j, const char* key, const std::string& src, const std::string& where) {
  if (!j.contains(key)) bad(src, where, std::string("missing field '") + key + "'");
  if (!j.at(key).is_string()) bad(src, where, std::string("field '") + key + "' must be a string, found " + io::json_excerpt(j.at(key)));
  return j.at(key).get<std::string>();
}

void check_keys(const json& j, std::initializer_list<const char*> allowed, const std::string& src, const std::string& where) {
  if (!j.is_object()) bad(src, where, "must be a JSON object, found " + io::json_excerpt(j));
  for (auto it = j.begin(); it != j.end(); ++it) {
    bool ok = false;
    for (const char* a : allowed) ok = ok || it.key() == a;
    if (!ok) bad(src, where, "unknown field '" + it.key() + "'");
  }
}

// An array of at most `max` entries (the reader's size limits, see kMaxNetworkNodes ...).
void check_count(const json& arr, std::size_t max, const std::string& src, const std::string& where) {
  if (arr.size() > max) bad(src, where, std::to_string(arr.size()) + " entries, at most " + std::to_string(max) + " are supported");
}

// "two nodes are named 'heater' (nodes[0] and nodes[2]) ...": both entries by their index in the
// JSON array, which is also their index in the Network's vectors (they keep the file's order).
std::string two_entries_named(const char* array, std::size_t first, std::size_t second, const std::string& what,
                              const std::string& name) {
  return "two " + what + "s are named '" + io::printable(name) + "' (" + array + "[" + std::to_string(first) + "] and " + array +
         "[" + std::to_string(second) + "]): a " + what + " name must be unique, rename one of them";
}

// The first pair of entries of `items` with the same name(item), as two_entries_named() says it;
// "" when every name is unique.
template <typename T, typename Name>
std::string duplicate_name_problem(const std::vector<T>& items, Name name, const char* array, const std::string& what) {
  for (std::size_t i = 0; i < items.size(); ++i)
    for (std::size_t k = 0; k < i; ++k)
      if (name(items[k]) == name(items[i])) return two_entries_named(array, k, i, what, name(items[i]));
  return "";
}

// Why `name` cannot name a node, "" when it can: 'ambient' and the declared boundary columns are
// link ends of their own (a link "between" [n, "ambient"] means the room), so a node of that name
// could never be reached by a link.
std::string reserved_node_name_problem(const Network& net, const std::string& name) {
  if (name == "ambient")
    return "'ambient' is reserved: a link to \"ambient\" means the recorded room temperature (ambient_c), not a node; "
           "name the node otherwise";
  for (const auto& b : net.boundaries)
    if (b == name)
      return "'" + io::printable(name) + "' is a declared boundary column: a link to it means the recorded column; name the node otherwise";
  for (const auto& e : net.events)
    if (e == name) return "'" + io::printable(name) + "' is a declared event column; name the node otherwise";
  return "";
}

std::vector<Term> parse_terms(const Network& net, const json& arr, bool link, const std::string& src, const std::string& where) {
  std::vector<Term> out;
  if (!arr.is_array()) bad(src, where, "must be an array of terms");
  check_count(arr, kMaxNetworkTermsPerList, src, where);
  for (std::size_t i = 0; i < arr.size(); ++i) {
    const std::string w = where + "[" + std::to_string(i) + "]";
    const json& t = arr[i];
    check_keys(t, {"resistance", "conductance", "power", "speed_exponent", "event", "driven_by"}, src, w);
    Term term;
    int kinds = 0;
    std::string pname;
    if (t.contains("resistance")) { term.kind = TermKind::Resistance; pname = get_string(t, "resistance", src, w); ++kinds; }
    if (t.contains("conductance")) { term.kind = TermKind::Conductance; pname = get_string(t, "conductance", src, w); ++kinds; }
    if (t.contains("power")) { term.kind = TermKind::Power; pname = get_string(t, "power", src, w); ++kinds; }
    if (kinds != 1) bad(src, w, link ? "a link term needs exactly one of 'resistance' or 'conductance'" : "a source term needs 'power'");
    if (link && term.kind == TermKind::Power) bad(src, w, "'power' terms belong to sources, not links");
    if (!link && term.kind != TermKind::Power) bad(src, w, "source terms use 'power'");
    term.param = net.param_index(pname);
    if (term.param < 0) bad(src, w, "unknown parameter '" + pname + "' (declare it in 'parameters')");
    term.speed_exponent = get_number(t, "speed_exponent", 0.0, src, w);
    if (std::abs(term.speed_exponent) > kMaxSpeedExponent)
      bad(src, w, "speed_exponent " + std::to_string(term.speed_exponent) + " is outside +-" +
                      std::to_string(static_cast<int>(kMaxSpeedExponent)));
    if (t.contains("event")) {
      const std::string ev = get_string(t, "event", src, w);
      for (std::size_t k = 0; k < net.events.size(); ++k)
        if (net.events[k] == ev) term.event = static_cast<int>(k);
      if (term.event < 0) bad(src, w, "unknown event column '" + ev + "' (declare it in 'events')");
    }
    if (t.contains("driven_by")) {
      if (link) bad(src, w, "'driven_by' belongs to source terms");
      const json& d = t.at("driven_by");
      if (!d.is_array() || d.size() != 2 || !d[0].is_string() || !d[1].is_string())
        bad(src, w, "'driven_by' must be [\"hot node or ambient\", \"cold node or ambient\"]");
      auto end = [&](const std::string& name) {
        if (name == "ambient") return kAmbient;
        const int i = net.node_index(name);
        if (i < 0) bad(src, w, "'driven_by': unknown node '" + name + "'");
        return i;
      };
      term.driven = true;
      term.hot = end(d[0].get<std::string>());
      term.cold = end(d[1].get<std::string>());
    }
    out.push_back(term);
  }
  return out;
}

json terms_to_json(const Network& net, const std::vector<Term>& terms) {
  json arr = json::array();
  for (const auto& t : terms) {
    json j;
    const char* k = t.kind == TermKind::Resistance ? "resistance" : t.kind == TermKind::Conductance ? "conductance" : "power";
    j[k] = net.params[static_cast<std::size_t>(t.param)].name;
    if (t.speed_exponent != 0.0) j["speed_exponent"] = t.speed_exponent;
    if (t.event >= 0) j["event"] = net.events[static_cast<std::size_t>(t.event)];
    if (t.driven) {
      auto end = [&](int i) { return i == kAmbient ? std::string("ambient") : net.nodes[static_cast<std::size_t>(i)].name; };
      j["driven_by"] = {end(t.hot), end(t.cold)};
    }
    arr.push_back(j);
  }
  return arr;
}

// Adds the "both" terms to operating and cooling lists.
void read_mode_terms(const Network& net, const json& j, bool link, std::vector<Term>& op, std::vector<Term>& cool,
                     const std::string& src, const std::string& where) {
  if (j.contains("both")) {
    auto both = parse_terms(net, j.at("both"), link, src, where + ".both");
    op.insert(op.end(), both.begin(), both.end());
    cool.insert(cool.end(), both.begin(), both.end());
  }
  if (j.contains("operating")) {
    auto t = parse_terms(net, j.at("operating"), link, src, where + ".operating");
    op.insert(op.end(), t.begin(), t.end());
  }
  if (j.contains("cooling")) {
    auto t = parse_terms(net, j.at("cooling"), link, src, where + ".cooling");
    cool.insert(cool.end(), t.begin(), t.end());
  }
}

double term_value(const Term& t, const Eigen::VectorXd& p, double s) {
  const double v = p[t.param];
  return t.speed_exponent == 0.0 ? v : v * std::pow(s, t.speed_exponent);
}

// A link conducts in `mode` when one of its terms does: any term while running; at standstill
// (cooling, 0 rpm) only a term without a speed law, since (w/w0)^e is 0 or infinite at w = 0.
// An event-switched term counts, as in the stability check of a model (model_file.cpp): the
// network is refused only when no event state links the node.
bool conducts(const Link& l, Mode mode) {
  if (mode == Mode::Operating) return !l.operating.empty();
  return std::any_of(l.cooling.begin(), l.cooling.end(), [](const Term& t) { return t.speed_exponent == 0.0; });
}

// Per node: whether a chain of links that conduct in `mode` joins it to the ambient or a boundary.
std::vector<bool> reaches_ambient(const Network& net, Mode mode) {
  std::vector<bool> reached(net.nodes.size(), false);
  for (bool grew = true; grew;) {
    grew = false;
    for (const Link& l : net.links) {
      if (!conducts(l, mode)) continue;
      const bool a = reached[static_cast<std::size_t>(l.a)];
      const bool b = l.b < 0 || reached[static_cast<std::size_t>(l.b)];  // ambient or a boundary
      if (a == b) continue;
      reached[static_cast<std::size_t>(a ? l.b : l.a)] = true;
      grew = true;
    }
  }
  return reached;
}

// Why node `i` is cut off at standstill or while running ("" when it is not).
std::string cut_off_reason(const Network& net, int i, const std::vector<bool>& at_standstill, const std::vector<bool>& running) {
  const auto k = static_cast<std::size_t>(i);
  const std::string node = "node '" + net.nodes[k].name + "'";
  const bool linked = std::any_of(net.links.begin(), net.links.end(), [&](const Link& l) { return l.a == i || l.b == i; });
  if (!linked) return node + " has no link at all";
  if (!at_standstill[k] && running[k])
    return node + " reaches the ambient only while running (through operating terms or cooling terms with a speed_exponent)";
  if (!at_standstill[k]) return node + " has no path of links to the ambient or a boundary";
  if (!running[k]) return node + " reaches the ambient only at standstill (its path has no operating terms)";
  return "";
}

// The network's structure, before any fit: a node that no path of conducting links joins to the
// ambient (or a declared boundary) heats or cools for ever, so every fit of it ends "not stable in
// cooling mode" without naming the node, or in a start value for a link between unmeasured nodes.
void check_paths_to_ambient(const Network& net) {
  const std::vector<bool> at_standstill = reaches_ambient(net, Mode::Cooling), running = reaches_ambient(net, Mode::Operating);
  std::string reasons;
  int listed = 0, more = 0;
  for (int i = 0; i < net.node_count(); ++i) {
    const std::string why = cut_off_reason(net, i, at_standstill, running);
    if (why.empty()) continue;
    if (listed++ < 8) reasons += (reasons.empty() ? "" : "; ") + why;
    else ++more;
  }
  if (reasons.empty()) return;
  if (more > 0) reasons += "; and " + std::to_string(more) + " more node(s)";
  bad("network '" + net.name + "'", "links",
      reasons + ": every node needs a path to 'ambient' or a boundary through links that conduct both at standstill (a "
                "'both' or 'cooling' term without speed_exponent) and while running, or its temperature never settles");
}

// What a parameter stands for where it is used, by its physical unit: a node's capacitance is
// J/K, a link's resistance K/W, a conductance W/K, a source's heat W, a heat driven by a
// temperature difference W/K, a probe's drift K/h. One parameter used for two of different units
// (a capacitance naming the resistance 'R_box') is a slip of the pen in the file; it used to
// surface only in the fit as "parameter 'R_box' enters non-linearly".
struct ParameterUse {
  const char* role;  // "the capacitance of", "a resistance in", ...
  const char* unit;
  std::string owner;  // "node 'air'", "link 'R_box'", ...
};

std::vector<std::vector<ParameterUse>> parameter_uses(const Network& net) {
  std::vector<std::vector<ParameterUse>> uses(net.params.size());
  const auto use = [&](int p, ParameterUse u) {
    if (p >= 0 && p < net.param_count()) uses[static_cast<std::size_t>(p)].push_back(std::move(u));
  };
  for (const auto& n : net.nodes) use(n.capacitance_param, {"the capacitance of", "J/K", "node '" + n.name + "'"});
  const auto terms = [&](const std::vector<Term>& ts, const std::string& owner) {
    for (const Term& t : ts) {
      if (t.kind == TermKind::Resistance) use(t.param, {"a resistance in", "K/W", owner});
      else if (t.kind == TermKind::Conductance) use(t.param, {"a conductance in", "W/K", owner});
      else if (t.driven) use(t.param, {"a heat per kelvin (driven_by) in", "W/K", owner});
      else use(t.param, {"a heat in", "W", owner});
    }
  };
  for (const auto& l : net.links)
    for (const auto* ts : {&l.operating, &l.cooling}) terms(*ts, "link '" + l.name + "'");
  for (const auto& s : net.sources)
    for (const auto* ts : {&s.operating, &s.cooling}) terms(*ts, "source '" + s.name + "'");
  for (const auto& m : net.measurements) use(m.drift_param, {"the drift of", "K/h", "measurement '" + m.column + "'"});
  return uses;
}

void check_parameter_roles(const Network& net, const std::string& src) {
  const auto uses = parameter_uses(net);
  for (std::size_t p = 0; p < uses.size(); ++p)
    for (const ParameterUse& u : uses[p]) {
      const ParameterUse& first = uses[p].front();
      if (std::string_view(u.unit) == first.unit) continue;
      const Parameter& par = net.params[p];
      bad(src, "parameter '" + io::printable(par.name) + "'",
          std::string("used as ") + first.role + " " + io::printable(first.owner) + " (" + first.unit + ") and as " + u.role + " " +
              io::printable(u.owner) + " (" + u.unit + ")" + (par.unit.empty() ? "" : ", declared in " + io::printable(par.unit)) +
              ": one value cannot stand for both; give each its own parameter (a reference to the wrong name?)");
    }
}

}  // namespace

const char* mode_name(Mode m) { return m == Mode::Operating ? "operating" : "cooling"; }

int Network::param_index(const std::string& n) const {
  for (std::size_t i = 0; i < params.size(); ++i)
    if (params[i].name == n) return static_cast<int>(i);
  return -1;
}

int Network::node_index(const std::string& n) const {
  for (std::size_t i = 0; i < nodes.size(); ++i)
    if (nodes[i].name == n) return static_cast<int>(i);
  return -1;
}

bool Network::has_probe(int node) const {
  for (const Measurement& m : measurements)
    if (m.node == node) return true;
  return false;
}

int Network::add_parameter(const Parameter& p) {
  if (param_index(p.name) >= 0) throw std::invalid_argument("network " + name + ": parameter '" + p.name + "' already exists");
  params.push_back(p);
  return static_cast<int>(params.size()) - 1;
}

bool Network::has_driven_terms() const {
  for (const auto& s : sources)
    for (const auto* ts : {&s.operating, &s.cooling})
      for (const auto& t : *ts)
        if (t.driven) return true;
  return false;
}

bool Network::has_drift() const {
  for (const auto& m : measurements)
    if (m.drift_param >= 0) return true;
  return false;
}

std::vector<std::string> Network::param_names() const {
  std::vector<std::string> v;
  for (const auto& p : params) v.push_back(p.name);
  return v;
}

void Network::validate() const {
  if (io::has_control_char(name)) bad("network " + json(name).dump(), "name", "contains a control character");
  const std::string src = "network '" + name + "'";
  {
    // (what, name, also a column or list entry): nodes are named in --nodes, --channels and
    // --column NODE=COLUMN and head heat's CSV columns; the columns are a recording's header
    std::vector<std::tuple<std::string, std::string, bool>> names;
    for (const auto& p : params) names.emplace_back("parameter", p.name, false);
    for (const auto& n : nodes) names.emplace_back("node", n.name, true);
    for (const auto& l : links) names.emplace_back("link", l.name, false);
    for (const auto& s : sources) names.emplace_back("source", s.name, false);
    for (const auto& m : measurements) names.emplace_back("measurement column", m.column, true);
    for (const auto& b : boundaries) names.emplace_back("boundary column", b, true);
    for (const auto& e : events) names.emplace_back("event column", e, true);
    for (const auto& [what, n, listed] : names) {
      if (io::has_control_char(n)) bad(src, what + " " + json(n).dump(), "contains a control character");
      if (const std::string why = io::name_problem(n); listed && !why.empty()) bad(src, what + " " + json(n).dump(), why);
    }
  }
  if (nodes.empty()) bad(src, "nodes", "at least one node is required");
  if (!(speed_ref_rpm > 0)) bad(src, "speed_ref_rpm", "must be > 0");
  if (!(operating_above_rpm >= 0)) bad(src, "operating_above_rpm", "must be >= 0");
  if (!std::isnan(sum_capacitance_J_per_K) && !(sum_capacitance_J_per_K > 0))
    bad(src, "sum_capacitance_J_per_K", "must be > 0");
  for (const auto& p : params) {
    const std::string w = "parameter '" + p.name + "'";
    if (p.name.empty()) bad(src, "parameters", "a parameter has an empty name");
    if (!(p.min < p.max)) bad(src, w, "min must be < max");
    if (p.log_scale && !(p.min > 0)) bad(src, w, "log-scaled parameters need min > 0 (set \"log\": false for ones that may be 0)");
    if (!p.initial_auto && (!std::isfinite(p.initial) || p.initial < p.min || p.initial > p.max))
      bad(src, w, "initial value outside [min, max]");
    if (p.fixed && p.initial_auto && std::isnan(p.nominal)) bad(src, w, "a fixed parameter needs a value ('initial' or 'nominal')");
  }
  auto check_param = [&](int idx, const std::string& w) {
    if (idx < 0 || idx >= param_count()) bad(src, w, "parameter index out of range");
  };
  for (const auto& n : nodes) {
    check_param(n.capacitance_param, "node '" + n.name + "' capacitance");
    if (n.name == "ambient") bad(src, "nodes", "'ambient' is reserved for the boundary");
  }
  {
    // Every named entry once: messages, the fit's report and a model's parameters name them, and
    // a second link 'R12' would read as the first one doubled. (Networks the tool extends itself,
    // the residual loop's effects, refuse a name the network has already: effects.cpp.)
    const auto named = [](const auto& e) -> const std::string& { return e.name; };
    const std::pair<const char*, std::string> problems[] = {
        {"parameters", duplicate_name_problem(params, named, "parameters", "parameter")},
        {"nodes", duplicate_name_problem(nodes, named, "nodes", "node")},
        {"links", duplicate_name_problem(links, named, "links", "link")},
        {"sources", duplicate_name_problem(sources, named, "sources", "source")}};
    for (const auto& [array, why] : problems)
      if (!why.empty()) bad(src, array, why);
  }
  auto check_terms = [&](const std::vector<Term>& ts, const std::string& w, bool cooling) {
    for (const auto& t : ts) {
      check_param(t.param, w);
      if (!std::isfinite(t.speed_exponent)) bad(src, w, "speed_exponent not finite");
      if (cooling && t.speed_exponent != 0.0 && operating_above_rpm == 0.0)
        bad(src, w + " (cooling)", "cooling-mode terms must have speed_exponent 0 (the speed is 0 there)");
      if (t.event < -1 || t.event >= static_cast<int>(events.size())) bad(src, w, "event index out of range");
      if (t.driven) {
        if (t.kind != TermKind::Power) bad(src, w, "only source (power) terms can be driven by a temperature difference");
        for (int e : {t.hot, t.cold})
          if (e != kAmbient && (e < 0 || e >= node_count())) bad(src, w, "'driven_by' end is not a node or ambient");
        if (t.hot == t.cold) bad(src, w, "'driven_by' needs two different ends");
      }
    }
  };
  if (events.size() > static_cast<std::size_t>(kMaxEvents)) bad(src, "events", "at most " + std::to_string(kMaxEvents) + " event columns");
  auto check_input_names = [&](const std::vector<std::string>& names, const char* what) {
    for (std::size_t k = 0; k < names.size(); ++k) {
      if (names[k].empty()) bad(src, what, "empty column name");
      if (names[k] == "ambient" || node_index(names[k]) >= 0) bad(src, what, "'" + names[k] + "' is also a node name or 'ambient'");
      for (std::size_t m = 0; m < k; ++m)
        if (names[m] == names[k]) bad(src, what, "duplicate column '" + names[k] + "'");
    }
  };
  check_input_names(boundaries, "boundaries");
  check_input_names(events, "events");
  for (const auto& b : boundaries)
    for (const auto& e : events)
      if (b == e) bad(src, "events", "'" + e + "' is declared as a boundary too");
  for (const auto& l : links) {
    const std::string w = "link '" + l.name + "'";
    if (l.a < 0 || l.a >= node_count()) bad(src, w, "first end is not a node");
    if (is_boundary_end(l.b)) {
      if (boundary_of_end(l.b) >= static_cast<int>(boundaries.size())) bad(src, w, "second end is not a declared boundary");
    } else if (l.b != kAmbient && (l.b < 0 || l.b >= node_count())) {
      bad(src, w, "second end is not a node, ambient or a boundary");
    }
    if (l.a == l.b) bad(src, w, "a link must join two different nodes");
    if (l.operating.empty() && l.cooling.empty()) bad(src, w, "has no terms");
    check_terms(l.operating, w, false);
    check_terms(l.cooling, w, true);
  }
  for (const auto& s : sources) {
    const std::string w = "source '" + s.name + "'";
    if (s.node < 0 || s.node >= node_count()) bad(src, w, "node out of range");
    check_terms(s.operating, w, false);
    check_terms(s.cooling, w, true);
  }
  for (const auto& m : measurements) {
    if (m.node < 0 || m.node >= node_count()) bad(src, "measurement '" + m.column + "'", "node out of range");
    if (m.drift_param != -1) check_param(m.drift_param, "measurement '" + m.column + "' drift");
    for (const auto& b : boundaries)
      if (m.column == b) bad(src, "measurement '" + m.column + "'", "a declared boundary column is not a node's measurement");
    for (const auto& e : events)
      if (m.column == e) bad(src, "measurement '" + m.column + "'", "a declared event column is not a node's measurement");
  }
  for (std::size_t i = 0; i < measurements.size(); ++i)  // nodes checked above
    for (std::size_t k = 0; k < i; ++k)
      if (measurements[k].column == measurements[i].column)
        bad(src, "measurement '" + measurements[i].column + "'",
            "one column cannot measure two nodes ('" + nodes[static_cast<std::size_t>(measurements[k].node)].name + "' and '" +
                nodes[static_cast<std::size_t>(measurements[i].node)].name + "')");
  check_parameter_roles(*this, src);
}

Network network_from_json(const json& j, const std::string& src) {
  Network net;
  check_keys(j, {"name", "description", "speed_ref_rpm", "operating_above_rpm", "sum_capacitance_J_per_K", "parameters", "nodes",
                 "links", "sources", "measurements", "boundaries", "events"},
             src, "top level");
  for (const char* k : {"boundaries", "events"}) {
    if (!j.contains(k)) continue;
    const json& a = j.at(k);
    if (!a.is_array()) bad(src, k, "must be an array of column names");
    check_count(a, kMaxNetworkNodes, src, k);
    for (std::size_t i = 0; i < a.size(); ++i) {
      if (!a[i].is_string()) bad(src, std::string(k) + "[" + std::to_string(i) + "]", "must be a column name, found " + io::json_excerpt(a[i]));
      (std::string(k) == "boundaries" ? net.boundaries : net.events).push_back(a[i].get<std::string>());
    }
  }
  net.name = j.contains("name") ? get_string(j, "name", src, "top level") : std::string("network");
  net.speed_ref_rpm = get_number(j, "speed_ref_rpm", 5000.0, src, "top level");
  net.operating_above_rpm = get_number(j, "operating_above_rpm", 0.0, src, "top level");
  net.sum_capacitance_J_per_K = get_number(j, "sum_capacitance_J_per_K", std::nan(""), src, "top level");
  for (const char* k : {"parameters", "nodes", "links"})
    if (!j.contains(k) || !j.at(k).is_array()) bad(src, k, "missing or not an array");
  check_count(j.at("parameters"), kMaxNetworkParameters, src, "parameters");
  check_count(j.at("nodes"), kMaxNetworkNodes, src, "nodes");
  check_count(j.at("links"), kMaxNetworkLinks, src, "links");
  const json& ps = j.at("parameters");
  for (std::size_t i = 0; i < ps.size(); ++i) {
    const std::string w = "parameters[" + std::to_string(i) + "]";
    const json& pj = ps[i];
    check_keys(pj, {"name", "unit", "nominal", "initial", "min", "max", "fixed", "log", "description"}, src, w);
    Parameter p;
    p.name = get_string(pj, "name", src, w);
    const std::string wn = "parameter '" + p.name + "'";
    if (const int first = net.param_index(p.name); first >= 0)
      bad(src, "parameters", two_entries_named("parameters", static_cast<std::size_t>(first), i, "parameter", p.name));
    p.unit = pj.contains("unit") ? get_string(pj, "unit", src, wn) : "";
    p.description = pj.contains("description") ? get_string(pj, "description", src, wn) : "";
    p.nominal = get_number(pj, "nominal", std::nan(""), src, wn);
    if (!pj.contains("initial") || (pj.at("initial").is_string() && pj.at("initial") == "auto")) {
      p.initial_auto = true;
    } else if (pj.at("initial").is_number()) {
      p.initial = get_number(pj, "initial", 1.0, src, wn);
      p.initial_auto = false;
    } else {
      bad(src, wn, "field 'initial' must be a number or \"auto\", found " + io::json_excerpt(pj.at("initial")));
    }
    p.min = get_number(pj, "min", 1e-9, src, wn);
    p.max = get_number(pj, "max", 1e9, src, wn);
    if (pj.contains("fixed")) {
      if (!pj.at("fixed").is_boolean()) bad(src, wn, "field 'fixed' must be true or false");
      p.fixed = pj.at("fixed").get<bool>();
    }
    if (pj.contains("log")) {
      if (!pj.at("log").is_boolean()) bad(src, wn, "field 'log' must be true or false");
      p.log_scale = pj.at("log").get<bool>();
    } else {
      p.log_scale = p.min > 0;
    }
    net.params.push_back(p);
  }
  const json& ns = j.at("nodes");
  for (std::size_t i = 0; i < ns.size(); ++i) {
    const std::string w = "nodes[" + std::to_string(i) + "]";
    check_keys(ns[i], {"name", "capacitance"}, src, w);
    Node n;
    n.name = get_string(ns[i], "name", src, w);
    // Checked here, before the links name their ends: a second 'heater' (or a node called
    // 'ambient') surfaced only as "link ...: unknown node 'air'", naming the node left out.
    if (const int first = net.node_index(n.name); first >= 0)
      bad(src, "nodes", two_entries_named("nodes", static_cast<std::size_t>(first), i, "node", n.name));
    if (const std::string why = reserved_node_name_problem(net, n.name); !why.empty()) bad(src, w, why);
    const std::string c = get_string(ns[i], "capacitance", src, "node '" + n.name + "'");
    n.capacitance_param = net.param_index(c);
    if (n.capacitance_param < 0) bad(src, "node '" + n.name + "'", "unknown capacitance parameter '" + c + "'");
    net.nodes.push_back(n);
  }
  auto node_ref = [&](const std::string& name, bool allow_ambient, const std::string& w) {
    if (allow_ambient && name == "ambient") return kAmbient;
    if (allow_ambient)
      for (std::size_t k = 0; k < net.boundaries.size(); ++k)
        if (net.boundaries[k] == name) return boundary_end(static_cast<int>(k));
    const int idx = net.node_index(name);
    if (idx < 0) bad(src, w, "unknown node '" + name + "'");
    return idx;
  };
  const json& ls = j.at("links");
  for (std::size_t i = 0; i < ls.size(); ++i) {
    std::string w = "links[" + std::to_string(i) + "]";
    check_keys(ls[i], {"name", "between", "both", "operating", "cooling"}, src, w);
    Link l;
    l.name = ls[i].contains("name") ? get_string(ls[i], "name", src, w) : w;
    w = "link '" + l.name + "'";
    const json& b = ls[i].contains("between") ? ls[i].at("between") : json();
    if (!b.is_array() || b.size() != 2 || !b[0].is_string() || !b[1].is_string())
      bad(src, w, "'between' must be [\"node\", \"node\" or \"ambient\"]");
    l.a = node_ref(b[0].get<std::string>(), true, w);
    l.b = node_ref(b[1].get<std::string>(), true, w);
    if (l.a < 0) std::swap(l.a, l.b);
    if (l.a < 0) bad(src, w, "a link needs at least one node end (ambient and boundaries are not nodes)");
    read_mode_terms(net, ls[i], true, l.operating, l.cooling, src, w);
    net.links.push_back(l);
  }
  if (j.contains("sources")) {
    const json& ss = j.at("sources");
    if (!ss.is_array()) bad(src, "sources", "must be an array");
    check_count(ss, kMaxNetworkLinks, src, "sources");
    for (std::size_t i = 0; i < ss.size(); ++i) {
      std::string w = "sources[" + std::to_string(i) + "]";
      check_keys(ss[i], {"name", "node", "both", "operating", "cooling"}, src, w);
      Source s;
      s.name = ss[i].contains("name") ? get_string(ss[i], "name", src, w) : w;
      w = "source '" + s.name + "'";
      s.node = node_ref(get_string(ss[i], "node", src, w), false, w);
      read_mode_terms(net, ss[i], false, s.operating, s.cooling, src, w);
      net.sources.push_back(s);
    }
  }
  if (j.contains("measurements")) {
    const json& ms = j.at("measurements");
    if (!ms.is_array()) bad(src, "measurements", "must be an array");
    check_count(ms, kMaxNetworkNodes, src, "measurements");
    for (std::size_t i = 0; i < ms.size(); ++i) {
      const std::string w = "measurements[" + std::to_string(i) + "]";
      check_keys(ms[i], {"column", "node", "drift"}, src, w);
      Measurement m;
      m.column = get_string(ms[i], "column", src, w);
      m.node = node_ref(get_string(ms[i], "node", src, w), false, w);
      if (ms[i].contains("drift")) {
        const std::string d = get_string(ms[i], "drift", src, w);
        m.drift_param = net.param_index(d);
        if (m.drift_param < 0) bad(src, w, "unknown drift parameter '" + d + "'");
      }
      net.measurements.push_back(m);
    }
  }
  try {
    net.validate();
    check_paths_to_ambient(net);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(src + ": " + e.what());
  }
  return net;
}

json network_to_json(const Network& net) {
  json j;
  j["name"] = net.name;
  j["speed_ref_rpm"] = net.speed_ref_rpm;
  j["operating_above_rpm"] = net.operating_above_rpm;
  if (!std::isnan(net.sum_capacitance_J_per_K)) j["sum_capacitance_J_per_K"] = net.sum_capacitance_J_per_K;
  j["parameters"] = json::array();
  for (const auto& p : net.params) {
    json pj{{"name", p.name}, {"unit", p.unit}, {"min", p.min}, {"max", p.max}, {"fixed", p.fixed}, {"log", p.log_scale}};
    if (!std::isnan(p.nominal)) pj["nominal"] = p.nominal;
    if (p.initial_auto) pj["initial"] = "auto"; else pj["initial"] = p.initial;
    if (!p.description.empty()) pj["description"] = p.description;
    j["parameters"].push_back(pj);
  }
  j["nodes"] = json::array();
  for (const auto& n : net.nodes)
    j["nodes"].push_back({{"name", n.name}, {"capacitance", net.params[static_cast<std::size_t>(n.capacitance_param)].name}});
  if (!net.boundaries.empty()) j["boundaries"] = net.boundaries;
  if (!net.events.empty()) j["events"] = net.events;
  auto node_name = [&](int i) {
    if (i == kAmbient) return std::string("ambient");
    if (is_boundary_end(i)) return net.boundaries[static_cast<std::size_t>(boundary_of_end(i))];
    return net.nodes[static_cast<std::size_t>(i)].name;
  };
  j["links"] = json::array();
  for (const auto& l : net.links) {
    json lj{{"name", l.name}, {"between", {node_name(l.a), node_name(l.b)}}};
    if (!l.operating.empty()) lj["operating"] = terms_to_json(net, l.operating);
    if (!l.cooling.empty()) lj["cooling"] = terms_to_json(net, l.cooling);
    j["links"].push_back(lj);
  }
  j["sources"] = json::array();
  for (const auto& s : net.sources) {
    json sj{{"name", s.name}, {"node", node_name(s.node)}};
    if (!s.operating.empty()) sj["operating"] = terms_to_json(net, s.operating);
    if (!s.cooling.empty()) sj["cooling"] = terms_to_json(net, s.cooling);
    j["sources"].push_back(sj);
  }
  j["measurements"] = json::array();
  for (const auto& m : net.measurements) {
    json mj{{"column", m.column}, {"node", node_name(m.node)}};
    if (m.drift_param >= 0) mj["drift"] = net.params[static_cast<std::size_t>(m.drift_param)].name;
    j["measurements"].push_back(mj);
  }
  return j;
}

Network load_network(const std::string& path) {
  return network_from_json(io::read_json_file(path, kMaxNetworkBytes, "network JSON"), path);
}

std::vector<std::string> preset_names() { return {"spindle4"}; }

void remap_measurements(Network& net, const std::vector<std::string>& specs) {
  // Applied as a whole (every named node's old column dropped first), so two probes can swap
  // places: rear_bearing=T3 front_bearing=T1. The last spec for a node counts.
  std::vector<std::pair<int, std::string>> wanted;  // node, column ("" = unmeasured)
  for (const std::string& spec : specs) {
    const auto eq = spec.find('=');
    if (eq == std::string::npos || eq == 0)
      throw std::invalid_argument("--column '" + spec + "': expected NODE=COLUMN, e.g. shaft=T5");
    const std::string node = spec.substr(0, eq), column = spec.substr(eq + 1);
    const int k = net.node_index(node);
    if (k < 0) throw std::invalid_argument("--column '" + spec + "': the network has no node '" + node + "'");
    // A later spec for the same node replaces the earlier one (the recordings' roles, then --column).
    std::erase_if(wanted, [&](const auto& w) { return w.first == k; });
    wanted.emplace_back(k, column);
  }
  for (const auto& w : wanted) std::erase_if(net.measurements, [&](const Measurement& m) { return m.node == w.first; });
  for (std::size_t i = 0; i < wanted.size(); ++i) {
    const auto& [k, column] = wanted[i];
    if (column.empty()) continue;
    const std::string spec = net.nodes[static_cast<std::size_t>(k)].name + "=" + column;
    for (const auto& m : net.measurements)
      if (m.column == column)
        throw std::invalid_argument("--column '" + spec + "': column '" + column + "' already measures node '" +
                                    net.nodes[static_cast<std::size_t>(m.node)].name + "' (to swap two probes, name both)");
    Measurement m;
    m.column = column;
    m.node = k;
    net.measurements.push_back(m);
  }
  if (net.measurements.empty()) throw std::invalid_argument("--column: no node is measured any more");
}

Network preset_network(const std::string& name) {
  if (name == "spindle4") return network_from_json(json::parse(kSpindle4Json), "preset spindle4");
  std::string known;
  for (const auto& n : preset_names()) known += " " + n;
  throw std::invalid_argument("unknown network preset '" + name + "' (known:" + known + ")");
}

Eigen::VectorXd default_parameters(const Network& net) {
  Eigen::VectorXd p(net.param_count());
  for (int i = 0; i < net.param_count(); ++i) {
    const auto& q = net.params[static_cast<std::size_t>(i)];
    p[i] = !std::isnan(q.nominal) ? q.nominal : (!q.initial_auto ? q.initial : std::nan(""));
  }
  return p;
}

NodeMatrices assemble(const Network& net, const Eigen::VectorXd& p, double speed_rpm, unsigned event_mask) {
  const int n = net.node_count();
  const int ns = static_cast<int>(net.sources.size());
  const Mode mode = net.mode_at(speed_rpm);
  const double s = speed_rpm / net.speed_ref_rpm;
  NodeMatrices m;
  m.capacitance.resize(n);
  for (int i = 0; i < n; ++i) m.capacitance[i] = p[net.nodes[static_cast<std::size_t>(i)].capacitance_param];
  m.G = Eigen::MatrixXd::Zero(n, n);
  m.ambient_conductance = Eigen::VectorXd::Zero(n);
  m.boundary_conductance = Eigen::MatrixXd::Zero(n, static_cast<Eigen::Index>(net.boundaries.size()));
  auto present = [&](const Term& t) { return t.event < 0 || ((event_mask >> t.event) & 1u) != 0; };
  for (const auto& l : net.links) {
    double g = 0.0;
    for (const auto& t : mode == Mode::Operating ? l.operating : l.cooling) {
      if (!present(t)) continue;
      const double v = term_value(t, p, s);
      g += t.kind == TermKind::Resistance ? 1.0 / v : v;
    }
    if (g == 0.0) continue;
    m.G(l.a, l.a) += g;
    if (l.b == kAmbient) {
      m.ambient_conductance[l.a] += g;
    } else if (is_boundary_end(l.b)) {
      m.boundary_conductance(l.a, boundary_of_end(l.b)) += g;
    } else {
      m.G(l.b, l.b) += g;
      m.G(l.a, l.b) -= g;
      m.G(l.b, l.a) -= g;
    }
  }
  m.source_to_node = Eigen::MatrixXd::Zero(n, ns);
  m.source_w = Eigen::VectorXd::Zero(ns);
  for (int k = 0; k < ns; ++k) {
    const auto& src = net.sources[static_cast<std::size_t>(k)];
    m.source_to_node(src.node, k) = 1.0;
    double q = 0.0;
    for (const auto& t : mode == Mode::Operating ? src.operating : src.cooling) {
      if (!present(t)) continue;
      if (!t.driven) {
        q += term_value(t, p, s);
        continue;
      }
      // heat g (T_hot - T_cold) at the source's node: -G gains -g at (node, hot), +g at (node, cold)
      const double g = term_value(t, p, s);
      if (t.hot == kAmbient) m.ambient_conductance[src.node] += g;
      else m.G(src.node, t.hot) -= g;
      if (t.cold == kAmbient) m.ambient_conductance[src.node] -= g;
      else m.G(src.node, t.cold) += g;
    }
    m.source_w[k] = q;
  }
  m.heat_w = m.source_to_node * m.source_w;
  return m;
}

}  // namespace btsm::thermal
