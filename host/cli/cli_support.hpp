#pragma once
// Shared plumbing for the btsm subcommands: error type with an exit code, JSON printing, and the
// common link options (--port / --ble / --usb) every device command takes.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <stdexcept>
#include <string>
#include <vector>

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

// " shaft=T5 (--column) ..." for the NODE=COLUMN pairs given with --column, appended to the roles
// line fit and residual print (it named only what the roles decided, so T5 seemed unused).
std::string given_columns(const std::vector<std::string>& columns);

// Adds to every floating-point option of `app` and its subcommands (registered so far) a check
// that refuses nan and inf (and numbers beyond double range): CLI11 converts "nan" to a double
// and its Range and PositiveNumber checks let it through, since every comparison with NaN is false.
// Integer options get one that refuses a number beyond their type (a seed of 1e20 digits was
// taken as 2^64-1).
void refuse_non_finite_numbers(CLI::App& app);

// CLI11's ExistingFile, with the cause when the file cannot be examined: a symbolic-link loop,
// a dangling link, a directory on the path that may not be entered (CLI11 said "File does not
// exist" for each).
CLI::Validator existing_input_file();

// CLI11's PositiveNumber / NonNegativeNumber, with a message a user can read ("must be > 0, got
// 0"), not "not in range 0.000000 to 1797...(300 digits)".
CLI::Validator positive_number();
CLI::Validator non_negative_number();

// A number typed as an argument or a list entry: decimal (spaces around it allowed), finite; no
// hex ("0x3e8" is not 1000 ohm to a user reading the command), no inf/nan. False if not.
bool parse_decimal(const std::string& text, double& out);

// "2000, 4000,6000" -> {2000, 4000, 6000}; CommandError (exit 2) naming `option` and the entry
// that is not a number, or an empty entry (",,", a trailing comma).
std::vector<double> number_list(const std::string& text, const std::string& option);

}  // namespace btsm::cli
