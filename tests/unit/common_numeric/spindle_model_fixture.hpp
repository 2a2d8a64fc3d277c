// A realistic reduced model of the reference spindle for the numeric tests: dt 5 s, breakpoints
// 0/2000/4000/6000/8000 rpm, one first-order model per channel (ch1 rear bearing, ch2 housing,
// ch3 front bearing, ch4 ambient, ch5 shaft) with time constants of 35..60 min running and
// 3.5 h stopped (the reduction of spindle4 gives these magnitudes), both early stop phases, steady
// rises up to 24 K.
#pragma once

#include "common/model_blob.hpp"
#include "host/thermal/model_reference.hpp"

#include <cmath>

namespace btsm::test {

inline thermal::ReducedModelF64 spindle_model() {
  thermal::ReducedModelF64 m;
  m.dt_ms = 5000;
  m.n_breakpoints = 5;
  m.ambient_channel = 3;
  m.enabled_mask = 0x1F;
  m.stop_end_s[0] = 600;
  m.stop_end_s[1] = 2400;
  const uint16_t speeds[5] = {0, 2000, 4000, 6000, 8000};
  const double tau_run_s[5] = {2400, 2800, 2900, 0, 2600};      // per channel at 6000 rpm
  const double tau_stop_s[3][5] = {{5000, 10000, 1e7, 0, 50000},  // early phases, then late
                                   {6000, 9500, 40000, 0, 16000},
                                   {13000, 13600, 17400, 0, 14600}};
  const double rise_6000_k[5] = {13.6, 12.2, 10.7, 0.0, 11.5};
  const uint8_t roles[5] = {3, 4, 2, kModelRoleAmbient, 8};
  for (int j = 0; j < 5; ++j) {
    m.role[j] = roles[j];
    m.detector[j].drift_K = 0.4;
    m.detector[j].low_drift_K = 0.6;
    m.detector[j].warn_evidence_K_min = 1.5;
    m.detector[j].alarm_evidence_K_min = 3.0;
    m.detector[j].low_warn_evidence_K_min = 2.0;
    m.detector[j].abs_limit_c = 70.0;
    m.detector[j].max_rise_K_per_min = 3.0;
    if (j == 3) continue;
    for (int k = 0; k < 2; ++k) m.stop_a[k][j] = std::exp(-5.0 / tau_stop_s[k][j]);
    for (int i = 0; i < 5; ++i) {
      const double load = speeds[i] / 6000.0;
      // Faster and hotter with speed (convection and friction grow).
      const double tau = i == 0 ? tau_stop_s[2][j] : tau_run_s[j] * (1.15 - 0.15 * load);
      m.a[i][j] = std::exp(-5.0 / tau);
      m.b_K[i][j] = i == 0 ? 0.0 : rise_6000_k[j] * std::pow(load, 1.3) * (1.0 - m.a[i][j]);
    }
  }
  for (int i = 0; i < 5; ++i) m.speed_rpm[i] = speeds[i];
  return m;
}

}  // namespace btsm::test
