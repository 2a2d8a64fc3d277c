// The fit's noise floor (fit_noise_floor.hpp).
#include "fit_noise_floor.hpp"

#include "heat_inverse.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>

namespace btsm::thermal::fitting {

void FilterLagFloor::add(const Recording& rec, const Eigen::MatrixXd& measured) {
  if (rec.meta_value("module_id").empty()) return;
  for (Eigen::Index k = 1; k < measured.rows(); ++k) {
    const double dt = rec.time_s[static_cast<std::size_t>(k)] - rec.time_s[static_cast<std::size_t>(k - 1)];
    if (!(dt > 0)) continue;
    periods_s_.push_back(dt);
    for (Eigen::Index c = 0; c < measured.cols(); ++c) {
      const double d = measured(k, c) - measured(k - 1, c);
      if (!std::isfinite(d)) continue;
      sum_sq_rate_ += (d / dt) * (d / dt);
      ++cells_;
    }
  }
}

double FilterLagFloor::floor_k(double sigma_k) const {
  if (cells_ == 0 || periods_s_.empty()) return sigma_k;
  std::vector<double> dts = periods_s_;
  std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2), dts.end());
  const double timing = std::sqrt(sum_sq_rate_ / static_cast<double>(cells_)) * dts[dts.size() / 2];
  return std::sqrt(sigma_k * sigma_k + timing * timing);
}

double fit_noise_floor_k(const std::vector<Recording>& recs, const std::vector<std::vector<int>>& cols) {
  std::vector<double> sigmas;
  FilterLagFloor lag;
  for (std::size_t r = 0; r < recs.size(); ++r) {
    const Recording& rec = recs[r];
    Eigen::MatrixXd m(static_cast<Eigen::Index>(rec.rows()), static_cast<Eigen::Index>(cols[r].size()));
    for (std::size_t c = 0; c < cols[r].size(); ++c) m.col(static_cast<Eigen::Index>(c)) = rec.temp_c.col(cols[r][c]);
    try {
      sigmas.push_back(estimate_noise_sigma(m));
    } catch (const std::invalid_argument&) {
      continue;  // too short to tell its noise: it says nothing about the floor
    }
    lag.add(rec, m);
  }
  if (sigmas.empty()) return 0.0;
  std::nth_element(sigmas.begin(), sigmas.begin() + static_cast<std::ptrdiff_t>(sigmas.size() / 2), sigmas.end());
  return lag.floor_k(sigmas[sigmas.size() / 2]);
}

}  // namespace btsm::thermal::fitting
