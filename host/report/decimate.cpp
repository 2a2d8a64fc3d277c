#include "host/report/decimate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_set>

namespace btsm::report {

std::vector<std::size_t> decimate_line(const std::vector<double>& x, const std::vector<double>& y, double bucket_px) {
  const std::size_t n = std::min(x.size(), y.size());
  std::vector<std::size_t> keep;
  if (!(bucket_px > 0)) {
    for (std::size_t i = 0; i < n; ++i) keep.push_back(i);
    return keep;
  }
  bool open = false;
  long bucket = 0;
  std::size_t first = 0, lo = 0, hi = 0, last = 0;
  auto flush = [&] {
    if (!open) return;
    std::size_t idx[4] = {first, lo, hi, last};
    std::sort(idx, idx + 4);
    for (int k = 0; k < 4; ++k)
      if (k == 0 || idx[k] != idx[k - 1]) keep.push_back(idx[k]);
    open = false;
  };
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) {
      flush();
      if (keep.empty() || keep.back() != i) keep.push_back(i);  // the break itself
      continue;
    }
    const long b = static_cast<long>(std::floor(x[i] / bucket_px));
    if (open && b != bucket) flush();
    if (!open) {
      open = true;
      bucket = b;
      first = lo = hi = last = i;
      continue;
    }
    if (y[i] < y[lo]) lo = i;
    if (y[i] > y[hi]) hi = i;
    last = i;
  }
  flush();
  return keep;
}

std::vector<std::size_t> decimate_points(const std::vector<double>& x, const std::vector<double>& y, double cell_px) {
  const std::size_t n = std::min(x.size(), y.size());
  std::vector<std::size_t> keep;
  std::unordered_set<std::uint64_t> cells;
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
    if (!(cell_px > 0)) {
      keep.push_back(i);
      continue;
    }
    const auto cx = static_cast<std::uint32_t>(static_cast<std::int32_t>(std::floor(x[i] / cell_px)));
    const auto cy = static_cast<std::uint32_t>(static_cast<std::int32_t>(std::floor(y[i] / cell_px)));
    if (cells.insert((static_cast<std::uint64_t>(cx) << 32) | cy).second) keep.push_back(i);
  }
  return keep;
}

}  // namespace btsm::report
