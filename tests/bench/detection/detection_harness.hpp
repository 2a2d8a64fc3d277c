#pragma once
// The detection benchmark: how fast the module itself flags real faults, and how often it flags
// normal running, with a model that came through the whole toolchain.
//
//   1. Commissioning exactly as the demo does it (host/demo/commission.hpp): the simulated module
//      (the real AVR image in simavr, or the native firmware core) records the identification
//      procedure over its link; the host fits, validates, runs the residual loop, reduces with
//      calibrated bands, and flashes the blob with authentication. The link is in-process
//      (host/demo/in_process_link.hpp): one thread, deterministic.
//   2. The machine stands still for `soak_h` (cold), then runs a varied production profile
//      (production_profile.hpp) fault-free: false WARN and ALARM episodes are counted (an ALARM is
//      acknowledged by the host right away, as an operator would, so a later one counts again).
//   3. At each chosen moment of that run the process forks once per fault (`jobs` at a time): the child continues the
//      identical simulated history with the fault injected (extra heat at a bearing, or an open
//      probe) and reports when the module first showed WARN, ALARM or SENSOR_FAULT, on which
//      channel; the parent goes on fault-free. So every fault starts from exactly the state the
//      fault-free run had at that moment.
// Times are module time from the fault's start to the first SAMPLE showing the state (5 s steps).
// The plant keeps a bearing fault's heat while the spindle stands still (conservative: a damaged
// bearing heats only when it turns); every fault stays until the end of its window.
#include "host/sim/plant/faults.hpp"
#include "host/sim/runner/sim_module.hpp"
#include "tests/bench/detection/production_profile.hpp"

#include <functional>
#include <string>
#include <vector>

namespace btsm::bench {

struct DetectionOptions {
  sim::BoardKind board = sim::BoardKind::Avr;
  std::string elf_path;                       // avr: the image (btsm-fw-bluno.elf)
  std::string out_dir;                        // commissioning artefacts, report page, detection.csv
  bool quick_identification = false;          // the demo's shorter procedure (tests)
  std::string effect = "bearing-tc:0.015";    // hidden plant effect, as in the demo
  ProductionProfileOptions profile;
  double soak_h = 3;                          // h stopped between commissioning and production
  std::vector<double> heats_w{10, 20, 30};    // W, bearing faults
  std::vector<sim::BearingPlace> places{sim::BearingPlace::Rear, sim::BearingPlace::Front};
  std::vector<int> open_probe_channels{1, 3}; // sensor faults: open probe on these channels
  std::vector<MomentKind> kinds{MomentKind::ColdStart, MomentKind::Restart, MomentKind::StepUp,
                                MomentKind::StepDown, MomentKind::Steady};
  int moments_per_kind = 2;
  double window_h = 3;                        // h watched after a bearing fault (no ALARM: "> window")
  double sensor_window_h = 0.5;               // h watched after a sensor fault
  int jobs = 1;                               // fault runs (forked children) at a time; the results
                                              // do not depend on it, only the wall time does
  std::function<void(const std::string&)> progress;
};

// Diagnosis states as the wire carries them (common/diagnosis.hpp DiagState).
enum : int { kNormal = 0, kWarn = 1, kAlarm = 2, kSensorFault = 3 };

struct FaultRun {
  std::string fault;        // "bearing 30 W" or "open probe"
  std::string place;        // "rear", "front", "ch1", ...
  ProfileMoment moment;
  int state_before = 0;     // worst thermal-channel state (WARN/ALARM) on the sample before the fault
  double window_s = 0;
  double warn_s = -1;       // s from the fault's start to the first WARN or ALARM; -1 = none in the window
  double alarm_s = -1;      // s to the first ALARM; -1 = none
  double sensor_s = -1;     // s to the first SENSOR_FAULT; -1 = none
  int warn_channel = 0, alarm_channel = 0, sensor_channel = 0;  // 1-based
  bool ok = false;          // the child ran to its end
  std::string error;
};

struct FaultFreeRun {
  double hours = 0;
  long samples = 0;
  int warn_episodes = 0;    // entries of a thermal channel into WARN (from NORMAL)
  int alarm_episodes = 0;   // entries into ALARM
  long warn_samples = 0, alarm_samples = 0;  // samples with some channel in that state
  long sensor_fault_samples = 0;
  std::vector<std::string> episodes;  // "12.3 h ALARM ch2", ...
};

struct DetectionResult {
  std::string board;
  std::string profile;               // ProductionProfile::describe()
  double drift_K[5] = {};            // the flashed model's calibrated detector: drift above the model, K
  double alarm_evidence_K_min[5] = {};  // and its ALARM evidence threshold, K min (0: not diagnosed)
  std::vector<FaultRun> faults;
  FaultFreeRun fault_free;
  double wall_s = 0;
  double cpu_s = 0;                  // user + system, this process and its fault runs
  // Every fault run, one line each.
  std::string runs_table() const;
  // Per fault and place: WARN/ALARM time (median, range), detected n/N, channels.
  std::string summary_table() const;
  std::string fault_free_line() const;
};

// Throws std::runtime_error when commissioning fails (the step is named).
DetectionResult run_detection(const DetectionOptions& o);

}  // namespace btsm::bench
