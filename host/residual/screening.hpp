#pragma once
// Trace first, then propose: the linear screening of the residual loop.
//
// The base model's residual r = measured - model is regressed on a dictionary of physical
// regressors, each mapped through the base model into what it would do to the measured columns:
//   heat regressors (W at a node, simulated through the base network from rest): speed powers
//     while running; decays after each start / speed increase / speed change at several time
//     constants, alone or times the node's friction law; each node's rise times its friction law;
//     node differences times speed; declared boundary columns minus the node; event columns times
//     (ambient - node); a node's own temperature through a lag minus itself (a missing mass); the
//     ambient through a lag minus the ambient, at every ambient link;
//   output regressors (K at a column): the column's model temperature through a lag minus itself
//     (a probe lag), hours since the recording's start with the probe's own offset in every
//     recording (a probe drift: how long it drifted before a recording is not recorded).
// What the base refit would absorb is projected out first: the regression runs in the orthogonal
// complement of the base model's Jacobian (its free parameters and every recording's initial
// state), so a regressor the base parameters can imitate scores nothing, and the scale gauge (a
// null direction of that Jacobian) is harmless. This is the inverse heat trace done in output
// space: no regularisation bias, and the unmeasured nodes are handled by the model itself.
//
// Per family, a forward selection picks the variant (time constant, trigger, exponent, pair) and
// the nodes with an information criterion on the effective sample size of the autocorrelated
// residual. Stability selection repeats it on resamples of time blocks of the fit recordings
// (Gram matrices per block, so a resample costs one small solve); a proposal reports how often
// its variant and nodes came back. Proposals carry the linear coefficients, the start values of
// the joint refit.
#include "host/residual/effects.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"

#include <Eigen/Core>

#include <functional>
#include <map>
#include <string>
#include <vector>

namespace btsm::residual {

struct ScreeningOptions {
  double sample_step_s = 30;        // s, rows used for the linear screening (thermal responses are smooth)
  int blocks_per_recording = 4;     // time blocks per recording for the stability resamples
  int resamples = 30;               // block resamples
  unsigned seed = 20240613u;        // resampling seed (the screening is deterministic)
  int max_nodes = 3;                // nodes (columns) per proposal
  std::vector<EffectKind> families; // empty = all
};

struct ScreeningInput {
  const thermal::Network* net = nullptr;
  Eigen::VectorXd params;                    // base parameter values
  const std::vector<thermal::Recording>* fit = nullptr;
  std::vector<Eigen::VectorXd> x0;           // base initial state per fit recording
  std::vector<int> free_params;              // base parameters the joint refit may move (projected out)
  std::vector<std::string> boundary_columns; // declared in every fit recording
  std::vector<std::string> event_columns;
  std::function<void(const std::string&)> progress;
};

struct Proposal {
  EffectSpec spec;
  std::string variant;                 // e.g. "additive, every speed increase, tau 20 min"
  std::vector<double> coefficients;    // linear coefficient per node (or column), the refit's start
  // The base parameters' shift in the same regression (ScreeningInput::free_params order, in the
  // fit's transformed units: log for log-scaled parameters): what the base fit absorbed of the
  // effect, given back. The refit's second start.
  Eigen::VectorXd base_shift;
  bool alternative = false;            // the family's second-best variant
  // The refit also runs the staged pipeline with every base parameter (and every effect parameter
  // that enters linearly) started by its equation-error stages, not by the base fit: for a
  // proposal the loop makes itself where the base fit's values are suspect (residual_loop.cpp,
  // declared boundaries refitted at every node).
  bool start_from_data = false;
  // Start values of the effect's own parameters by network name; when given they replace the ones
  // `coefficients` would give (a claim refitted from another candidate's base starts from its own
  // fitted effect: residual_loop.cpp, refit_claim_from_better_basin).
  std::map<std::string, double> effect_start;
  double gain_k2 = 0;                  // linearised RSS reduction after projection [K^2]
  double rss_fraction = 0;             // gain / base RSS (on the screening rows)
  double score = 0;                    // information-criterion gain on the effective sample size (> 0 = selected)
  double stability = 0;                // share of block resamples that selected the same variant and nodes
};

struct ScreeningResult {
  std::vector<Proposal> proposals;     // per family the best variant (and a clearly different second), best score first
  double rss_base_k2 = 0;              // base RSS after projection, screening rows
  double effective_samples = 0;        // from the residual's lag-1 autocorrelation
  std::size_t cells = 0;
  int regressors = 0;
};

// Throws std::invalid_argument on inconsistent input.
ScreeningResult screen_effects(const ScreeningInput& in, const ScreeningOptions& opts = {});

}  // namespace btsm::residual
