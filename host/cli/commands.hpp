#pragma once
// One registration function per area; each lives in host/cli/cmd_<area>.cpp.
#include <CLI/CLI.hpp>

namespace btsm::cli {
void register_rtd_commands(CLI::App& app);       // btsm rtd r2t|t2r
void register_link_commands(CLI::App& app);      // list scan info monitor record set-speed set-config get-config ack-alarm flash-model flash-firmware keys
void register_sysid_commands(CLI::App& app);     // fit validate reduce
void register_heat_commands(CLI::App& app);      // heat
void register_residual_commands(CLI::App& app);  // residual
void register_sim_commands(CLI::App& app);       // sim-module
void register_demo_commands(CLI::App& app);      // demo
void register_suite_commands(CLI::App& app);     // effect-suite
}  // namespace btsm::cli
