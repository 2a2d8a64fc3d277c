#pragma once
// Hook for the `btsm heat` subcommand (inverse heat-source estimation). Declared by the sysid
// area, implemented by the heat engineer in host/cli/sysid_heat_command.cpp. cmd_sysid.cpp calls
// it when that file exists (CMake defines BTSM_HAVE_HEAT_COMMAND).
#include <CLI/CLI.hpp>

namespace btsm::cli {
void register_heat_command(CLI::App& app);
}  // namespace btsm::cli
