// Fitted-model JSON reader and the checks every loaded model passes.
#include "model_file.hpp"

#include "host/io/output_file.hpp"

#include "host/io/json_input.hpp"
#include "host/io/utf8_text.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <vector>

namespace btsm::thermal {
namespace {

std::string parameter_list(const Network& net) {
  std::string out;
  for (const auto& p : net.params) out += (out.empty() ? "" : ", ") + p.name;
  return out.size() > 300 ? out.substr(0, 300) + "..." : out;  // names are checked for control characters
}

std::string value_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// A fit that stops at a bound of a log-scaled parameter returns exp(log(bound)), an ulp or so
// beyond it: that is the bound, not a value outside it.
double bound_slack(double bound) { return 1e-9 * std::abs(bound); }

// The eigenvalues of C^-1 G resolve time constants about 1e12 apart at most (double precision:
// the slow ones are lost in the rounding of the fast ones), so stability is decided within that.
constexpr double kResolvableTimeConstantRatio = 1e12;
constexpr const char* kSpreadHead = "time constants too far apart to simulate at ";

// Node i's own time constant C_i / (sum of its conductances), +inf when nothing conducts from it.
double node_time_constant_s(const NodeMatrices& m, int i) {
  return m.G(i, i) > 0 ? m.capacitance[i] / m.G(i, i) : std::numeric_limits<double>::infinity();
}

// "" when the node time constants lie within kResolvableTimeConstantRatio of each other, else
// the two extremes named. A capacitance of 1e300 J/K (or 1e-300) made the poles unresolvable
// and was called "not stable ... heat growing faster than it flows away" of a network that is
// stable, only absurd.
std::string time_constant_spread(const Network& net, const Eigen::VectorXd& params, const NodeMatrices& m, double speed_rpm) {
  int fast = 0, slow = 0;
  for (int i = 0; i < net.node_count(); ++i) {
    if (!(m.G(i, i) > 0)) return "";  // nothing conducts from it: not a spread, a cut-off node
    if (node_time_constant_s(m, i) < node_time_constant_s(m, fast)) fast = i;
    if (node_time_constant_s(m, i) > node_time_constant_s(m, slow)) slow = i;
  }
  const double t_fast = node_time_constant_s(m, fast), t_slow = node_time_constant_s(m, slow);
  if (std::isfinite(t_slow) && t_fast > 0 && t_slow <= kResolvableTimeConstantRatio * t_fast) return "";
  const auto node = [&](int i) {
    const Node& n = net.nodes[static_cast<std::size_t>(i)];
    const Parameter& c = net.params[static_cast<std::size_t>(n.capacitance_param)];
    return "node '" + n.name + "' " + value_text(node_time_constant_s(m, i)) + " s (" + c.name + " = " +
           value_text(params[n.capacitance_param]) + " J/K over " + value_text(m.G(i, i)) + " W/K of links)";
  };
  return kSpreadHead + value_text(speed_rpm) + " rpm: " + node(slow) + ", " + node(fast) +
         ", more than 1e12 apart (a capacitance or a conductance far outside its physical range)";
}

// "" when the poles of A = -C^-1 G lie in the left half plane at `speed_rpm`, else why not. With a
// symmetric G (a passive network) they do exactly when every node has a path of positive
// conductances to ambient or a boundary; a source driven by a temperature difference makes G
// non-symmetric and may also push a pole across, hence the general eigenvalues. Checked with every
// declared event present (a link an event switches on counts), so a network is refused only when
// no event state can make it stable.
std::string instability(const Network& net, const Eigen::VectorXd& params, double speed_rpm) {
  const NodeMatrices m = assemble(net, params, speed_rpm, ~0u);
  const std::string unstable = std::string("not stable in ") + mode_name(net.mode_at(speed_rpm)) + " mode at " +
                               value_text(speed_rpm) +
                               " rpm (a node without a path of positive conductances to ambient, or heat that grows with "
                               "temperature faster than it flows away)";
  const Eigen::MatrixXd CiG = m.capacitance.cwiseInverse().asDiagonal() * m.G;
  if (!CiG.allFinite()) {
    const std::string spread = time_constant_spread(net, params, m, speed_rpm);
    return spread.empty() ? unstable : spread;
  }
  const Eigen::EigenSolver<Eigen::MatrixXd> es(CiG, false);
  if (es.info() != Eigen::Success) return unstable;
  const Eigen::VectorXcd ev = es.eigenvalues();
  const double resolution = std::max(ev.cwiseAbs().maxCoeff(), 1e-300) / kResolvableTimeConstantRatio;
  const double slowest = ev.real().minCoeff();
  if (slowest > resolution) return "";
  // A pole clearly in the right half plane is instability whatever the spread; one within the
  // rounding of the fastest pole is either a cut-off node or time constants too far apart.
  if (slowest >= -resolution)
    if (std::string spread = time_constant_spread(net, params, m, speed_rpm); !spread.empty()) return spread;
  return unstable;
}

// Edits between a and b (insert, delete, replace, swap of neighbours): "paramters" is 1 from
// "parameters".
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t k = 0; k <= b.size(); ++k) d[0][k] = k;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t k = 1; k <= b.size(); ++k) {
      d[i][k] = std::min({d[i - 1][k] + 1, d[i][k - 1] + 1, d[i - 1][k - 1] + (a[i - 1] == b[k - 1] ? 0 : 1)});
      if (i > 1 && k > 1 && a[i - 1] == b[k - 2] && a[i - 2] == b[k - 1]) d[i][k] = std::min(d[i][k], d[i - 2][k - 2] + 1);
    }
  return d[a.size()][b.size()];
}

