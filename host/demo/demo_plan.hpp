#pragma once
// What the demo asks of the simulated spindle: the paper's identification procedure (warm-ups at
// several speeds, each followed by natural cooling, then a stepwise external-validation run) and
// the production phase (changing speeds, then a bearing fault). Durations are simulated time.
#include "host/sim/plant/profile.hpp"

#include <string>
#include <vector>

namespace btsm::demo {

struct PlannedRun {
  std::string name;                       // file stem of the recording
  std::vector<sim::SpeedSegment> segments;
  bool for_fit = true;                    // false: external validation (check) run
  double duration_s() const;
};

struct DemoPlan {
  std::vector<PlannedRun> identification;  // recorded back to back, in order
  std::vector<sim::SpeedSegment> production;
  double fault_after_s = 0;               // s into production when the bearing fault starts
  double fault_heat_w = 0;                // W of extra heat at the rear bearing
  std::vector<double> reduce_speeds_rpm;  // breakpoints of the firmware model (besides 0 rpm)
};

// quick = a shorter procedure for tests (fewer and shorter runs).
DemoPlan make_demo_plan(bool quick);

}  // namespace btsm::demo
