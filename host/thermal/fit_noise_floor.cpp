// The fit's noise floor (fit_noise_floor.hpp).
#include "fit_noise_floor.hpp"

#include "heat_inverse.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>

namespace btsm::thermal::fitting {

double fit_noise_floor_k(const std::vector<Recording>& recs, const std::vector<std::vector<int>>& cols) {
  std::vector<double> sigmas, dts;
  double ss = 0;
  std::size_t n = 0;
  for (std::size_t r = 0; r < recs.size(); ++r) {
    const Recording& rec = recs[r];
    Eigen::MatrixXd m(static_cast<Eigen::Index>(rec.rows()), static_cast<Eigen::Index>(cols[r].size()));
    for (std::size_t c = 0; c < cols[r].size(); ++c) m.col(static_cast<Eigen::Index>(c)) = rec.temp_c.col(cols[r][c]);
    try {
      sigmas.push_back(estimate_noise_sigma(m));
    } catch (const std::invalid_argument&) {
      continue;  // too short to tell its noise: it says nothing about the floor
    }
    if (rec.meta_value("module_id").empty()) continue;
    for (Eigen::Index k = 1; k < m.rows(); ++k) {
      const double dt = rec.time_s[static_cast<std::size_t>(k)] - rec.time_s[static_cast<std::size_t>(k - 1)];
      if (!(dt > 0)) continue;
      dts.push_back(dt);
      for (Eigen::Index c = 0; c < m.cols(); ++c) {
        const double d = m(k, c) - m(k - 1, c);
        if (!std::isfinite(d)) continue;
        ss += (d / dt) * (d / dt);
        ++n;
      }
    }
  }
  if (sigmas.empty()) return 0.0;
  std::nth_element(sigmas.begin(), sigmas.begin() + static_cast<std::ptrdiff_t>(sigmas.size() / 2), sigmas.end());
  const double sigma = sigmas[sigmas.size() / 2];
  if (n == 0 || dts.empty()) return sigma;
  std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2), dts.end());
  const double timing = std::sqrt(ss / static_cast<double>(n)) * dts[dts.size() / 2];
  return std::sqrt(sigma * sigma + timing * timing);
}

}  // namespace btsm::thermal::fitting
