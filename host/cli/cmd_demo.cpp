// btsm demo — the closed-loop story on the simulated module (the README's main command).
#include "cli_support.hpp"
#include "commands.hpp"
#include "host/demo/demo.hpp"

#include <fmt/core.h>

#include <iostream>

namespace btsm::cli {

void register_demo_commands(CLI::App& app) {
  auto opts = std::make_shared<demo::DemoOptions>();
  auto* cmd = app.add_subcommand(
      "demo",
      "Run the closed-loop demo on the simulated module: record the identification procedure over the module's "
      "serial link, fit and validate the full thermal model, find the effect the model lacks, reduce, flash with "
      "authentication, then watch the module raise ALARM on a bearing fault. Writes a report folder.");
  cmd->add_option("--out", opts->out_dir, "report folder (index.html, recordings, models, plots)")->capture_default_str();
  cmd->add_option("--board", opts->board, "avr: the real firmware image in simavr; native: the firmware core built for the host")
      ->check(CLI::IsMember({"avr", "native"}))->capture_default_str();
  cmd->add_option("--elf", opts->elf_path, "firmware image for --board avr (default: btsm-fw-bluno.elf next to btsm)");
  cmd->add_option("--effect", opts->effect, "hidden plant effect, as `btsm sim-module --effect`")->capture_default_str();
  cmd->add_flag("--quick", opts->quick, "shorter identification and production phases (for tests)");
  cmd->callback([opts] {
    try {
      demo::check_demo_options(*opts);
    } catch (const std::invalid_argument& e) {
      throw CommandError(kExitUsage, e.what());
    }
    const demo::DemoSummary s = demo::run_demo(*opts);
    if (!s.ok) throw CommandError(kExitFailure, "demo failed at " + s.failure);
    std::cout << fmt::format("demo finished in {:.0f} s; report: {}/index.html\n", s.wall_s, opts->out_dir);
  });
}

}  // namespace btsm::cli