// A top-level key a fitted model does not have: a misspelt "paramters" was ignored, so the values
// meant were not the ones read (or a required key was reported missing without a word on the typo).
void refuse_unknown_top_level_keys(const nlohmann::json& j, const std::string& src) {
  std::string known;
  for (const char* k : kFittedModelKeys) known += (known.empty() ? "" : ", ") + std::string(k);
  for (const auto& [key, value] : j.items()) {
    if (std::find(std::begin(kFittedModelKeys), std::end(kFittedModelKeys), key) != std::end(kFittedModelKeys)) continue;
    std::string nearest;
    std::size_t best = std::numeric_limits<std::size_t>::max();
    for (const char* k : kFittedModelKeys)
      if (const std::size_t d = edit_distance(key.size() > 64 ? key.substr(0, 64) : key, k); d < best) best = d, nearest = k;
    const bool close = best <= std::max<std::size_t>(1, nearest.size() / 4);
    throw std::invalid_argument(src + ": unknown top-level key " + io::printable(io::json_excerpt(key)) +
                                (close ? " (did you mean '" + nearest + "'?)" : "") + "; a fitted model has: " + known);
  }
}

}  // namespace

std::string model_problems(const Network& net, const Eigen::VectorXd& params) {
  std::string out;
  auto add = [&](const std::string& s) { out += (out.empty() ? "" : "; ") + s; };
  if (params.size() != net.param_count()) return "expected " + std::to_string(net.param_count()) + " parameter values";
  bool all_finite = true;
  for (int i = 0; i < net.param_count(); ++i) {
    const Parameter& p = net.params[static_cast<std::size_t>(i)];
    const double v = params[i];
    if (!std::isfinite(v)) {
      add("'" + p.name + "' is not finite");
      all_finite = false;
    } else if (v < p.min - bound_slack(p.min) || v > p.max + bound_slack(p.max)) {
      add("'" + p.name + "' = " + value_text(v) + " " + p.unit + " is outside the network's bounds [" + value_text(p.min) +
          ", " + value_text(p.max) + "]");
    }
  }
  if (!all_finite || !out.empty()) return out;
  for (const Node& n : net.nodes)
    if (!(params[n.capacitance_param] > 0)) add("node '" + n.name + "' has a capacitance <= 0");
  if (!out.empty()) return out;
  const double operating = net.mode_at(net.speed_ref_rpm) == Mode::Operating ? net.speed_ref_rpm : 2 * net.operating_above_rpm;
  bool spread_told = false;  // time constants too far apart: once, not again for the other mode
  for (const double s : {0.0, operating}) {
    const std::string why = instability(net, params, s);
    if (why.empty() || (spread_told && why.rfind(kSpreadHead, 0) == 0)) continue;
    spread_told = spread_told || why.rfind(kSpreadHead, 0) == 0;
    add(why);
  }
  if (!out.empty()) return out;
  for (const double s : {0.0, operating})
    if (const std::string why = steady_rise_problem(net, params, s); !why.empty()) return why;
  return out;
}

std::string instability_at(const Network& net, const Eigen::VectorXd& params, double speed_rpm) {
  return instability(net, params, speed_rpm);
}

std::string steady_rise_problem(const Network& net, const Eigen::VectorXd& params, double speed_rpm) {
  const NodeMatrices m = assemble(net, params, speed_rpm, ~0u);
  const Eigen::VectorXd rise = m.G.fullPivLu().solve(m.heat_w);
  Eigen::Index node = 0;
  const double largest = rise.cwiseAbs().maxCoeff(&node);
  if (std::isfinite(largest) && largest <= kMaxSteadyRiseK) return "";
  Eigen::Index source = 0;
  const double heat = net.sources.empty() ? 0.0 : m.source_w.cwiseAbs().maxCoeff(&source);
  std::string out = "at " + value_text(speed_rpm) + " rpm its heat would settle node '" + net.nodes[static_cast<std::size_t>(node)].name +
                    "' " + value_text(std::abs(rise[node])) + " K " + (rise[node] < 0 ? "below" : "above") + " ambient, more than the " +
                    value_text(kMaxSteadyRiseK) +
                    " K a recording can hold (the network is stable there: a heat source or a resistance is far outside its physical "
                    "range, or the speed far beyond the ones the model was made for";
  if (heat > 0)  // as reduce names it (reduce.cpp, check_steady_rise)
    out += "; its largest heat source is '" + net.sources[static_cast<std::size_t>(source)].name + "' = " + value_text(m.source_w[source]) + " W";
  return out + ")";
}

