// A realistic speed-scheduled reduced model of the reference spindle for the numeric tests:
// dt 5 s, breakpoints 0/2000/4000/6000/8000 rpm, slowest pole -2.6e-4 (cooling) ... -4.05e-4 1/s
// (sysid notes: -3.67e-4 at 6000 rpm, -4.055e-4 at 8028 rpm), steady front-bearing rise up to 20 K.
#pragma once

#include "common/reduced_model.hpp"

#include <cmath>

namespace btsm::test {

inline ReducedModelF64 spindle_model() {
  ReducedModelF64 m;
  m.dt_ms = 5000;
  m.n_breakpoints = 5;
  m.ambient_channel = 3;
  m.enabled_mask = 0x1F;
  const uint16_t speeds[5] = {0, 2000, 4000, 6000, 8000};
  const double pole_per_s[5] = {-2.6e-4, -2.9e-4, -3.2e-4, -3.67e-4, -4.05e-4};
  const double x_ss_k[5] = {0.0, 3.0, 8.0, 13.0, 20.0};  // front-bearing steady rise
  // Channel roles: rear bearing, housing, front bearing (reference, c = 1), ambient, spare.
  const double c_base[5] = {0.75, 0.45, 1.0, 0.0, 0.3};
  const double d_base[5] = {0.3, -0.1, 0.8, 0.0, 0.05};
  for (int i = 0; i < 5; ++i) {
    m.speed_rpm[i] = speeds[i];
    m.a[i] = std::exp(pole_per_s[i] * m.dt_ms * 1e-3);
    m.b[i] = x_ss_k[i] * (1.0 - m.a[i]);
    const double load = speeds[i] / 8000.0;
    for (int j = 0; j < 5; ++j) {
      m.c[i][j] = j == 2 ? 1.0 : c_base[j] * (1.0 + 0.1 * load);
      m.d[i][j] = d_base[j] * load;
    }
  }
  for (int j = 0; j < 5; ++j) {
    m.warn_band_k[j] = 1.5;
    m.alarm_band_k[j] = 4.0;
    m.abs_limit_c[j] = 70.0;
    m.max_rise_k_per_min[j] = 3.0;
  }
  return m;
}

}  // namespace btsm::test
