#pragma once
// Step 3 and 4 of the demo on the host side: fit, validation, residual loop and reduction, each
// through the same library calls the CLI commands use, with their figures and plots added to the
// report page.
#include "host/demo/demo_plan.hpp"
#include "host/report/html_report.hpp"

#include "common/reduced_model.hpp"

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
  double band_margin = 1.5;             // ALARM band = margin x worst residual on the recordings
  double band_floor_K = 1.0;            // ALARM band never below this, K
  std::function<void(const std::string&)> progress;
};

struct AnalysisOutputs {
  std::string model_json;               // full fitted model (base + the effect found, if any)
  std::string reduced_json;             // speed-scheduled first-order model
  std::vector<uint8_t> blob;            // the firmware blob to flash
  std::string effect;                   // what the residual loop found ("none", "unexplained", ...)
  std::vector<std::string> effect_nodes;
  double check_rmse_before_K = 0, check_rmse_after_K = 0;
  double quantized_vs_full_max_K = 0;   // measured deviation of the flashed model
  double alarm_band_K[kModelChannels] = {};  // per channel, calibrated on the recordings (0 = not diagnosed)
  std::vector<std::string> failures;    // checks that did not hold
};

AnalysisOutputs analyse(const AnalysisInputs& in, report::HtmlReport& page);

}  // namespace btsm::demo
