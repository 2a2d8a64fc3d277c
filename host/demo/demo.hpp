#pragma once
// The closed-loop demo on the simulated module (README's main command):
//   1. start the simulated module (the real AVR image in simavr, or the native firmware core),
//      whose spindle has one effect the paper's model lacks, not announced to the host side;
//   2. record the identification procedure over the module's serial link;
//   3. fit the full model, validate it (self and external), run the residual loop;
//   4. reduce to the speed-scheduled first-order model, flash it with authentication, verify;
//   5. production: changing speeds (NORMAL expected), then a bearing fault the module must ALARM on;
//   6. write a report folder (recordings, models, plots, index.html) and say where it is.
// Exits non-zero when any step fails or a check does not hold.
#include <string>

namespace btsm::demo {

struct DemoOptions {
  std::string out_dir = "report";   // report folder (created; existing files are replaced)
  std::string board = "avr";        // "avr" (real image in simavr) or "native"
  std::string elf_path;             // default: btsm-fw-bluno.elf next to the btsm executable
  std::string effect = "bearing-tc:0.015";  // hidden plant effect (sim-module --effect syntax)
  bool quick = false;               // shorter procedure (tests)
};

struct DemoSummary {
  bool ok = false;
  std::string failure;              // first failed step, when !ok
  double wall_s = 0;
};

// Throws std::invalid_argument naming the option when the demo could not run with `opts` (an
// --effect the plant does not know, an --elf that is no AVR image, an --out that is a file):
// checked before run_demo() creates the report folder or a key.
void check_demo_options(const DemoOptions& opts);

DemoSummary run_demo(const DemoOptions& opts);

}  // namespace btsm::demo
