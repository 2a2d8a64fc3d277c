#pragma once
// The paper's identification procedure on the simulated spindle (Lo, Hu & Chang 2018, Sect. 4):
// warm-ups from a cold machine at several speeds, each followed by natural cooling, for the fit;
// a stepwise run at speeds the fit never saw for the check. Between recordings the machine stands
// overnight (not recorded), so every run starts close to ambient as in the paper, where each
// experiment was a separate day.
#include "host/sim/plant/profile.hpp"

#include <string>
#include <vector>

namespace btsm::sim::suite {

struct ProcedureRun {
  std::string name;                    // file stem of the recording
  std::vector<SpeedSegment> segments;  // recorded
  bool for_fit = true;                 // false: the check (external validation) run
  double start_s = 0;                  // s of plant time when the recording starts
  double duration_s() const;
};

struct Procedure {
  std::vector<ProcedureRun> runs;      // in plant-time order
  double total_s = 0;                  // s of plant time incl. the idle gaps
  SpeedProfile speed() const;          // the whole plant speed profile (gaps at 0 rpm)
};

enum class ProcedureSize {
  Full,     // 5 warm-ups 4000..8000 rpm of 6 h + 4 h cooling; check 3 x 2 h + 3 h cooling (the paper)
  Reduced,  // 3 warm-ups 4000/6000/8000 rpm of 4 h + 3 h cooling; check 3 x 1.5 h + 3 h (for ctest)
};

struct ProcedureOptions {
  ProcedureSize size = ProcedureSize::Full;
  double speed_jitter_rpm = 40;        // rpm, each nominal speed +- up to this (uniform)
  double idle_gap_s = 12 * 3600.0;     // s of standstill before every recording after the first
  double lead_in_s = 600;              // s of standstill before the first recording
};

// `rng_seed` draws the speed jitter (the paper's speeds were not round either: 4006 .. 8028 rpm).
Procedure make_procedure(const ProcedureOptions& opts, unsigned rng_seed);

}  // namespace btsm::sim::suite
