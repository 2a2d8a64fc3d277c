#pragma once
// A stop phase's time constant as people read it. The reduction fits a node's free response after
// a stop with a pole clamped at >= 3e-8 1/s; a node that does not fall in that phase (it is warmed
// by its neighbours, e.g. a bearing next to the hotter housing) gets the clamp, 3.3e7 s, which
// printed as "555555.6 min" reads like a year-long time constant.
#include <fmt/format.h>

#include <string>

namespace btsm::thermal {

inline constexpr double kNoCoolingTimeConstantS = 1e7;  // s (~116 days): beyond it, "does not cool"

// "84.5" (minutes, one decimal) or "does not cool".
inline std::string stop_time_constant_text(double tau_s) {
  if (!(tau_s < kNoCoolingTimeConstantS)) return "does not cool";
  return fmt::format("{:.1f}", tau_s / 60.0);
}

}  // namespace btsm::thermal
