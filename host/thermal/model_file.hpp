#pragma once
// The fitted-model JSON written by `btsm fit` and read by validate / reduce / heat / residual:
// self-contained (embeds the network description) with values, units, 1 sigma, identifiability,
// gauge, fit metrics and the recordings used.
#include "fit.hpp"
#include "network.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace btsm::thermal {

struct FittedModel {
  Network network;
  Eigen::VectorXd params;
  Eigen::VectorXd sigma;   // NaN where unknown (model written by hand)
  nlohmann::json json;     // the whole document
};

nlohmann::json model_to_json(const Network& net, const FitResult& fit, const std::vector<Recording>& recs);
// The module channel -> recorded column -> node map of a fit ("channel_map" in the model JSON):
// channel n is recorded as column "Tn" (btsm record); its module role comes from the recordings'
// channel_roles metadata (null when they carry none), its node from the network's measurements,
// or "ambient" for the channel the recordings name as ambient (recorded as ambient_c). Channels
// without a column in the recordings are left out.
nlohmann::json channel_map_json(const Network& net, const std::vector<Recording>& recs);
FittedModel model_from_json(const nlohmann::json& j, const std::string& source);
FittedModel load_model(const std::string& path);
void save_json(const std::string& path, const nlohmann::json& j);

}  // namespace btsm::thermal
