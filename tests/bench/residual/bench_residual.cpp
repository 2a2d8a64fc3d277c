// Figures: wall and CPU time of one residual loop on five warm-ups + one check run (the reference
// data size; issue 13's bar is <= 30 s wall on 2 cores), with the independent refits side by side
// on the machine's cores against the same loop with them one after the other (threads = 1), both
// measured in this run on the same data, and whether both give the same answer (they must: each
// refit depends on its own inputs only).
// Data: tests/data/tnm-reference by default; or suite case directories (truth.json lists the runs
// and their use, as `btsm effect-suite` writes them) given as arguments.
#include "tests/bench/load_average.hpp"
#include "host/residual/residual_loop.hpp"
#include "host/thermal/column_map.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <string>
#include <vector>

namespace th = btsm::thermal;
namespace rs = btsm::residual;

namespace {
double now_s() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }
// process CPU time over all threads
double cpu_s() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

struct Case {
  std::string name;
  std::vector<th::Recording> fit, check;
};

Case reference_case() {
  const std::string dir = std::string(BTSM_TEST_DATA_DIR) + "/tnm-reference/";
  Case c{"tnm-reference", {}, {}};
  for (const char* f : {"warmup_4006rpm.csv", "warmup_5013rpm.csv", "warmup_6021rpm.csv", "warmup_7023rpm.csv", "warmup_8028rpm.csv"})
    c.fit.push_back(th::read_recording_csv(dir + f));
  c.check.push_back(th::read_recording_csv(dir + "stepwise_3001_5018_7028.csv"));
  return c;
}

Case suite_case(const std::string& dir) {
  std::ifstream in(dir + "/truth.json");
  if (!in) throw std::runtime_error("no truth.json in " + dir);
  const nlohmann::json truth = nlohmann::json::parse(in);
  Case c;
  c.name = dir.substr(dir.find_last_of('/', dir.size() - 2) + 1);
  for (const auto& r : truth.at("runs")) {
    th::Recording rec = th::read_recording_csv(dir + "/" + r.at("file").get<std::string>());
    (r.at("use") == "fit" ? c.fit : c.check).push_back(std::move(rec));
  }
  return c;
}

struct Timed {
  double wall = 0, cpu = 0, load = 0;
  rs::LoopResult r;
};

Timed run(const Case& c, unsigned threads) {
  th::Network net = th::preset_network("spindle4");
  std::vector<th::Recording> all = c.fit;
  all.insert(all.end(), c.check.begin(), c.check.end());
  th::map_measurements(net, all, {});
  rs::LoopOptions o;
  o.threads = threads;
  Timed t;
  t.load = btsm::bench::load_average_1min();
  const double w0 = now_s(), c0 = cpu_s();
  t.r = rs::run_residual_loop(net, Eigen::VectorXd(), c.fit, c.check, o);
  t.wall = now_s() - w0;
  t.cpu = cpu_s() - c0;
  return t;
}

std::string answer(const rs::LoopResult& r) {
  std::string nodes;
  for (const auto& n : r.nodes) nodes += (nodes.empty() ? "" : "+") + n;
  return fmt::format("{} {} [{}] check {:.4g} -> {:.4g} K", r.verdict, r.effect, nodes, r.before_check.rmse_k, r.after_check.rmse_k);
}
}  // namespace

int main(int argc, char** argv) {
  std::vector<Case> cases;
  if (argc > 1)
    for (int i = 1; i < argc; ++i) cases.push_back(suite_case(argv[i]));
  else
    cases.push_back(reference_case());
  std::printf("residual loop on 5 warm-ups + 1 check run (bar: <= 30 s wall on 2 cores)\n");
  std::printf("%-44s | %-30s | %-30s | same answer | answer\n", "case", "refits side by side: wall (CPU)", "one after the other: wall (CPU)");
  int failures = 0;
  for (const Case& c : cases) {
    const Timed par = run(c, 0), seq = run(c, 1);
    const bool same = answer(par.r) == answer(seq.r);
    failures += same ? 0 : 1;
    std::printf("%-44s | %6.1f s (%6.1f s) load %4.1f | %6.1f s (%6.1f s) load %4.1f | %-11s | %s\n", c.name.c_str(), par.wall, par.cpu,
                par.load, seq.wall, seq.cpu, seq.load, same ? "yes" : "NO", answer(par.r).c_str());
    std::printf("%-44s | %s\n", "", par.wall <= 30.0 ? "<= 30 s: met" : "> 30 s: NOT met");
  }
  return failures == 0 ? 0 : 1;
}
