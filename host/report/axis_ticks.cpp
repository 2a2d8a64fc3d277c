#include "host/report/axis_ticks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace btsm::report {
namespace {

double nice_step(double span, int target_count) {
  const double raw = span / std::max(1, target_count);
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / mag;
  const double nice = f < 1.5 ? 1 : f < 3 ? 2 : f < 7 ? 5 : 10;
  return nice * mag;
}

std::string format_tick(double v, double step) {
  char buf[32];
  if (std::fabs(v) < step * 1e-9) v = 0;  // print 0, not -1.2e-17
  const double a = std::fabs(v);
  if ((a >= 1e5 || (a > 0 && a < 1e-3)))
    std::snprintf(buf, sizeof buf, "%.3g", v);
  else {
    const int decimals = step >= 1 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  }
  return buf;
}

}  // namespace

AxisTicks linear_ticks(double lo, double hi, int target_count) {
  AxisTicks t;
  if (!std::isfinite(lo) || !std::isfinite(hi)) lo = 0, hi = 1;
  if (hi < lo) std::swap(lo, hi);
  if (hi - lo < 1e-12 * std::max(1.0, std::fabs(hi))) {
    const double pad = std::max(1e-6, std::fabs(hi) * 0.05);
    lo -= pad, hi += pad;
  }
  const double step = nice_step(hi - lo, target_count);
  t.lo = std::floor(lo / step) * step;
  t.hi = std::ceil(hi / step) * step;
  for (double v = t.lo; v <= t.hi + step * 1e-6; v += step) {
    t.values.push_back(v);
    t.labels.push_back(format_tick(v, step));
  }
  return t;
}

AxisTicks linear_ticks_within(double lo, double hi, int target_count) {
  AxisTicks t = linear_ticks(lo, hi, target_count);
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(hi > lo)) return t;  // degenerate: keep the padded range
  const double step = t.values.size() > 1 ? t.values[1] - t.values[0] : hi - lo;
  AxisTicks in;
  in.lo = lo;
  in.hi = hi;
  for (size_t i = 0; i < t.values.size(); ++i)
    if (t.values[i] >= lo - step * 1e-9 && t.values[i] <= hi + step * 1e-9) {
      in.values.push_back(t.values[i]);
      in.labels.push_back(t.labels[i]);
    }
  return in;
}

AxisTicks log_ticks(double lo, double hi, int max_labels) {
  AxisTicks t;
  if (!(lo > 0) || !std::isfinite(lo)) lo = 1e-3;
  if (!(hi > lo) || !std::isfinite(hi)) hi = lo * 10;
  const int e0 = static_cast<int>(std::floor(std::log10(lo)));
  const int e1 = static_cast<int>(std::ceil(std::log10(hi)));
  t.lo = std::pow(10.0, e0);
  t.hi = std::pow(10.0, std::max(e1, e0 + 1));
  const int last = std::max(e1, e0 + 1);
  const int every = std::max(1, (last - e0 + 1 + max_labels - 1) / std::max(1, max_labels));
  for (int e = e0; e <= last; ++e) {
    t.values.push_back(std::pow(10.0, e));
    char buf[16];
    std::snprintf(buf, sizeof buf, "1e%d", e);
    t.labels.push_back((e - e0) % every == 0 ? buf : "");
  }
  return t;
}

}  // namespace btsm::report
