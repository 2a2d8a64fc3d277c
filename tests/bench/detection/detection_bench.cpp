// The detection benchmark (`cmake --build build --target bench_detection`): the module's own time
// to WARN and ALARM for bearing faults of 10, 20 and 30 W at the rear and front bearing and for an
// open probe, injected at moments of a varied 48 h production profile, and its false WARN/ALARM
// episodes on the fault-free run; the model comes through the whole toolchain
// (detection_harness.hpp). Prints figures; asserts nothing.
//   detection_bench [--board avr|native] [--elf PATH] [--out DIR] [--quick] [--hours H]
//                   [--moments N] [--window-h H] [--seed S] [--jobs N]
#include "tests/bench/detection/detection_harness.hpp"

#include <fmt/core.h>

#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>

int main(int argc, char** argv) {
  using namespace btsm;
  bench::DetectionOptions o;
  o.elf_path = std::string(BTSM_BIN_DIR) + "/btsm-fw-bluno.elf";
  o.out_dir = "bench-detection";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* what) -> std::string {
      if (i + 1 >= argc) {
        std::cerr << a << ": missing " << what << "\n";
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--board") o.board = sim::parse_board_kind(value("avr|native"));
    else if (a == "--elf") o.elf_path = value("path");
    else if (a == "--out") o.out_dir = value("folder");
    else if (a == "--quick") o.quick_identification = true;
    else if (a == "--hours") o.profile.hours = std::stod(value("hours"));
    else if (a == "--moments") o.moments_per_kind = std::stoi(value("moments per kind"));
    else if (a == "--window-h") o.window_h = std::stod(value("hours"));
    else if (a == "--seed") o.profile.seed = static_cast<uint32_t>(std::stoul(value("seed")));
    else if (a == "--jobs") o.jobs = std::stoi(value("fault runs at a time"));
    else {
      std::cerr << "unknown argument " << a << "\n";
      return 2;
    }
  }
  o.progress = [](const std::string& s) { std::cerr << "[detection] " << s << std::endl; };
  try {
    const bench::DetectionResult r = bench::run_detection(o);
    std::printf("== detection benchmark (%s board, %s identification, %.0f s wall)\n", r.board.c_str(),
                o.quick_identification ? "quick" : "full", r.wall_s);
    std::printf("-- production profile (seed %u): %s\n", o.profile.seed, r.profile.c_str());
    std::printf("-- calibrated detector, drift (K) / ALARM evidence (K min): T1 %.2f / %.1f, T2 %.2f / %.1f, "
                "T3 %.2f / %.1f, T5 %.2f / %.1f\n",
                r.drift_K[0], r.alarm_evidence_K_min[0], r.drift_K[1], r.alarm_evidence_K_min[1], r.drift_K[2],
                r.alarm_evidence_K_min[2], r.drift_K[4], r.alarm_evidence_K_min[4]);
    std::printf("-- every fault run\n%s", r.runs_table().c_str());
    std::printf("-- per fault and place\n%s", r.summary_table().c_str());
    std::printf("-- %s\n", r.fault_free_line().c_str());
    std::printf("-- targets: 30 W -> ALARM <= 10 min, 10 W -> <= 30 min, fault-free: zero WARN and ALARM\n");
    std::printf("-- cost: %.0f s wall, %.0f s CPU (%d fault runs at a time)\n", r.wall_s, r.cpu_s, o.jobs);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "detection benchmark failed: %s\n", e.what());
    return 1;
  }
  return 0;
}