std::vector<FittedChannel> fitted_channels(const nlohmann::json& channel_map) {
  std::vector<FittedChannel> out;
  if (!channel_map.is_array()) return out;
  auto text = [](const nlohmann::json& e, const char* key) {
    return e.contains(key) && e.at(key).is_string() ? e.at(key).get<std::string>() : std::string();
  };
  for (const auto& e : channel_map)
    if (e.is_object() && !text(e, "column").empty()) out.push_back({text(e, "column"), text(e, "module_role"), text(e, "node")});
  return out;
}

FittedModel model_from_json(const nlohmann::json& j, const std::string& src) {
  // The other JSON files the tool writes, given where a fit result belongs, are named for what they
  // are: "needs 'network'" alone sends a user looking for a field a reduced model never has.
  if (j.is_object() && j.contains("format") && !j.at("format").is_string())
    throw std::invalid_argument(src + ": \"format\" is " + io::json_excerpt(j.at("format")) + ", not the string '" +
                                kFittedModelFormat + "' a fitted model carries");
  if (j.is_object() && j.contains("format") && j.at("format").is_string()) {
    const std::string format = j.at("format").get<std::string>();
    if (format.rfind("btsm-reduced-model", 0) == 0)
      throw std::invalid_argument(src + ": a reduced model ('" + format +
                                  "', from btsm reduce); this command takes the fitted model from btsm fit --out");
    if (format != kFittedModelFormat)
      throw std::invalid_argument(src + ": format '" + format + "' is not a fitted model ('" + kFittedModelFormat + "')");
  }
  if (!j.is_object() || !j.contains("network"))
    throw std::invalid_argument(src + ": not a btsm model (needs 'network' and 'parameters')");
  // (after 'network': a network JSON given as a model is named by the line above, not by its keys)
  refuse_unknown_top_level_keys(j, src);
  if (!j.contains("parameters")) throw std::invalid_argument(src + ": not a btsm model (needs 'network' and 'parameters')");
  FittedModel m;
  m.json = j;
  m.network = network_from_json(j.at("network"), src + " (network)");
  if (j.contains("channel_map")) m.channel_map = fitted_channels(j.at("channel_map"));
  m.params.resize(m.network.param_count());
  m.sigma = Eigen::VectorXd::Constant(m.network.param_count(), std::numeric_limits<double>::quiet_NaN());
  const auto& pv = j.at("parameters");
  if (!pv.is_object()) throw std::invalid_argument(src + ": \"parameters\" must be an object of name: value");
  // A value for no parameter of the network is a typo or a model edited for another network: the
  // parameter meant keeps its old value while the file looks changed.
  for (const auto& [name, value] : pv.items())
    if (m.network.param_index(name) < 0)
      throw std::invalid_argument(src + ": parameters: " + io::json_excerpt(name) + " is no parameter of the network (its parameters: " +
                                  parameter_list(m.network) + ")");
  for (int i = 0; i < m.network.param_count(); ++i) {
    const std::string& name = m.network.params[static_cast<std::size_t>(i)].name;
    if (!pv.contains(name) || !pv.at(name).is_number())
      throw std::invalid_argument(src + ": parameters: " +
                                  (pv.contains(name) ? "'" + name + "' is " + io::json_excerpt(pv.at(name)) + ", expected a number"
                                                     : "missing value for '" + name + "'"));
    m.params[i] = pv.at(name).get<double>();
    if (!std::isfinite(m.params[i])) throw std::invalid_argument(src + ": parameters: '" + name + "' is not finite");
    if (j.contains("sigma") && j.at("sigma").is_object() && j.at("sigma").contains(name) && j.at("sigma").at(name).is_number())
      m.sigma[i] = j.at("sigma").at(name).get<double>();
  }
  const std::string problems = model_problems(m.network, m.params);
  if (!problems.empty()) throw std::invalid_argument(src + ": not a usable model: " + problems);
  return m;
}

FittedModel load_model(const std::string& path) {
  return model_from_json(io::read_json_file(path, kMaxModelBytes, "model JSON"), path);
}

std::string json_file_text(const nlohmann::json& j) { return j.dump(2) + "\n"; }

void save_json(const std::string& path, const nlohmann::json& j) { io::write_output_file(path, json_file_text(j), "JSON"); }

}  // namespace btsm::thermal
