#pragma once
// "Nice" axis ranges and tick positions (1, 2, 5 × 10^k steps), linear and logarithmic.
#include <string>
#include <vector>

namespace btsm::report {

struct AxisTicks {
  double lo = 0, hi = 1;          // axis range after rounding outward to the tick step
  std::vector<double> values;     // tick positions inside [lo, hi]
  std::vector<std::string> labels;
};

// data_lo/data_hi may be equal or non-finite; a sensible range is produced anyway.
AxisTicks linear_ticks(double data_lo, double data_hi, int target_count = 6);
// Decades covering [data_lo, data_hi] (both > 0).
AxisTicks log_ticks(double data_lo, double data_hi);

}  // namespace btsm::report
