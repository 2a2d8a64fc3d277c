// Hand-written Levenberg-Marquardt vs Ceres (LM trust region, bounds, residual blocks per run on
// all cores, ceres::Covariance) on the reference fit (five tnm-reference warm-ups) and the demo fit
// (tests/data/demo-warmups), same pipeline, same tolerances: final rms, parameter error against the
// truth (reference), iterations, converged, wall and CPU time. Printed for the decision in README.
#include "host/thermal/fit.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <string>
#include <vector>

using namespace btsm::thermal;

namespace {

void run(const char* label, const Network& net, const std::vector<Recording>& recs, const nlohmann::json* truth,
         FitSolver solver, int iterations) {
  FitOptions o;
  o.sum_capacitance_J_per_K = 20478.7;
  o.solver = solver;
  o.max_iterations = iterations;
  const auto t0 = std::chrono::steady_clock::now();
  const double c0 = static_cast<double>(std::clock()) / CLOCKS_PER_SEC;
  const FitResult r = fit_network(net, recs, o);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double cpu = static_cast<double>(std::clock()) / CLOCKS_PER_SEC - c0;
  int its = 0;
  for (const auto& s : r.stages) its += s.iterations;
  double worst_rel = 0, worst_z = 0;
  if (truth)
    for (const auto& e : r.estimates) {
      if (e.status != Identifiability::Good) continue;
      const double t = truth->at(e.name).get<double>();
      worst_rel = std::max(worst_rel, std::abs(e.value / t - 1));
      worst_z = std::max(worst_z, std::abs(e.value - t) / e.sigma);
    }
  std::printf("  %-6s %-7s %4d it budget: rms %.6f K, %4d iterations over the stages (final %3d), %-13s %7.3f s wall %7.3f s CPU",
              label, solver == FitSolver::Ceres ? "Ceres" : "hand LM", iterations, r.rms_K, its, r.stages.back().iterations,
              r.converged ? "converged," : "NOT converged,", wall, cpu);
  if (truth) std::printf("; worst identifiable |err| %.3f %% = %.2f sigma", 100 * worst_rel, worst_z);
  std::printf("\n");
}

}  // namespace

int main() {
  const std::string data = BTSM_TEST_DATA_DIR;
  std::ifstream tf(data + "/tnm-reference/true_parameters.json");
  const nlohmann::json truth = nlohmann::json::parse(tf).at("parameters");
  std::vector<Recording> ref;
  for (const char* f : {"warmup_4006rpm.csv", "warmup_5013rpm.csv", "warmup_6021rpm.csv", "warmup_7023rpm.csv", "warmup_8028rpm.csv"})
    ref.push_back(read_recording_csv(data + "/tnm-reference/" + f));
  std::vector<Recording> demo;
  for (const char* f : {"warmup_4000rpm.csv", "warmup_6000rpm.csv", "warmup_8000rpm.csv"})
    demo.push_back(read_recording_csv(data + "/demo-warmups/" + f));
  const Network net = preset_network("spindle4");
  Network demo_net = net;
  remap_measurements(demo_net, {"shaft=T5"});
  std::printf("fit solvers (load average at start: see /proc/loadavg)\n");
  for (FitSolver s : {FitSolver::HandWritten, FitSolver::Ceres}) {
    run("ref", net, ref, &truth, s, 60);
    run("demo", demo_net, demo, nullptr, s, 60);
    run("demo", demo_net, demo, nullptr, s, 400);
  }
  return 0;
}
