// btsm list | scan | info | monitor | record | set-speed | set-config | get-config | ack-alarm | flash-model |
// flash-firmware | keys -- talking to a module. The logic lives in host/link/; the command groups
// (cmd_link_<group>.cpp) parse options, print, and map errors onto exit codes
// (cmd_link_support.hpp).
#include "cmd_link_support.hpp"
#include "commands.hpp"

namespace btsm::cli {

void register_link_commands(CLI::App& app) {
  register_link_discovery_commands(app);
  register_link_live_commands(app);
  register_link_control_commands(app);
  register_link_model_commands(app);
  register_link_firmware_commands(app);
}

}  // namespace btsm::cli
