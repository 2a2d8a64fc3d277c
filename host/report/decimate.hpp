#pragma once
// Thinning of dense series for vector output (SVG): what is kept looks the same at the given
// pixel resolution, so a 100,000-sample recording does not become a 10 MB file. Inputs are canvas
// coordinates; the outputs are indices into them, in order.
#include <cstddef>
#include <vector>

namespace btsm::report {

// Polyline: per bucket of `bucket_px` canvas pixels along x, the first, lowest, highest and last
// point (M4), so the drawn envelope is unchanged. A non-finite y is kept as a pen-up break.
std::vector<std::size_t> decimate_line(const std::vector<double>& x, const std::vector<double>& y, double bucket_px);

// Dots: the first point in each `cell_px` square cell; non-finite points are dropped.
std::vector<std::size_t> decimate_points(const std::vector<double>& x, const std::vector<double>& y, double cell_px);

}  // namespace btsm::report
