#pragma once
// Shared plumbing for the btsm subcommands: error type with an exit code, JSON printing, and the
// common link options (--port / --ble / --usb) every device command takes.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <stdexcept>
#include <string>

namespace btsm::cli {

// Thrown by a command's action; main() prints "btsm <command>: <message>" and exits with `code`.
struct CommandError : std::runtime_error {
  CommandError(int code_, const std::string& what) : std::runtime_error(what), code(code_) {}
  int code;
};

enum ExitCode : int {
  kExitOk = 0,
  kExitFailure = 1,   // the operation ran and failed (verification, test, fit did not converge)
  kExitUsage = 2,     // bad arguments or unreadable input
  kExitDevice = 3,    // no device, permission denied, link lost
};

// Print JSON to stdout, two-space indented, with a trailing newline.
void print_json(const nlohmann::json& j);

// The options that select a module link; every device command adds these.
struct LinkOptions {
  std::string port;     // serial device or pty path
  std::string ble;      // BLE address AA:BB:CC:DD:EE:FF
  std::string rfcomm;   // classic Bluetooth address (SPP modules)
  std::string usb;      // VID:PID of a USB-serial adapter
  int rfcomm_channel = 1;
  double timeout_s = 2.0;
};
void add_link_options(CLI::App& cmd, LinkOptions& opts);

// Adds to every floating-point option of `app` and its subcommands (registered so far) a check
// that refuses nan and inf (and numbers beyond double range): CLI11 converts "nan" to a double
// and its Range and PositiveNumber checks let it through, since every comparison with NaN is false.
void refuse_non_finite_numbers(CLI::App& app);

}  // namespace btsm::cli
