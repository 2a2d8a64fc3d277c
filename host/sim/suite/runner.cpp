#include "host/sim/suite/runner.hpp"

#include "host/io/input_error.hpp"
#include "host/io/json_input.hpp"
#include "host/io/output_file.hpp"
#include "host/sim/suite/generate.hpp"

#include <fmt/core.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <spawn.h>
#include <stdexcept>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

extern char** environ;

namespace fs = std::filesystem;

namespace btsm::sim::suite {
namespace {

using Clock = std::chrono::steady_clock;

// Through the capped, depth- and duplicate-key-checked reader every user file goes through: a
// hand-edited {"verdict":"none","verdict":"effect"} was scored as a claim.
nlohmann::json read_json(const fs::path& p) {
  return io::read_json_file(p.string(), 64u << 20, "suite JSON");
}

// The answer a child writes goes to a part file, renamed over residual.json only when the child
// exits 0: a stopped or failed rerun leaves the previous answer as it was.
fs::path answer_part(const fs::path& dir) { return dir / "residual.json.part"; }

struct Child {
  size_t index = 0;
  pid_t pid = -1;
  Clock::time_point started;
};

// Starts argv with stdout -> out_path, stderr -> err_path.
pid_t spawn(const std::vector<std::string>& argv, const std::string& out_path, const std::string& err_path) {
  // The child opens them before it runs, and posix_spawn waits for that: a named pipe there
  // blocked the suite for ever.
  io::refuse_output_file_that_cannot_be_made(out_path, "case file", "answer of btsm residual");
  io::refuse_output_file_that_cannot_be_made(err_path, "case file", "log of btsm residual");
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&fa, STDERR_FILENO, err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, argv[0].c_str(), &fa, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) throw std::runtime_error("cannot start " + argv[0] + ": " + std::strerror(rc));
  return pid;
}

// The child's last word: its last line that says something (CLI11 ends a usage error with "Run
// with --help for more information.", which is not the cause).
std::string last_line(const fs::path& p) {
  std::ifstream in(p);
  std::string line, last;
  while (std::getline(in, line))
    if (!line.empty() && line.rfind("Run with --help", 0) != 0) last = line;
  return last;
}

}  // namespace

std::vector<std::string> residual_command(const std::string& btsm, const std::string& case_dir,
                                          const std::vector<std::string>& extra) {
  const nlohmann::json truth = read_json(fs::path(case_dir) / "truth.json");
  std::vector<std::string> argv{btsm, "residual", "--preset", "spindle4", "--json"};
  for (const char* use : {"fit", "check"})
    for (const auto& r : truth.at("runs"))
      if (r.at("use") == use) {
        // a case's recordings are files in its own folder: a hand-edited "../../x" or "/etc/passwd" is no run of it
        const std::string file = r.at("file").get<std::string>();
        if (file.empty() || file.find('/') != std::string::npos || file == "." || file == "..")
          throw io::InputError((fs::path(case_dir) / "truth.json").string() + ": run file '" + file +
                               "' is not a file name in the case's folder");
        argv.push_back(std::string("--") + use);
        argv.push_back((fs::path(case_dir) / file).string());
      }
  argv.insert(argv.end(), extra.begin(), extra.end());
  return argv;
}

