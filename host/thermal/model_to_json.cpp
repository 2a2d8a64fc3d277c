// Fitted-model JSON writer (the reader and its checks are model_file.cpp, which needs nothing
// of the fit).
#include "model_file.hpp"

namespace btsm::thermal {

nlohmann::json model_to_json(const Network& net, const FitResult& fit, const std::vector<Recording>& recs) {
  nlohmann::json j;
  j["format"] = "btsm-thermal-model-1";
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
  return j;
}

}  // namespace btsm::thermal
