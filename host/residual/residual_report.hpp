#pragma once
// Output of the residual loop: a plain-text table, JSON, and plots into a report directory.
#include "host/io/output_file.hpp"
#include "host/residual/residual_loop.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace btsm::residual {

// Human-readable summary (what was tested, candidates, verdict, before/after errors).
std::string format_table(const LoopResult& r);

// Machine-readable result; keys documented in the README ("btsm residual --json").
nlohmann::json to_json(const LoopResult& r);

// Writes residual_result.json, residual_model.png/.svg (measured vs base vs augmented, check
// recordings), residual_residuals.png/.svg (before/after, and the measurement distortion of a
// sensor-side effect), residual_heat_trace.png/.svg (unexplained heat flow per node) into `dir`.
// `check` must be the recordings the loop was checked on; `trace_recording`, when given, the first
// fit recording the heat trace ran on (its name goes into the title, its speed into a panel).
// Throws std::runtime_error on I/O errors.
void write_report(const LoopResult& r, const std::vector<thermal::Recording>& check, const std::string& dir,
                  const thermal::Recording* trace_recording = nullptr);

// The files write_report may write into its directory, for the check of the place before the loop.
std::vector<io::OutputName> report_files();

}  // namespace btsm::residual
