#pragma once
// Steps 1-4 of the demo, shared by `btsm demo` and the detection benchmark
// (tests/bench/detection): the simulated module the demo commissions (the paper's spindle with a
// hidden effect the host side is not told, the probe on the shaft end, a device key), and its
// commissioning over a session with that module -- the identification procedure recorded over the
// module's link, fit + validation + residual loop + reduction with calibrated bands
// (demo_analysis.hpp), and the blob flashed with authentication, read back and verified.
#include "host/demo/demo_analysis.hpp"
#include "host/demo/demo_plan.hpp"
#include "host/link/device_keys.hpp"
#include "host/link/model_flash.hpp"
#include "host/link/recorder.hpp"
#include "host/link/session.hpp"
#include "host/report/html_report.hpp"
#include "host/sim/runner/sim_module.hpp"

#include <cstdint>
#include <functional>
#include <string>

namespace btsm::demo {

// The demo module's key: a fresh random key for `device_id`, kept in `out_dir`/keys like
// `btsm keys` does (the module refuses models not authenticated with it).
struct ModuleKey {
  uint32_t device_id = 0x0000B75Du;
  link::DeviceKey key{};
};
ModuleKey make_module_key(const std::string& out_dir);

// The simulated module of the demo, without a link (the caller adds a pty or links in-process):
// the spindle runs the identification procedure of `plan`, then idles until production; `effect`
// is hidden in the plant (sim-module --effect syntax); the module holds `key`'s record.
sim::SimModuleOptions demo_module_options(const DemoPlan& plan, const std::string& effect, const ModuleKey& key);

struct Commissioned {
  link::ModuleIdentity id;
  AnalysisOutputs analysis;
  link::FlashSummary flash;
};

// Where commissioning writes and reports: recordings/ and models/ under out_dir, the report
// page's sections, progress lines, and the step being run (for the caller's error message).
struct CommissionIo {
  std::string out_dir;
  std::string board_kind;  // "avr" or "native", for the report
  report::HtmlReport* page = nullptr;
  std::string* step = nullptr;
  std::function<void(const std::string&)> say;
};

// Identifies the module, records `plan`'s identification runs, fits, validates, runs the residual
// loop, reduces with calibrated bands, and flashes the blob with `key` (read back and verified).
// Throws std::runtime_error when a step fails or one of its checks does not hold.
Commissioned commission_module(link::Session& session, const DemoPlan& plan, const ModuleKey& key,
                               const CommissionIo& io);

}  // namespace btsm::demo
