#pragma once
// The rms a fit of the right model could reach on given recordings: the readings' noise and, for
// a BTSM module's recordings, the lag of its filtered readings. The fit compares its final rms
// with it to tell a wrong basin (rms many times this) from a converged fit of a good model.
#include "recording.hpp"

#include <vector>

namespace btsm::thermal::fitting {

// sqrt(sigma^2 + timing^2): sigma = the median over recordings of estimate_noise_sigma() of the
// measured columns (heat_inverse.hpp: MAD of second differences, never below the quantisation
// rms); timing = rms probe rate x median sample period over the measured cells of the recordings
// of a BTSM module (metadata `module_id`: every reading is its Kalman filter's estimate, which lags
// the probe and sigma does not see), 0 for other recordings (readings taken at their times). The
// same rule as the residual loop's check measurement floor. 0 when no column has 10 samples.
double fit_noise_floor_k(const std::vector<Recording>& recs, const std::vector<std::vector<int>>& cols);

}  // namespace btsm::thermal::fitting
