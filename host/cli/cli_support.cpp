#include "cli_support.hpp"
#include "host/io/decimal_number.hpp"
#include "host/io/input_file.hpp"
#include "host/io/utf8_text.hpp"

#include <sys/stat.h>

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <iostream>

namespace btsm::cli {

void print_json(const nlohmann::json& j) { std::cout << j.dump(2) << "\n"; }

void add_link_options(CLI::App& cmd, LinkOptions& opts) {
  auto* port = cmd.add_option("--port", opts.port, "serial port or pty of the module (/dev/ttyACM0, /dev/rfcomm0, /dev/pts/N)");
  auto* ble = cmd.add_option("--ble", opts.ble, "BLE address of the module (AA:BB:CC:DD:EE:FF)");
  auto* rf = cmd.add_option("--rfcomm", opts.rfcomm, "classic Bluetooth (SPP) address of the module");
  auto* usb = cmd.add_option("--usb", opts.usb, "USB adapter VID:PID; its tty is used");
  port->excludes(ble)->excludes(rf)->excludes(usb);
  ble->excludes(rf)->excludes(usb);
  rf->excludes(usb);
  cmd.add_option("--rfcomm-channel", opts.rfcomm_channel, "RFCOMM channel for --rfcomm (1..30)")
      ->check(CLI::Range(1, 30))  // the RFCOMM server channels Bluetooth defines
      ->capture_default_str();
  cmd.add_option("--timeout", opts.timeout_s, "reply timeout in seconds (0.01..3600)")
      ->check(CLI::Range(0.01, 3600.0))
      ->capture_default_str();
}

void refuse_non_finite_numbers(CLI::App& app) {
  // Empty description: the option's help text stays as it is.
  const CLI::Validator finite(
      [](std::string& text) -> std::string {
        const char* begin = text.c_str();
        char* end = nullptr;
        const double v = std::strtod(begin, &end);  // 1e999 overflows to inf
        if (end == begin) return {};  // not a number at all: the option's own conversion says so
        if (!std::isfinite(v)) return "'" + text + "' is not a finite number";
        return {};
      },
      "", "finite number");
  const CLI::Validator representable(
      [](std::string& text) -> std::string {
        const char* begin = text.c_str();
        char* end = nullptr;
        errno = 0;
        (void)std::strtold(begin, &end);
        if (end == begin) return {};  // the option's own conversion names it
        const long double v = std::strtold(begin, nullptr);
        if (v > static_cast<long double>(UINT64_MAX) || v < static_cast<long double>(INT64_MIN))
          return "'" + text + "' is beyond the range of whole numbers this option takes";
        return {};
      },
      "", "representable integer");
  // `--truth-out ''` wrote nothing and `flash-firmware --out ''` took the default name, silently: a
  // value typed as empty is a mistake (an unset shell variable), never a choice; leave the option out.
  const CLI::Validator not_empty(
      [](std::string& text) -> std::string {
        if (text.find_first_not_of(" \t") != std::string::npos) return {};
        return "an empty value (an unset variable?); leave the option out for its default";
      },
      "", "non-empty");
  for (CLI::Option* opt : app.get_options()) {
    const std::string type = opt->get_type_name();
    if (opt->get_type_size() != 0) opt->check(not_empty);  // every option with a value (numbers: '' read as 0); not flags
    if (type.find("FLOAT") != std::string::npos) opt->check(finite);
    else if (type.find("INT") != std::string::npos) opt->check(representable);
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) refuse_non_finite_numbers(*sub);
}

namespace {
CLI::Validator bound_check(bool strict, const char* name) {
  return CLI::Validator(
      [strict](std::string& text) -> std::string {
        const char* begin = text.c_str();
        char* end = nullptr;
        const double v = std::strtod(begin, &end);
        if (end == begin) return {};  // not a number: the option's own conversion says so
        if (strict ? v > 0 : v >= 0) return {};
        return std::string("must be ") + (strict ? "> 0" : ">= 0") + ", got " + text;
      },
      "", name);
}
}  // namespace

CLI::Validator existing_input_file() {
  return CLI::Validator(
      [](std::string& path) -> std::string {
        struct stat st {};
        // The parser prints this as it is: the path escaped here (a newline in it forged a line).
        if (::stat(path.c_str(), &st) == 0) return S_ISDIR(st.st_mode) ? "File is actually a directory: " + io::printable(path) : "";
        const int err = errno;
        const std::string why = io::open_failure_reason(path, err);
        if (err == ENOENT && why == "no such file or directory")
          return "File does not exist: " + io::printable(path);  // CLI11's words, which scripts may look for
        return io::printable(path) + ": " + io::printable(why);
      },
      "FILE", "existing input file");
}

CLI::Validator positive_number() { return bound_check(true, "positive number"); }
CLI::Validator non_negative_number() { return bound_check(false, "non-negative number"); }

bool parse_decimal(const std::string& text, double& out) {
  const auto v = io::decimal_number(text);
  if (v) out = *v;
  return v.has_value();
}

std::vector<double> number_list(const std::string& text, const std::string& option) {
  std::vector<double> v;
  if (text.empty()) return v;  // the option left at its default; the caller says whether that is enough
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = text.find(',', start);
    const std::string tok = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    double x = 0;
    if (tok.find_first_not_of(" \t") == std::string::npos)
      throw CommandError(kExitUsage, option + " '" + text + "': an empty entry (a doubled or trailing comma)");
    if (!parse_decimal(tok, x)) throw CommandError(kExitUsage, option + ": '" + tok + "' is not a number");
    v.push_back(x);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return v;
}

std::string given_columns(const std::vector<std::string>& columns) {
  std::string s;
  for (const auto& c : columns) s += " " + c + " (--column)";
  return s;
}

}  // namespace btsm::cli
