#pragma once
// Step 3 and 4 of the demo on the host side: fit, validation, residual loop and reduction, each
// through the same library calls the CLI commands use, with their figures and plots added to the
// report page.
#include "host/demo/demo_plan.hpp"
#include "host/thermal/detector_calibration.hpp"
#include "host/report/html_report.hpp"

#include "common/model_blob.hpp"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace btsm::demo {

struct AnalysisInputs {
  std::vector<std::string> fit_csv;     // identification runs
  std::vector<std::string> check_csv;   // external validation runs
  std::string out_dir;                  // report folder
  std::vector<double> reduce_speeds_rpm;
  double sample_period_s = 5.0;         // the module's sample period (the reduced model's dt)
  thermal::DetectorRule detector_rule;  // how the module's detector is calibrated on the recordings
  std::function<void(const std::string&)> progress;
};

struct AnalysisOutputs {
  std::string model_json;               // full fitted model (base + the effect found, if any)
  std::string reduced_json;             // speed-scheduled first-order model
  std::vector<uint8_t> blob;            // the firmware blob to flash
  std::string effect;                   // what the residual loop found ("none", "unexplained", ...)
  std::vector<std::string> effect_nodes;
  double check_rmse_before_K = 0, check_rmse_after_K = 0;
  double quantized_vs_full_max_K = 0;   // measured deviation of the flashed model, worst channel
  double deviation_vs_full_K[5] = {};   // K, per channel (0 = not modelled)
  double worst_residual_K[5] = {};      // K, per diagnosed channel, on the recordings
  double drift_K[5] = {};               // K, calibrated detector per diagnosed channel
  double alarm_evidence_K_min[5] = {};  // K min
  std::vector<std::string> failures;    // checks that did not hold
};

AnalysisOutputs analyse(const AnalysisInputs& in, report::HtmlReport& page);

}  // namespace btsm::demo
