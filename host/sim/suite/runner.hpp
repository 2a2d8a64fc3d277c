#pragma once
// The undeclared-effect suite end to end: generate every case (generate.hpp), run the real
// `btsm residual --json` on each (a child process, as a user would), score (score.hpp), and write
//   OUT/cases/<id>/   recordings, truth.json, residual.json (the loop's answer), residual.log
//   OUT/results.csv   one row per case;  OUT/results.json  cases + table rows;  OUT/table.md
#include "host/sim/suite/cases.hpp"
#include "host/sim/suite/score.hpp"

#include <functional>
#include <string>
#include <vector>

namespace btsm::sim::suite {

struct RunnerOptions {
  std::string out_dir = "effect-suite";
  std::string btsm_path;                 // the btsm executable that runs `residual`
  std::vector<std::string> residual_args;  // extra arguments for every `btsm residual`
  int jobs = 1;                          // residual runs at once (the machine's cores are shared)
  double timeout_s = 1800;               // s per residual run; a run past it is killed and counted
  bool generate = true;                  // false: reuse the recordings already in out_dir
  bool run = true;                       // false: only generate
  // true: a case whose residual.json already holds an answer (a `verdict`) written after its
  // truth.json is scored as it is, not run again -- resumes a suite that was stopped part-way
  bool reuse_answers = false;
  std::function<void(const std::string&)> progress;
};

struct SuiteReport {
  std::vector<CaseResult> results;
  std::vector<TableRow> rows;
  std::string table_md;
  double wall_s = 0;
};

SuiteReport run_suite(const std::vector<SuiteCase>& cases, const RunnerOptions& opts);

// The `btsm residual` argument list for a generated case directory (recordings from truth.json).
std::vector<std::string> residual_command(const std::string& btsm, const std::string& case_dir,
                                          const std::vector<std::string>& extra);

}  // namespace btsm::sim::suite
