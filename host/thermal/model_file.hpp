#pragma once
// The fitted-model JSON written by `btsm fit` and read by validate / reduce / heat / residual:
// self-contained (embeds the network description) with values, units, 1 sigma, identifiability,
// gauge, fit metrics and the recordings used.
#include "fit.hpp"
#include "network.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <cstddef>
#include <string>
#include <vector>

namespace btsm::thermal {

struct FittedModel {
  Network network;
  Eigen::VectorXd params;
  Eigen::VectorXd sigma;   // NaN where unknown (model written by hand)
  nlohmann::json json;     // the whole document
  std::vector<FittedChannel> channel_map;  // its "channel_map": where the fit's probes were (empty: none)
};

// Size cap of a model file (a fitted model is a few kB), stated in the error.
// The "format" every fitted-model JSON carries (a reader refuses another named format).
inline constexpr const char* kFittedModelFormat = "btsm-thermal-model-1";
constexpr std::size_t kMaxModelBytes = std::size_t{16} << 20;

nlohmann::json model_to_json(const Network& net, const FitResult& fit, const std::vector<Recording>& recs);

// What makes parameter values unusable as a model of `net`, "" when none: a value that is not
// finite or outside its parameter's [min, max], a capacitance <= 0, or a network that is not
// stable at 0 rpm or in the operating mode (a pole of -C^-1 G with a real part >= 0: a node
// without a path of positive conductances to ambient, or driven heat that outgrows its outflow).
// Also refused there: node time constants more than 1e12 apart (the stability test cannot resolve
// them; named as such, not as "not stable"), and heat that would hold a node more than
// kMaxSteadyRiseK from ambient when settled at rest or at the reference speed (a stable network
// with a heat source or a resistance far out of range).
std::string model_problems(const Network& net, const Eigen::VectorXd& params);

// A settled node further than this from ambient is beyond any temperature a recording may hold
// (kMaxRecordedTempC = 10000 degC): a model predicting it has a value far out of range.
inline constexpr double kMaxSteadyRiseK = 10000.0;
// The parts of model_problems() at one speed, "" when none: why the network is not stable there
// (or its time constants cannot be resolved), and a steady rise beyond kMaxSteadyRiseK.
std::string instability_at(const Network& net, const Eigen::VectorXd& params, double speed_rpm);
std::string steady_rise_problem(const Network& net, const Eigen::VectorXd& params, double speed_rpm);

// The top-level keys of a fitted-model JSON (what model_to_json, the demo's final model and the
// files in tests/data carry); any other is refused by name, a typo such as "paramters" with the
// known key it is nearest to. What lies inside "fit", "notes", "units", "recordings" ... is
// informative and not checked: readers act only on "network", "parameters", "sigma" and
// "channel_map".
inline constexpr const char* kFittedModelKeys[] = {"format", "network", "parameters", "sigma", "sigma_note",
                                                   "units", "identifiability", "notes", "gauge", "fit",
                                                   "recordings", "warnings", "channel_map"};

// The module channel -> recorded column -> node map of a fit ("channel_map" in the model JSON):
// channel n is recorded as column "Tn" (btsm record); its module role comes from the recordings'
// channel_roles metadata (null when they carry none), its node from the network's measurements,
// or "ambient" for the channel the recordings name as ambient (recorded as ambient_c). Channels
// without a column in the recordings are left out.
nlohmann::json channel_map_json(const Network& net, const std::vector<Recording>& recs);

// The entries of a "channel_map" array that name a column (FittedModel::channel_map); entries of
// another shape are left out (reduce, which builds the module's map from them, refuses those itself).
std::vector<FittedChannel> fitted_channels(const nlohmann::json& channel_map);

// Reads a model; every model passes model_problems() on load, so validate, reduce, heat and
// residual never work on a value the network forbids. Throws std::invalid_argument (io::InputError
// for an unreadable file) naming the source and the problems.
FittedModel model_from_json(const nlohmann::json& j, const std::string& source);
FittedModel load_model(const std::string& path);
// A JSON file's text as the tool writes it (two-space indent, final newline), and the file written
// through io::write_output_file.
std::string json_file_text(const nlohmann::json& j);
void save_json(const std::string& path, const nlohmann::json& j);

}  // namespace btsm::thermal
