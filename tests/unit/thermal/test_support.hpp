#pragma once
// Shared helpers of the thermal unit tests: the reference data set and its truth.
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"

#include <nlohmann/json.hpp>

#include <fstream>
#include <string>
#include <vector>

namespace btsm::thermal::test {

inline std::string ref_dir() { return std::string(BTSM_TEST_DATA_DIR) + "/tnm-reference"; }

inline const std::vector<std::string>& warmup_files() {
  static const std::vector<std::string> f{"warmup_4006rpm.csv", "warmup_5013rpm.csv", "warmup_6021rpm.csv",
                                          "warmup_7023rpm.csv", "warmup_8028rpm.csv"};
  return f;
}
inline const char* kStepwise = "stepwise_3001_5018_7028.csv";

inline nlohmann::json truth_json() {
  std::ifstream f(ref_dir() + "/true_parameters.json");
  return nlohmann::json::parse(f);
}

// True parameter vector of the spindle4 preset, from true_parameters.json.
inline Eigen::VectorXd true_parameters(const Network& net) {
  const auto j = truth_json().at("parameters");
  Eigen::VectorXd p(net.param_count());
  for (int i = 0; i < net.param_count(); ++i) p[i] = j.at(net.params[static_cast<std::size_t>(i)].name).get<double>();
  return p;
}

}  // namespace btsm::thermal::test
