#pragma once
// Stage 6 of the residual loop: one proposal refitted jointly with the base parameters and scored
// on the fit recordings (BIC, parameter significance, identifiability) and the held-out check
// recordings (RMSE before/after).
#include "host/residual/residual_loop.hpp"
#include "host/residual/screening.hpp"

#include <functional>
#include <map>
#include <string>
#include <vector>

namespace btsm::residual {

struct CandidateContext {
  const thermal::Network* base = nullptr;
  Eigen::VectorXd base_params;
  const std::vector<thermal::Recording>* fit = nullptr;
  // the fit recordings the refits run on (decimated: thermal responses are smooth and the cost of
  // a refit is linear in rows); the evidence is always computed on `fit` itself
  const std::vector<thermal::Recording>* fit_refit = nullptr;
  const std::vector<thermal::Recording>* check = nullptr;
  std::vector<Eigen::MatrixXd> measured_fit, measured_check;
  ErrorMetrics before_check;
  double base_bic = 0;
  std::vector<int> free_params;     // base parameters the refit may move (Proposal::base_shift order)
  bool fit_base = true;             // false: only the effect's parameters are fitted
  // The starts that lead a refit out of the base fit's basin (the base refitted around the
  // screening's effect, the staged fits of base + effect) run only while the base misfits the fit
  // recordings (LoopOptions::basin_starts_above_noise): a base at the noise has no better minimum
  // of the fit part to be led to, and those starts were 60 % of the loop's CPU on such data.
  bool basin_starts = true;
  int effect_iterations = 60;       // Levenberg-Marquardt iterations of each start's effect-only stage
  int joint_iterations = 300;       // ... of the joint refit from the best start
  thermal::BudgetContinuation joint_continuation;  // ... and past it while it still gains (LoopOptions::refit_continuation)
  double param_z = 3.0;             // a node whose key parameter is below this |value| / sigma is dropped
  // Base values of a candidate fitted before (empty: none): one more staged start runs from them,
  // named after `other_base_from` (refit_candidate says why).
  Eigen::VectorXd other_base_params;
  std::string other_base_from;
  // A probe lag: the base fitted without the probe is a start whatever share of the base residual
  // the probe carries, and the joint refit also runs from it (the better end is kept). That start's
  // effect-alone fit is poor by construction (the probe's node is unprobed in it, its parameters
  // free), so the best-start rule alone never continues from it.
  bool lag_from_base_without_probe = false;
  std::function<void(const std::string&)> progress;
};

// The candidate of a proposal before any fit: its effect, nodes and screening evidence.
CandidateResult candidate_of(const Proposal& p, const thermal::Network& base);

// Refits `p` from several starts, each an effect-only fit first: the screening's coefficients on the
// base fit and on the base shifted as the screening's regression says (what the base absorbed,
// given back), and for a family with a time constant a second time constant; the joint refit of
// every parameter then runs from the best of them. Fills the candidate's evidence; status and
// reason are left to the decision. A failing fit gives status "failed" with the error as the reason.
CandidateResult refit_candidate(const CandidateContext& ctx, const Proposal& p);

// True when no recording in `recs` changes speed while turning: there every start-or-change
// transient restarts at the same rows as a starts-only one, so both fit those recordings alike.
bool starts_only_restarts_alike(const thermal::Network& base, const std::vector<thermal::Recording>& recs);
// The starts-only twin of a fitted start-or-change transient whose fit recordings restart both
// alike (starts_only_restarts_alike on ctx.fit): its refit would be this one, so the twin carries
// the same fit evidence and parameters; only the check run (speed changes while turning) tells
// them apart, and its check evidence is its own.
CandidateResult starts_only_twin(const CandidateContext& ctx, const CandidateResult& c);

// The candidate without its `drop`-th node, refitted jointly from its values (status "fitted").
CandidateResult refit_fewer_nodes(const CandidateContext& ctx, const CandidateResult& c, std::size_t drop);

// A fitted candidate's own effect parameters by network name, at their fitted values.
std::map<std::string, double> fitted_effect_values(const CandidateResult& c);

// The fitted candidate refitted jointly with the base at one node more, from its own values; the
// added node's parameters start at those of the candidate's first node (an equal share).
CandidateResult refit_more_nodes(const CandidateContext& ctx, const CandidateResult& c, int node);

// The node of a fitted multi-node candidate whose key parameter is weakest, when it is below
// ctx.param_z sigma, at its bound or not identifiable (-1: none, or a single node).
int weakest_node(const CandidateContext& ctx, const CandidateResult& c);

// Drops such nodes one at a time (each time refitting the rest jointly from the candidate's values)
// until every node left is supported; a right effect fitted at one node too many is then judged
// at its own nodes instead of being rejected for the extra node's weak |z|. True when it dropped any.
bool prune_weak_nodes(const CandidateContext& ctx, CandidateResult& c);

// Refits a fitted candidate jointly on the full-rate fit recordings from its values (the refits
// run on decimated recordings) and refreshes its evidence; true when that lowered the fit error.
bool polish_candidate(const CandidateContext& ctx, CandidateResult& c);

// Every k-th row of a recording with k = the step that reaches `step_s` (1: the recording itself).
// The speed on a kept row holds until the next kept row, so a speed change moves by < k samples.
thermal::Recording decimated(const thermal::Recording& rec, double step_s);

// The augmented model's start values from the screening's linear coefficients.
std::map<std::string, double> start_values(const thermal::Network& base, const Eigen::VectorXd& base_params, const Proposal& p);

}  // namespace btsm::residual
