// Fitted-model JSON reader and the checks every loaded model passes.
#include "model_file.hpp"

#include "host/io/output_file.hpp"

#include "host/io/json_input.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <stdexcept>

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

// The poles of A = -C^-1 G all in the left half plane: with a symmetric G (a passive network)
// exactly when every node has a path of positive conductances to ambient or a boundary; a source
// driven by a temperature difference makes G non-symmetric and may also push a pole across, hence
// the general eigenvalues. Checked with every declared event present (a link an event switches on
// counts), so a network is refused only when no event state can make it stable.
bool stable(const Network& net, const Eigen::VectorXd& params, double speed_rpm) {
  const NodeMatrices m = assemble(net, params, speed_rpm, ~0u);
  const Eigen::MatrixXd CiG = m.capacitance.cwiseInverse().asDiagonal() * m.G;
  if (!CiG.allFinite()) return false;
  const Eigen::EigenSolver<Eigen::MatrixXd> es(CiG, false);
  if (es.info() != Eigen::Success) return false;
  const Eigen::VectorXcd ev = es.eigenvalues();
  return ev.real().minCoeff() > 1e-12 * std::max(ev.cwiseAbs().maxCoeff(), 1e-300);
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
  for (const double s : {0.0, operating})
    if (!stable(net, params, s))
      add(std::string("not stable in ") + mode_name(net.mode_at(s)) +
          " mode (a node without a path of positive conductances to ambient, or heat that grows with temperature faster than it flows away)");
  return out;
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
  if (!j.is_object() || !j.contains("network") || !j.contains("parameters"))
    throw std::invalid_argument(src + ": not a btsm model (needs 'network' and 'parameters')");
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
