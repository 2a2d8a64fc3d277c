// btsm rtd r2t|t2r — Callendar–Van Dusen conversions (IEC 60751) with the same code the firmware
// runs (common/rtd.hpp), in double precision.
#include "cli_support.hpp"
#include "commands.hpp"
#include "common/rtd.hpp"
#include "host/io/decimal_number.hpp"
#include "host/io/utf8_text.hpp"

#include <fmt/core.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

namespace btsm::cli {
namespace {

// The R0 --r0 may give: from Pt10, the smallest platinum RTD made, to 1 MOhm, where the conversion
// still holds in double precision.
constexpr double kMinR0Ohm = 10.0, kMaxR0Ohm = 1e6;

struct RtdOptions {
  double r0_ohm = 1000.0;
  std::string r0_text = "1000";  // as typed, for the message
  bool json = false;
  std::vector<std::string> values;
};

// A value or --r0 as a recording's cell is read: decimal, finite, one too small for a double is 0.
bool read_reading(const std::string& text, double& out) {
  const auto v = io::decimal_number(text, io::TinyNumber::ReadAsNearest);
  if (v) out = *v;
  return v.has_value();
}

// A well-formed decimal number too large for a double (1e400): named as such, as a recording's cell is.
bool beyond_a_double(const std::string& text) {
  if (text.empty() || text.find_first_not_of("0123456789+-.eE ") != std::string::npos) return false;
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  return errno == ERANGE && std::isinf(v) && end != text.c_str();
}

enum class Direction { kResistanceToTemperature, kTemperatureToResistance };

void run(const RtdOptions& o, Direction dir) {
  // Platinum RTDs are made from Pt10 to Pt10000; beyond 1 MOhm the conversion overflows (inf), and
  // --r0 1e-300 was taken and printed every resistance as 0.0000 ohm.
  if (!std::isfinite(o.r0_ohm) || o.r0_ohm < kMinR0Ohm || o.r0_ohm > kMaxR0Ohm)
    throw CommandError(kExitUsage, fmt::format("--r0 must be a resistance in ohm in 10...1e6 (Pt10 to beyond Pt10000; 100 = "
                                               "Pt100, 1000 = Pt1000), got {}", io::printable(o.r0_text)));
  const RtdCoefficients<double> k = iec60751<double>(o.r0_ohm);
  const bool r2t = dir == Direction::kResistanceToTemperature;
  const char* in_unit = r2t ? "ohm" : "degC";

  // Convert everything first so that bad input produces one error naming every bad value and no
  // partial output.
  std::vector<double> results;
  std::vector<std::string> errors;
  for (size_t i = 0; i < o.values.size(); ++i) {
    const std::string& v = o.values[i];
    double x = 0.0;
    // decimal only ("0x3e8" is no resistance a user means); 1e-400 is 0, as in a recording
    if (!read_reading(v, x)) {
      errors.push_back(fmt::format("value #{} '{}' {} ({} expected)", i + 1, v, beyond_a_double(v) ? "is beyond the range of a number (+-1.8e308)" : "is not a number", in_unit));
      continue;
    }
    const RtdResult<double> r = r2t ? rtd_temperature(k, x) : rtd_resistance(k, x);
    if (!r.ok()) {
      const std::string range =
          r2t ? fmt::format("valid {:.4f}...{:.4f} ohm for R0 = {} ohm, -200...850 degC, read up to {:g} K beyond "
                            "as the firmware reads them",
                            rtd_resistance(k, -200.0).value, rtd_resistance(k, 850.0).value, o.r0_ohm,
                            static_cast<double>(kRtdInverseMarginC))
              : std::string("valid -200...850 degC");
      errors.push_back(fmt::format("value #{} '{}' {}: {} ({})", i + 1, v, in_unit, rtd_status_name(r.status), range));
      continue;
    }
    results.push_back(r.value);
  }
  if (!errors.empty()) {
    std::string msg = errors.front();
    for (size_t i = 1; i < errors.size(); ++i) msg += "; " + errors[i];
    throw CommandError(kExitUsage, msg);
  }
  if (o.json) {
    nlohmann::json arr = nlohmann::json::array();
    for (size_t i = 0; i < results.size(); ++i) {
      nlohmann::json e;
      e[r2t ? "resistance_ohm" : "temperature_c"] = std::strtod(o.values[i].c_str(), nullptr);
      e[r2t ? "temperature_c" : "resistance_ohm"] = results[i];
      arr.push_back(e);
    }
    print_json(nlohmann::json{{"r0_ohm", o.r0_ohm}, {"standard", "IEC 60751"}, {"results", arr}});
    return;
  }
  // 4 decimals: 0.1 mK / 0.1 mohm, finer than any table or measurement it is compared with.
  for (double r : results) fmt::print("{:.4f}\n", r);
}

void add_direction(CLI::App& rtd, const char* name, const char* help, Direction dir) {
  auto opts = std::make_shared<RtdOptions>();
  CLI::App* cmd = rtd.add_subcommand(name, help);
  // Read as the values are (1e-400 is 0, as in a recording), then refused by range.
  cmd->add_option_function<std::string>(
         "--r0",
         [opts](const std::string& text) {
           opts->r0_text = text;
           if (!read_reading(text, opts->r0_ohm))
             throw CLI::ValidationError("--r0", "'" + io::printable(text) + "' is not a number (ohm expected, 10...1e6)");
         },
         "resistance at 0 degC in ohm, 10...1e6 (100 = Pt100, 1000 = Pt1000; default 1000)");
  cmd->add_flag("--json", opts->json, "print {r0_ohm, standard, results:[{resistance_ohm, temperature_c}]} as JSON");
  cmd->add_option("values", opts->values,
                  dir == Direction::kResistanceToTemperature
                      ? "resistances in ohm"
                      : "temperatures in degC, -200...850")
      ->required();
  cmd->callback([opts, dir]() { run(*opts, dir); });
}

}  // namespace

void register_rtd_commands(CLI::App& app) {
  CLI::App* rtd = app.add_subcommand(
      "rtd",
      "Platinum RTD conversions, Callendar-Van Dusen with IEC 60751 coefficients (A = 3.9083e-3, "
      "B = -5.775e-7, C = -4.183e-12 below 0 degC), exact inverse over -200...850 degC");
  rtd->require_subcommand(1);
  add_direction(*rtd, "r2t",
                "resistance (ohm) -> temperature (degC), one result per line, 4 decimals; out-of-range "
                "or non-numeric input is an error naming the value (exit code 2)",
                Direction::kResistanceToTemperature);
  add_direction(*rtd, "t2r",
                "temperature (degC) -> resistance (ohm), one result per line, 4 decimals; out-of-range "
                "or non-numeric input is an error naming the value (exit code 2)",
                Direction::kTemperatureToResistance);
}

}  // namespace btsm::cli
