#include "cli_support.hpp"

#include <cmath>
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
  cmd.add_option("--rfcomm-channel", opts.rfcomm_channel, "RFCOMM channel for --rfcomm")->capture_default_str();
  cmd.add_option("--timeout", opts.timeout_s, "reply timeout in seconds")->capture_default_str();
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
  for (CLI::Option* opt : app.get_options())
    if (opt->get_type_name().find("FLOAT") != std::string::npos) opt->check(finite);
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) refuse_non_finite_numbers(*sub);
}

}  // namespace btsm::cli
