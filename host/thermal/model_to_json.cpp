// Fitted-model JSON writer (the reader and its checks are model_file.cpp, which needs nothing
// of the fit).
#include "model_file.hpp"
#include "recording_metadata.hpp"

#include <fmt/core.h>

#include <map>

namespace btsm::thermal {

nlohmann::json channel_map_json(const Network& net, const std::vector<Recording>& recs) {
  std::map<std::string, std::string> role_of_column;  // from the first recording that read the module's roles
  std::string ambient_column;
  for (const auto& rec : recs) {
    if (role_of_column.empty())
      for (const auto& [column, role] : channel_roles(rec)) role_of_column[column] = role;
    if (ambient_column.empty()) ambient_column = ambient_channel(rec);
  }
  nlohmann::json map = nlohmann::json::array();
  for (int ch = 1; ch <= 5; ++ch) {
    const std::string column = fmt::format("T{}", ch);  // not "T" + to_string: GCC 12 -Wrestrict false positive
    if (recs.empty()) continue;
    if (recs.front().channel_index(column) < 0) {
      // btsm record writes the ambient channel's reading as ambient_c, not as its own column.
      if (column == ambient_column)
        map.push_back({{"channel", ch}, {"column", "ambient_c"}, {"module_role", "ambient"}, {"node", "ambient"}});
      continue;
    }
    nlohmann::json e{{"channel", ch}, {"column", column}};
    const auto role = role_of_column.find(column);
    e["module_role"] = role == role_of_column.end() ? nlohmann::json(nullptr) : nlohmann::json(role->second);
    nlohmann::json node = nullptr;
    for (const auto& m : net.measurements)
      if (m.column == column) node = net.nodes[static_cast<std::size_t>(m.node)].name;
    if (node.is_null() && (column == ambient_column || (role != role_of_column.end() && role->second == "ambient")))
      node = "ambient";
    e["node"] = node;
    map.push_back(e);
  }
  return map;
}

nlohmann::json model_to_json(const Network& net, const FitResult& fit, const std::vector<Recording>& recs) {
  nlohmann::json j;
  j["format"] = kFittedModelFormat;
  j["network"] = network_to_json(net);
  nlohmann::json values, sigma, units, status, notes;
  for (const auto& e : fit.estimates) {
    values[e.name] = e.value;
    sigma[e.name] = e.sigma;
    units[e.name] = e.unit;
    status[e.name] = identifiability_name(e.status);
    if (!e.note.empty()) notes[e.name] = e.note;
  }
  j["parameters"] = values;
  j["sigma"] = sigma;
  j["sigma_note"] = fit.sigma_method + " (fixed: 0)";
  j["units"] = units;
  j["identifiability"] = status;
  j["notes"] = notes.is_null() ? nlohmann::json::object() : notes;
  j["gauge"] = fit.gauge;
  j["fit"] = {{"rms_K", fit.rms_K},
              {"residual_sigma_K", fit.residual_sigma_K},
              {"residual_count", fit.residual_count},
              {"free_parameters", fit.free_parameter_count},
              {"condition_number", fit.condition_number},
              {"converged", fit.converged},
              {"seconds", fit.seconds}};
  j["fit"]["stages"] = nlohmann::json::array();
  for (const auto& s : fit.stages)
    j["fit"]["stages"].push_back({{"name", s.name}, {"iterations", s.iterations}, {"rms_K", s.rms_K}, {"seconds", s.seconds}});
  j["recordings"] = nlohmann::json::array();
  for (std::size_t r = 0; r < recs.size(); ++r) {
    nlohmann::json rj{{"file", recs[r].source}, {"rows", recs[r].rows()}};
    if (r < fit.correlation_rows.size()) rj["residual_correlation_rows"] = fit.correlation_rows[r];
    if (r < fit.initial_states.size()) {
      std::vector<double> x(fit.initial_states[r].data(), fit.initial_states[r].data() + fit.initial_states[r].size());
      rj["initial_state_c"] = x;
    }
    j["recordings"].push_back(rj);
  }
  j["warnings"] = fit.warnings;
  j["channel_map"] = channel_map_json(net, recs);
  return j;
}

}  // namespace btsm::thermal
