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
// The axis runs exactly over [data_lo, data_hi] (a time axis ends where the data end); ticks at
// the nice steps inside it.
AxisTicks linear_ticks_within(double data_lo, double data_hi, int target_count = 8);
// Decades covering [data_lo, data_hi] (both > 0); with more than max_labels decades only every
// k-th carries a label (the others keep their grid line, label "").
AxisTicks log_ticks(double data_lo, double data_hi, int max_labels = 8);

}  // namespace btsm::report
