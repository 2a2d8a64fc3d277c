#pragma once
// The 1-minute load average. On the shared 2-core machine other jobs stretch a bench's wall time,
// so benches print it beside their figures (CPU time is the part that does not depend on them).
#include <cstdio>

namespace btsm::bench {

// -1 when /proc/loadavg cannot be read.
inline double load_average_1min() {
  double l = -1;
  if (std::FILE* f = std::fopen("/proc/loadavg", "r")) {
    if (std::fscanf(f, "%lf", &l) != 1) l = -1;
    std::fclose(f);
  }
  return l;
}

}  // namespace btsm::bench
