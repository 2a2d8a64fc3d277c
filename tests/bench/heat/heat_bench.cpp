// Benchmark of the inverse heat-source estimation. Every case runs in a forked child so its peak
// resident memory (ru_maxrss of that child) is its own. Prints figures; asserts nothing.
//   1. reference stepwise run (6481 samples at 5 s, 60 s steps): GCV + tikhonov1, full alpha search
//   2. dense stacked formulation (the paper's H, Eq. 30-39) vs the smoother at ONE alpha on the
//      first N samples, N = 720 and 1440: the baseline ratio and how the dense cost grows
//   3. 24 h at 1 s (86,400 samples, simulated spindle4 with speed steps): one alpha, and GCV
#include "host/thermal/heat_inverse.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"
#include "host/thermal/simulator.hpp"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <functional>
#include <random>

namespace th = btsm::thermal;

namespace {

// Runs `f` in a child; prints label, wall time and peak RSS.
void measure(const char* label, const std::function<std::string()>& f) {
  std::fflush(stdout);
  const pid_t pid = fork();
  if (pid == 0) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::string note = f();
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    std::printf("%-58s %9.3f s %9.1f MB  %s\n", label, s, ru.ru_maxrss / 1024.0, note.c_str());
    std::fflush(stdout);
    _exit(0);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) std::printf("%-58s FAILED (status %d)\n", label, status);
}

th::Recording truncate(const th::Recording& r, std::size_t n) {
  th::Recording t = r;
  t.time_s.resize(n);
  t.speed_rpm.resize(n);
  t.ambient_c.resize(n);
  t.temp_c.conservativeResize(static_cast<Eigen::Index>(n), Eigen::NoChange);
  return t;
}

th::Recording day_at_1s(const th::Network& net, const Eigen::VectorXd& p) {
  th::Recording rec;
  rec.source = "simulated 24 h at 1 s";
  rec.channels = {"T1", "T2", "T3", "T4"};
  std::mt19937 rng(24);
  std::uniform_int_distribution<int> speed(0, 8);
  double rpm = 0;
  for (int k = 0; k < 86400; ++k) {
    if (k % 1800 == 0) rpm = speed(rng) * 1000.0;  // a new speed every 30 min (0 = standstill)
    rec.time_s.push_back(k);
    rec.speed_rpm.push_back(rpm);
    rec.ambient_c.push_back(25.0);
  }
  rec.temp_c = Eigen::MatrixXd::Zero(86400, 4);
  const Eigen::MatrixXd x = th::simulate_recording(net, p, rec, Eigen::VectorXd::Constant(4, 25.0));
  std::normal_distribution<double> noise(0, 0.005);
  for (int k = 0; k < 86400; ++k)
    for (int c = 0; c < 4; ++c) rec.temp_c(k, c) = (c == 3 && rec.speed_rpm[k] > 0) ? NAN : x(k, c) + noise(rng);
  return rec;
}

}  // namespace

int main() {
  const th::Network net = th::preset_network("spindle4");
  const Eigen::VectorXd p = th::default_parameters(net);
  const th::Recording ref = th::read_recording_csv(std::string(BTSM_TEST_DATA_DIR) + "/tnm-reference/stepwise_3001_5018_7028.csv");
  std::printf("%-58s %11s %12s\n", "case", "wall", "peak RSS");
  th::HeatInverseOptions o;
  o.step_s = 60;
  measure("baseline: process with the reference recording loaded", [&] { return std::string(); });
  measure("reference stepwise run, GCV + tikhonov1 (full search)", [&] {
    const th::HeatInverseResult r = th::solve_heat_inverse(th::make_inverse_problem(net, p, ref, {}, false), o);
    return "alpha " + std::to_string(r.alpha) + ", " + std::to_string(r.scan.size()) + " alpha evaluations";
  });
  for (std::size_t n : {720u, 1440u}) {
    const th::Recording part = truncate(ref, n);
    const std::string tag = std::to_string(n) + " samples (" + std::to_string(n * 5 / 60) + " steps)";
    measure(("smoother, one alpha, " + tag).c_str(), [&] {
      th::solve_heat_inverse_fixed(th::make_inverse_problem(net, p, part, {}, false), o, 3e-6);
      return std::string();
    });
    measure(("dense stacked H, one alpha, " + tag).c_str(), [&] {
      th::solve_heat_inverse_dense(th::make_inverse_problem(net, p, part, {}, false), o, 3e-6);
      return std::string();
    });
  }
  const th::Recording day = day_at_1s(net, p);
  measure("24 h at 1 s (86,400 samples, 1440 steps), one alpha", [&] {
    th::solve_heat_inverse_fixed(th::make_inverse_problem(net, p, day, {}, false), o, 3e-6);
    return std::string();
  });
  th::HeatInverseOptions og = o;
  og.alpha_points = 20;
  measure("24 h at 1 s, GCV over 20 grid points + refinement", [&] {
    const th::HeatInverseResult r = th::solve_heat_inverse(th::make_inverse_problem(net, p, day, {}, false), og);
    return "alpha " + std::to_string(r.alpha);
  });
  std::printf("dense at 24 h would need a %d x %d sensitivity matrix (%.1f GB) before the solve\n", 86400 * 3, 4 + 2 * 1440,
              86400.0 * 3 * (4 + 2 * 1440) * 8 / 1e9);
  return 0;
}
