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
FittedModel model_from_json(const nlohmann::json& j, const std::string& source);
FittedModel load_model(const std::string& path);
void save_json(const std::string& path, const nlohmann::json& j);

}  // namespace btsm::thermal
