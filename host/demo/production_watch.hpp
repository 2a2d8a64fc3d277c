#pragma once
// Step 5 of the demo: follow the module's own diagnosis through normal running and a bearing
// fault, from its SAMPLE frames alone (the host only watches; the module decides).
#include "host/link/recorder.hpp"
#include "host/link/session.hpp"
#include "host/report/html_report.hpp"

#include <functional>
#include <string>
#include <vector>

namespace btsm::demo {

struct ProductionOptions {
  double start_s = 0;   // module time (s) the production profile starts; older samples are skipped
  double fault_s = 0;   // module time (s) the fault starts
  double end_s = 0;     // module time (s) to stop
  double fault_heat_w = 0;  // W, for the report text
  std::string out_dir;
  std::function<void(const std::string&)> progress;
};

struct ProductionResult {
  int false_alarms = 0;          // ALARM samples before the fault
  int warn_before_fault = 0;     // WARN samples before the fault (reported, not a failure)
  double fault_to_alarm_s = -1;  // s from fault start to the first ALARM; < 0 = never
  int alarm_channel = 0;         // 1-based channel that raised it
  std::vector<std::string> failures;
};

ProductionResult watch_production(link::Session& session, const link::ModuleIdentity& id,
                                  const ProductionOptions& opts, report::HtmlReport& page);

}  // namespace btsm::demo
