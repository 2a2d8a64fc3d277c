#include "host/thermal/sensor_faults.hpp"

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

std::vector<SensorFaultEpisode> sensor_faults(const Recording& rec) {
  std::vector<SensorFaultEpisode> out;
  for (const auto& [key, value] : rec.meta) {
    if (key != kSensorFaultKey) continue;
    auto bad = [&](const char* what) {
      return std::invalid_argument(rec.source + ": '# " + key + ": " + value + "': " + what +
                                   " (expected '# sensor_fault: T2 open 1200.0-1500.0')");
    };
    std::istringstream in(value);
    SensorFaultEpisode e;
    std::string range, extra;
    if (!(in >> e.channel >> e.code >> range) || (in >> extra)) throw bad("not CHANNEL CODE FROM-TO");
    if (e.channel.size() < 2 || e.channel[0] != 'T') throw bad("the channel is not T<number>");
    const auto dash = range.find('-', 1);  // a time is never negative, but skip a leading sign anyway
    if (dash == std::string::npos) throw bad("the range is not FROM-TO");
    const std::string from = range.substr(0, dash), to = range.substr(dash + 1);
    char* end = nullptr;
    e.from_s = std::strtod(from.c_str(), &end);
    if (from.empty() || *end != '\0') throw bad("FROM is not a number");
    e.to_s = std::strtod(to.c_str(), &end);
    if (to.empty() || *end != '\0') throw bad("TO is not a number");
    if (!std::isfinite(e.from_s) || !std::isfinite(e.to_s) || e.to_s < e.from_s) throw bad("the range runs backwards");
    out.push_back(e);
  }
  return out;
}

}  // namespace btsm::thermal
