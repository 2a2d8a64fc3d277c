#include "host/thermal/sensor_faults.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

namespace btsm::thermal {

std::string format_sensor_fault(const SensorFaultEpisode& e) {
  char range[80];
  std::snprintf(range, sizeof range, "%.3f-%.3f", e.from_s, e.to_s);
  return e.channel + " " + e.code + " " + range;
}

namespace {

// "open", "short", "adc", "ref" joined by '+' (each once), or "fault" alone: what the recorder writes.
bool known_fault_code(const std::string& code) {
  if (code == "fault") return true;
  static const char* kBits[] = {"open", "short", "adc", "ref"};
  std::vector<std::string> seen;
  std::size_t start = 0;
  while (true) {
    const std::size_t plus = code.find('+', start);
    const std::string part = code.substr(start, plus == std::string::npos ? std::string::npos : plus - start);
    if (std::find(std::begin(kBits), std::end(kBits), part) == std::end(kBits)) return false;
    if (std::find(seen.begin(), seen.end(), part) != seen.end()) return false;
    seen.push_back(part);
    if (plus == std::string::npos) return true;
    start = plus + 1;
  }
}

bool module_channel(const std::string& ch) { return ch.size() == 2 && ch[0] == 'T' && ch[1] >= '1' && ch[1] <= '5'; }

// A finite decimal time ("nan", "inf", hex and trailing text are not).
bool read_time(const std::string& text, double& out) {
  if (text.empty() || text.find_first_not_of("0123456789+-.eE") != std::string::npos) return false;
  char* end = nullptr;
  out = std::strtod(text.c_str(), &end);
  return *end == '\0' && std::isfinite(out);
}

}  // namespace

std::string parse_sensor_fault(const std::string& value, SensorFaultEpisode& e) {
  std::istringstream in(value);
  std::string range, extra;
  if (!(in >> e.channel >> e.code >> range) || (in >> extra)) return "not CHANNEL CODE FROM-TO";
  if (!module_channel(e.channel)) return "'" + e.channel + "' is not a module channel (T1..T5)";
  if (!known_fault_code(e.code))
    return "unknown fault code '" + e.code + "' (open, short, adc, ref, joined with '+' when several; or fault)";
  const auto dash = range.find('-', 1);  // a time is never negative, but skip a leading sign anyway
  if (dash == std::string::npos) return "the range is not FROM-TO";
  if (!read_time(range.substr(0, dash), e.from_s)) return "FROM is not a finite number";
  if (!read_time(range.substr(dash + 1), e.to_s)) return "TO is not a finite number";
  if (e.to_s < e.from_s) return "the range runs backwards";
  return "";
}

std::string sensor_fault_line_problem(const std::string& value) {
  SensorFaultEpisode e;
  const std::string why = parse_sensor_fault(value, e);
  return why.empty() ? "" : why + " (expected '# sensor_fault: T2 open 1200.0-1500.0')";
}

std::vector<SensorFaultEpisode> sensor_faults(const Recording& rec) {
  std::vector<SensorFaultEpisode> out;
  for (const auto& [key, value] : rec.meta) {
    if (key != kSensorFaultKey) continue;
    SensorFaultEpisode e;
    if (const std::string why = parse_sensor_fault(value, e); !why.empty())
      throw std::invalid_argument(rec.source + ": '# " + key + ": " + value + "': " + why +
                                  " (expected '# sensor_fault: T2 open 1200.0-1500.0')");
    out.push_back(e);
  }
  return out;
}

}  // namespace btsm::thermal
