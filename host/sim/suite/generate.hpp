#pragma once
// Records one suite case the way a user records a real spindle: the simulated module (firmware
// core + register-level AD7794 with datasheet noise + the plant with the case's hidden effect,
// probe 5 on the shaft end with role `shaft`) is read over the wire protocol by the same session
// and recorder code as `btsm record`, one recording per run of the procedure (a fresh session per
// day, the overnight standstill not recorded). Declared extra columns (coolant temperature, cover
// events) come from a separate logger: they are merged into the recordings by module time and
// declared in the metadata (`# boundary_columns: coolant_c`, `# event_columns: lid_open`).
// The plant's true probe readings at every sample give the case's noise floor (what the
// recording differs from the truth by: AD7794 noise, quantisation, the module's Kalman filter).
#include "host/sim/suite/cases.hpp"

#include <string>
#include <vector>

namespace btsm::sim::suite {

struct GeneratedRun {
  std::string name, path;       // path relative to the case directory
  bool for_fit = true;
  double plant_start_s = 0;     // s, plant time of the first row
  size_t rows = 0;
  uint64_t lost = 0, rejected_frames = 0;
};

struct GeneratedCase {
  std::vector<GeneratedRun> runs;
  double noise_floor_fit_k = 0;    // K, RMSE recorded - true probe reading over the fit runs
  double noise_floor_check_k = 0;  // K, the same over the check run
  double wall_s = 0;
};

struct GenerateOptions {
  double coolant_logger_sigma_k = 0.01;  // K, noise of the separate coolant logger
};

// Writes the recordings and truth.json into `dir` (created). Throws std::runtime_error naming the
// case on failure (a lost sample is a failure: the suite must score the loop, not the link).
GeneratedCase generate_case(const SuiteCase& c, const std::string& dir, const GenerateOptions& opts = {});

// truth.json of a generated case: the case (cases.hpp to_json) plus the runs and noise floors.
nlohmann::json generated_json(const SuiteCase& c, const GeneratedCase& g);

}  // namespace btsm::sim::suite
