// Minimises a one-dimensional function that may have several local minima over [lo, hi]: a coarse
// uniform grid finds the best cell (so a far-off local minimum is not followed), then a golden-
// section search refines inside the grid cells either side of it. Used by the reduction to place
// first-order poles (on a log scale) where the error is a max norm, which has no useful gradient.
#ifndef BTSM_HOST_THERMAL_GRID_GOLDEN_SEARCH_HPP
#define BTSM_HOST_THERMAL_GRID_GOLDEN_SEARCH_HPP

#include <algorithm>
#include <cmath>

namespace btsm::thermal {

struct GridGoldenOptions {
  int grid_cells = 40;         // uniform cells of the coarse grid over [lo, hi]
  int golden_iterations = 40;  // golden-section steps inside the best cell's neighbours
};

// The argument in [lo, hi] where f is smallest (as found by the grid, then the golden section).
template <class F>
double grid_golden_minimize(const F& f, double lo, double hi, GridGoldenOptions o = {}) {
  int best = 0;
  double best_f = 1e300;
  for (int i = 0; i <= o.grid_cells; ++i) {
    const double v = f(lo + (hi - lo) * i / o.grid_cells);
    if (v < best_f) best_f = v, best = i;
  }
  double a = lo + (hi - lo) * std::max(0, best - 1) / o.grid_cells;
  double b = lo + (hi - lo) * std::min(o.grid_cells, best + 1) / o.grid_cells;
  const double g = (std::sqrt(5.0) - 1) / 2;
  double c = b - g * (b - a), d = a + g * (b - a), fc = f(c), fd = f(d);
  for (int it = 0; it < o.golden_iterations; ++it) {
    if (fc < fd) {
      b = d, d = c, fd = fc, c = b - g * (b - a), fc = f(c);
    } else {
      a = c, c = d, fc = fd, d = a + g * (b - a), fd = f(d);
    }
  }
  return 0.5 * (a + b);
}

}  // namespace btsm::thermal
#endif
