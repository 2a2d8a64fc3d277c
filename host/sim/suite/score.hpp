#pragma once
// Scoring of one case's `btsm residual --json` answer against its truth, and the suite table.
//
// Per case:
//   named    the loop's family (`effect`) is one of the family's accepted names AND its `nodes`
//            contain every node the effect acts on and nothing outside the allowed set (for a
//            boundary family, whose effect acts on every node, the family alone); a `partial`
//            verdict with the right family and nodes is named, not claimed
//   claimed  verdict `effect` (older loops without `verdict`: an effect name other than none /
//            unexplained); on clean and distractor cases every claim is a false claim
//   goal     named, claimed, and the check RMSE after is within 2x the case's noise floor or cut
//            >= 5x (sensor lag: >= 3x) -- issue 13's goal
#include "host/sim/suite/cases.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace btsm::sim::suite {

struct CaseResult {
  std::string id, kind, family, variant;
  std::vector<std::string> truth_nodes;
  std::string verdict;                  // effect, partial, none, unexplained, error
  std::string effect;                   // the loop's family (or none/unexplained)
  std::vector<std::string> nodes;       // the loop's nodes
  double rmse_before_k = NAN, rmse_after_k = NAN;  // check recording, K
  double noise_floor_k = NAN;           // K, recorded vs truth on the check recording
  double residual_s = NAN;              // wall seconds of the btsm residual run
  double goal_factor = 5;
  bool family_named = false, named = false, claimed = false, goal = false;
  std::string error;                    // why the run gave no answer
  double cut() const { return rmse_before_k / rmse_after_k; }
};

// `truth` = truth.json of the case (generate.hpp), `answer` = the parsed --json output.
CaseResult score_case(const nlohmann::json& truth, const nlohmann::json& answer, double residual_s);
// "" when `answer` has the shape of `btsm residual --json` as far as scoring reads it (an object;
// verdict one of effect/partial/none/unexplained (or, from a loop before verdicts, an effect name); effect a string; nodes a list of names;
// rmse_before_K/rmse_after_K numbers 0..10000 K or null, seconds a number >= 0), else what is
// wrong: {"verdict":5}, "effects":"x", a node name holding ESC [ 2 J or a newline (printed raw in
// the progress line) or an RMSE of -5 K were scored as if meant.
std::string answer_shape_problem(const nlohmann::json& answer);
// "" when `truth` (a case's truth.json) is the truth of case `c` as far as scoring reads it, else
// what is wrong, naming the key: truth.json is our own file, so a hand edit that would change the
// score or reach the terminal and table.md is refused -- an id, kind, family or variant other than
// the case's (the table prints them), accepted_names outside the family's, nodes that are no plain
// node names, a goal_factor that is no cut (<= 1: every answer would meet the goal), a negative
// noise floor.
std::string truth_problem(const nlohmann::json& truth, const SuiteCase& c);
// A case whose run failed (no JSON): counted, never named or claimed.
CaseResult failed_case(const nlohmann::json& truth, const std::string& error, double residual_s);

nlohmann::json to_json(const CaseResult& r);

// One row per family variant (effect cases) and per clean/distractor variant.
struct TableRow {
  std::string group;                   // "temperature_dependent_heat (falling)", "clean", ...
  bool quiet = false;                  // clean or distractor
  int cases = 0, family_named = 0, named = 0, claimed = 0, partial = 0, goal = 0, errors = 0;
  double before_median = NAN, after_median = NAN;   // K
  double worst_before = NAN, worst_after = NAN;     // K, the case with the smallest cut
  double floor_median = NAN;                        // K
};
std::vector<TableRow> summarize(const std::vector<CaseResult>& results);

std::string markdown_table(const std::vector<TableRow>& rows);
std::string results_csv(const std::vector<CaseResult>& results);

}  // namespace btsm::sim::suite
