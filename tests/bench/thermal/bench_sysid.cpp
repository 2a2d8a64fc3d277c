// Figures: fit wall/CPU time and peak RSS on the five reference warm-ups, validation and reduction
// time, as ratios to the baseline measured with the Octave (lsqnonlin + SLICOT) toolchain on a
// 2-core machine (docs/sysid-notes: whole pipeline 30 s, cooling-first fit alone 5 s). The
// baseline cannot be re-run here (no Octave), so it is quoted; everything else is measured.
#include "tests/bench/load_average.hpp"
#include "host/thermal/fit.hpp"
#include "host/thermal/reduce.hpp"
#include "host/thermal/validate.hpp"

#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <ctime>
#include <thread>

using namespace btsm::thermal;

namespace {
double now_s() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }
double cpu_s() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }
long peak_rss_kb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss;
}
}  // namespace

int main() {
  const std::string dir = std::string(BTSM_TEST_DATA_DIR) + "/tnm-reference/";
  const char* files[] = {"warmup_4006rpm.csv", "warmup_5013rpm.csv", "warmup_6021rpm.csv", "warmup_7023rpm.csv", "warmup_8028rpm.csv"};
  const long rss0 = peak_rss_kb();
  double t0 = now_s();
  std::vector<Recording> recs;
  for (const char* f : files) recs.push_back(read_recording_csv(dir + f));
  const double t_read = now_s() - t0;
  const Network net = preset_network("spindle4");
  FitOptions o;
  o.sum_capacitance_J_per_K = 20478.7;
  const double load_before_fit = btsm::bench::load_average_1min();
  t0 = now_s();
  const double c0 = cpu_s();
  const FitResult fit = fit_network(net, recs, o);
  const double t_fit = now_s() - t0, c_fit = cpu_s() - c0;
  const long rss_fit = peak_rss_kb();
  t0 = now_s();
  const Recording ext = read_recording_csv(dir + "stepwise_3001_5018_7028.csv");
  for (const auto& r : recs) validate_recording(net, fit.params, r);
  validate_recording(net, fit.params, ext);
  const double t_val = now_s() - t0;
  t0 = now_s();
  ReduceOptions ro;
  ro.speeds_rpm = {4000, 5000, 6000, 7000, 8000};
  const ScheduledReduction red = build_scheduled_model(net, fit.params, ro);
  const double t_red = now_s() - t0;
  const double pipeline = t_read + t_fit + t_val + t_red;
  std::printf("sysid bench (5 warm-ups x 7201 rows, %zu residuals, %d free parameters + %zu initial states)\n",
              fit.residual_count, fit.free_parameter_count, recs.size() * 4);
  std::printf("  read CSVs           %8.3f s\n", t_read);
  std::printf("  whole fit           %8.3f s wall, %.3f s CPU (load average %.2f on %u cores)   baseline 5 s  -> %.1fx faster (target <= 1.0 s wall)\n",
              t_fit, c_fit, load_before_fit, std::thread::hardware_concurrency(), 5.0 / t_fit);
  for (const auto& s : fit.stages) std::printf("    %-34s %3d it %8.3f s\n", s.name.c_str(), s.iterations, s.seconds);
  std::printf("    (stage 3's two starts are solved at once: their wall times overlap)\n");
  std::printf("  validation (6 runs) %8.3f s\n", t_val);
  std::printf("  reduction (5 speeds + blob + 26 h deviation run) %8.4f s\n", t_red);
  std::printf("  pipeline w/o inverse heat %8.3f s  baseline 30 s (incl. inverse) -> %.1fx faster\n", pipeline, 30.0 / pipeline);
  std::printf("  peak RSS            %8ld kB (before fit %ld kB)\n", rss_fit, rss0);
  std::printf("  fit rms %.5f K, quantized vs double %.6f K\n", fit.rms_K, red.deviation.quantized_vs_double_max_K);
  return 0;
}
