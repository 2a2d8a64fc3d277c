// `btsm effect-suite`: the undeclared-effect suite (host/sim/suite) -- recordings of the paper's
// identification procedure on the simulated spindle, each with one hidden effect (or none), the
// real `btsm residual` run on each, and the table of what it named.
#include "host/io/output_file.hpp"
#include "host/io/utf8_text.hpp"
#include "host/sim/suite/runner.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

#include <fmt/core.h>

#include <filesystem>
#include <iostream>
#include <unistd.h>

namespace btsm::cli {
namespace {

namespace su = btsm::sim::suite;

struct SuiteArgs {
  std::string set = "full";
  std::string out = "effect-suite";
  std::string btsm;
  std::vector<std::string> only, residual_args;
  int per_family = 3, jobs = 1;
  unsigned seed = 2024;
  double timeout_s = 1800;
  bool generate_only = false, score_only = false, list = false, reuse = false;
};

std::string self_path() {
  char buf[4096] = {};
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 1);
  return n > 0 ? std::string(buf, size_t(n)) : std::string("btsm");
}

void run_effect_suite(const SuiteArgs& a) {
  su::SuiteOptions so;
  so.set = a.set == "reduced" ? su::SuiteSet::Reduced : su::SuiteSet::Full;
  so.per_family = a.per_family;
  so.seed = a.seed;
  so.only = a.only;
  const auto cases = su::make_cases(so);
  if (cases.empty()) throw CommandError(kExitUsage, "no case matches --only");
  if (a.list) {
    for (const auto& c : cases) {
      std::string fx;
      for (const auto& e : c.effects) fx += (fx.empty() ? "" : " ") + (e.size() > 70 ? e.substr(0, 67) + "..." : e);
      std::cout << fmt::format("{:<48} {:<10} {}\n", c.id, su::case_kind_name(c.kind), fx.empty() ? "-" : fx);
    }
    return;
  }
  // Before the first case is generated or run (a --out naming a file gave a raw "filesystem error").
  io::refuse_output_dir_that_cannot_be_made(a.out, "--out");
  su::RunnerOptions ro;
  ro.out_dir = a.out;
  ro.btsm_path = a.btsm.empty() ? self_path() : a.btsm;
  ro.residual_args = a.residual_args;
  ro.jobs = a.jobs;
  ro.timeout_s = a.timeout_s;
  ro.generate = !a.score_only;
  ro.run = !a.generate_only;
  ro.reuse_answers = a.reuse;
  ro.progress = [](const std::string& s) { std::cerr << "effect-suite: " << s << std::endl; };
  su::SuiteReport rep;
  try {
    rep = su::run_suite(cases, ro);
  } catch (const std::invalid_argument& e) {
    throw CommandError(kExitUsage, e.what());
  }
  if (a.generate_only) {
    std::cerr << "effect-suite: " << cases.size() << " cases generated in " << a.out << "/cases\n";
    return;
  }
  std::cout << rep.table_md;
  std::cerr << fmt::format("effect-suite: {} cases in {:.0f} s; {}/results.csv, results.json, table.md\n",
                           rep.results.size(), rep.wall_s, a.out);
  // A case the loop gave no answer on is a result of the suite (counted in the table), not a
  // failure of the suite: say which, and exit 0.
  std::size_t errors = 0;
  for (const auto& r : rep.results)
    if (r.verdict == "error") {
      ++errors;
      std::cerr << "effect-suite: case " << r.id << " gave no answer: " << io::printable(r.error) << "\n";
    }
  // ... unless no case gave one: then the suite measured nothing (a bad --residual-arg, a btsm
  // that does not run), and a table of errors with exit 0 would pass for a result.
  if (!rep.results.empty() && errors == rep.results.size())
    throw CommandError(kExitFailure, "no case gave an answer (the first: " + rep.results.front().error + ")");
}

}  // namespace

void register_suite_commands(CLI::App& app) {
  auto a = std::make_shared<SuiteArgs>();
  auto* cmd = app.add_subcommand(
      "effect-suite",
      "Undeclared-effect suite: record the paper's identification procedure (warm-ups at 4000..8000 rpm with\n"
      "natural cooling + a stepwise check run, 5 s samples) on the simulated module, each case with one hidden\n"
      "plant effect of random strength, nodes and noise seed (or none: clean and distractor cases), run\n"
      "`btsm residual --json` on every case and print per family: named correctly (family AND nodes), check\n"
      "RMSE before -> after, the share meeting the goal, false claims on data without an effect.\n"
      "  btsm effect-suite --out suite/                 # full set (README table)\n"
      "  btsm effect-suite --set reduced --out s/       # the ctest subset");
  cmd->add_option("--set", a->set, "full (every family x --per-family) or reduced (9 fixed cases, short procedure)")
      ->check(CLI::IsMember({"full", "reduced"}))
      ->capture_default_str();
  cmd->add_option("--out", a->out, "output folder: cases/<id>/ (recordings, truth.json, residual.json), results.csv/json, table.md")
      ->capture_default_str();
  cmd->add_option("--per-family", a->per_family, "random cases per family variant and per clean/distractor kind (full set)")
      ->check(CLI::Range(1, 50))
      ->capture_default_str();
  cmd->add_option("--seed", a->seed, "master seed: strengths, nodes, noise and speeds of every case")->capture_default_str();
  cmd->add_option("--only", a->only, "keep cases whose id starts with this (repeatable)");
  cmd->add_option("--jobs", a->jobs, "btsm residual runs at once")->check(CLI::Range(1, 16))->capture_default_str();
  cmd->add_option("--timeout", a->timeout_s, "seconds one btsm residual run may take")->check(positive_number())->capture_default_str();
  cmd->add_option("--btsm", a->btsm, "btsm executable to run `residual` with (default: this one)");
  cmd->add_option("--residual-arg", a->residual_args, "extra argument for every btsm residual (repeatable)")
      ->allow_extra_args(false);
  auto* gen = cmd->add_flag("--generate-only", a->generate_only, "only write the recordings and truth.json");
  cmd->add_flag("--score-only", a->score_only, "reuse the recordings in --out, run and score only")->excludes(gen);
  cmd->add_flag("--reuse", a->reuse,
                "with --score-only: score a case's existing residual.json (newer than its recordings) instead of "
                "running it again (resumes a suite stopped part-way)");
  cmd->add_flag("--list", a->list, "print the cases (id, kind, hidden effect) and exit");
  cmd->callback([a] { run_effect_suite(*a); });
}

}  // namespace btsm::cli
