#pragma once
// The rms a fit of the right model could reach on given recordings: the readings' noise and, for
// a BTSM module's recordings, the lag of its filtered readings. The fit compares its final rms
// with it to tell a wrong basin (rms many times this) from a converged fit of a good model.
#include "recording.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <vector>

namespace btsm::thermal::fitting {

// The timing part of a measurement floor: rms probe rate x median sample period over the measured
// cells of the recordings of a BTSM module (metadata `module_id`: every reading is its Kalman
// filter's estimate, which lags the probe by about a sample; second differences do not see it).
// Recordings of other loggers add nothing (their readings are taken at their times). One rule for
// the fit's noise floor and the residual loop's check floor.
class FilterLagFloor {
 public:
  // `measured`: the recording's measured columns, one row per sample.
  void add(const Recording& rec, const Eigen::MatrixXd& measured);
  // sqrt(sigma^2 + timing^2), or sigma itself when no module recording was added.
  double floor_k(double sigma_k) const;

 private:
  double sum_sq_rate_ = 0;  // (K/s)^2, over the finite cells
  std::size_t cells_ = 0;
  std::vector<double> periods_s_;
};

// sqrt(sigma^2 + timing^2): sigma = the median over recordings of estimate_noise_sigma() of the
// measured columns (heat_inverse.hpp: MAD of second differences, never below the quantisation
// rms); timing = rms probe rate x median sample period over the measured cells of the recordings
// of a BTSM module (metadata `module_id`: every reading is its Kalman filter's estimate, which lags
// the probe and sigma does not see), 0 for other recordings (readings taken at their times). The
// same rule as the residual loop's check measurement floor. 0 when no column has 10 samples.
double fit_noise_floor_k(const std::vector<Recording>& recs, const std::vector<std::vector<int>>& cols);

}  // namespace btsm::thermal::fitting