SuiteReport run_suite(const std::vector<SuiteCase>& cases, const RunnerOptions& opts) {
  const auto t0 = Clock::now();
  const auto say = [&](const std::string& s) {
    if (opts.progress) opts.progress(s);
  };
  const fs::path out = opts.out_dir;
  fs::create_directories(out / "cases");
  const auto dir_of = [&](const SuiteCase& c) { return (out / "cases" / c.id).string(); };

  if (opts.generate)
    for (size_t i = 0; i < cases.size(); ++i) {
      const GeneratedCase g = generate_case(cases[i], dir_of(cases[i]));
      say(fmt::format("generated {}/{} {}: {} recordings, noise floor {:.4f} K (check), {:.1f} s", i + 1, cases.size(),
                      cases[i].id, g.runs.size(), g.noise_floor_check_k, g.wall_s));
    }

  SuiteReport rep;
  if (!opts.run) return rep;
  if (opts.btsm_path.empty() || !fs::exists(opts.btsm_path))
    throw std::invalid_argument("effect suite: btsm executable '" + opts.btsm_path + "' not found");

  std::vector<CaseResult> results(cases.size());
  std::vector<Child> running;
  size_t next = 0, done = 0;
  const int jobs = std::max(1, opts.jobs);
  // Every field the scoring reads, checked and named before a case is run or scored: a bad
  // truth.json is refused (exit 2), not scored, and costs no residual run.
  const auto checked_truth = [&](const SuiteCase& c) {
    const fs::path path = fs::path(dir_of(c)) / "truth.json";
    const nlohmann::json truth = read_json(path);
    if (const std::string why = truth_problem(truth, c); !why.empty()) throw io::InputError(path.string() + ": " + why);
    try {
      (void)failed_case(truth, "", 0);
    } catch (const nlohmann::json::exception& e) {
      throw io::InputError(path.string() + ": not a case's truth: " + io::without_json_exception_ids(e.what()));
    }
    return truth;
  };
  const auto finish = [&](const Child& ch, int status, bool timed_out) {
    const SuiteCase& c = cases[ch.index];
    const fs::path dir = dir_of(c);
    const double secs = std::chrono::duration<double>(Clock::now() - ch.started).count();
    const nlohmann::json truth = checked_truth(c);
    // A reused answer runs nothing, but its truth is held to what a run would check: its run files in
    // the case's folder (residual_command, which a run already went through before it was started),
    // and a kind the scoring knows ("bogus" counted as quiet).
    if (ch.pid < 0) (void)residual_command(opts.btsm_path.empty() ? std::string("btsm") : opts.btsm_path, dir.string(), {});
    // A reused answer is an input like the truth (no run made it here): one the scoring cannot take
    // is refused, naming file and key, instead of being counted as a case without an answer.
    if (ch.pid < 0)
      if (const std::string why = answer_shape_problem(read_json(dir / "residual.json")); !why.empty())
        throw io::InputError((dir / "residual.json").string() + ": " + why + "; not an answer to reuse (remove it to run the case again)");
    CaseResult r;
    std::error_code rename_error;
    std::string not_an_answer;  // a child that exited 0 but printed no residual answer (another program as --btsm)
    if (ch.pid >= 0) {  // a child ran: its answer replaces the old one only when complete
      std::error_code ec;
      const bool exited_ok = !timed_out && WIFEXITED(status) && WEXITSTATUS(status) == 0;
      if (exited_ok) {
        try {
          not_an_answer = answer_shape_problem(read_json(answer_part(dir)));
        } catch (const std::exception& e) {
          not_an_answer = io::without_json_exception_ids(e.what());
        }
      }
      if (exited_ok && not_an_answer.empty())
        fs::rename(answer_part(dir), dir / "residual.json", rename_error);
      else
        fs::remove(answer_part(dir), ec);
    }
    if (!not_an_answer.empty()) {
      r = failed_case(truth, "btsm residual exited 0 but printed no answer (" + not_an_answer + "); the previous residual.json is kept",
                      secs);
    } else if (rename_error) {
      r = failed_case(truth, "cannot keep the answer as residual.json: " + rename_error.message(), secs);
    } else if (timed_out) {
      r = failed_case(truth, fmt::format("btsm residual ran past {:.0f} s and was stopped", opts.timeout_s), secs);
    } else if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
      r = failed_case(truth,
                      fmt::format("btsm residual exited with {}: {}", WIFEXITED(status) ? WEXITSTATUS(status) : -1,
                                  last_line(dir / "residual.log")),
                      secs);
    } else {
      try {
        const nlohmann::json answer = read_json(dir / "residual.json");
        if (const std::string why = answer_shape_problem(answer); !why.empty())
          throw io::InputError((dir / "residual.json").string() + ": " + why);
        // a reused answer (no child ran): the loop's own run time, as it reported it
        const double reported = answer.contains("seconds") && answer["seconds"].is_number() ? answer["seconds"].get<double>() : secs;
        r = score_case(truth, answer, ch.pid < 0 ? reported : secs);
      } catch (const std::exception& e) {
        r = failed_case(truth, std::string("unreadable residual.json: ") + io::without_json_exception_ids(e.what()), secs);
      }
    }
    results[ch.index] = r;
    ++done;
    say(fmt::format("[{}/{}] {}: {} {} [{}] check {:.4f} -> {:.4f} K{} ({:.0f} s)", done, cases.size(), c.id, r.verdict,
                    r.effect, [&] { std::string s; for (const auto& n : r.nodes) s += (s.empty() ? "" : "+") + n; return s; }(), r.rmse_before_k, r.rmse_after_k,
                    c.kind == CaseKind::Effect ? (r.named ? ", named" : ", NOT named") : (r.claimed ? ", FALSE CLAIM" : ""),
                    r.residual_s));
  };
  // An answer already on disk (reuse_answers): newer than the recordings and holding a verdict.
  // One that is no JSON (cut short, a key twice) was run again and overwritten without a word; a
  // run never leaves one (it writes a part file and renames it), so it is named instead.
  const auto has_answer = [&](const fs::path& dir) {
    const fs::path answer = dir / "residual.json", truth = dir / "truth.json";
    std::error_code ec;
    if (!fs::exists(answer, ec) || fs::last_write_time(answer, ec) < fs::last_write_time(truth, ec)) return false;
    nlohmann::json j;
    try {
      j = read_json(answer);
    } catch (const std::invalid_argument& e) {
      throw io::InputError(std::string(e.what()) + "; not an answer to reuse (remove it to run the case again)");
    }
    return j.is_object() && j.contains("verdict");
  };
  while (done < cases.size()) {
    while (opts.reuse_answers && next < cases.size() && has_answer(dir_of(cases[next]))) {
      finish({next, -1, Clock::now()}, 0, false);
      ++next;
    }
    while (int(running.size()) < jobs && next < cases.size()) {
      if (opts.reuse_answers && has_answer(dir_of(cases[next]))) break;  // scored by the loop above
      const fs::path dir = dir_of(cases[next]);
      (void)checked_truth(cases[next]);
      const auto argv = residual_command(opts.btsm_path, dir.string(), opts.residual_args);
      running.push_back({next, spawn(argv, answer_part(dir).string(), (dir / "residual.log").string()), Clock::now()});
      ++next;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    for (size_t k = 0; k < running.size();) {
      int status = 0;
      const pid_t r = waitpid(running[k].pid, &status, WNOHANG);
      const bool late = std::chrono::duration<double>(Clock::now() - running[k].started).count() > opts.timeout_s;
      if (r == 0 && late) {
        kill(running[k].pid, SIGKILL);
        waitpid(running[k].pid, &status, 0);
      }
      if (r == running[k].pid || (r == 0 && late)) {
        finish(running[k], status, r == 0);
        running.erase(running.begin() + long(k));
      } else {
        ++k;
      }
    }
  }

  rep.results = results;
  rep.rows = summarize(results);
  rep.table_md = markdown_table(rep.rows);
  rep.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  // Beside-and-rename with every write checked (probe 5: /dev/full and a directory in the way
  // were "written", a symlinked results.json was written through to its target).
  // Each output is tried: one that cannot be written must not cost the others a long run's results.
  std::string write_errors;
  const auto write = [&](const fs::path& path, const std::string& text, const char* what) {
    try {
      io::write_output_file(path.string(), text, what);
    } catch (const std::exception& e) {
      write_errors += (write_errors.empty() ? "" : "; ") + std::string(e.what());
    }
  };
  write(out / "results.csv", results_csv(results), "suite results");
  nlohmann::json j;
  j["cases"] = nlohmann::json::array();
  for (const auto& r : results) j["cases"].push_back(to_json(r));
  j["table"] = nlohmann::json::array();
  for (const auto& row : rep.rows)
    j["table"].push_back({{"group", row.group},
                          {"quiet", row.quiet},
                          {"cases", row.cases},
                          {"named", row.named},
                          {"family_named", row.family_named},
                          {"claimed", row.claimed},
                          {"partial", row.partial},
                          {"goal", row.goal},
                          {"errors", row.errors}});
  j["wall_s"] = rep.wall_s;
  write(out / "results.json", j.dump(1) + "\n", "suite results");
  write(out / "table.md", rep.table_md, "suite table");
  if (!write_errors.empty()) throw std::runtime_error(write_errors);
  return rep;
}

}  // namespace btsm::sim::suite
