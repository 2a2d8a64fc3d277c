// Double-precision reference of the module's model and its quantizer.
#include "model_reference.hpp"

#include "common/wire_messages.hpp"

#include <cmath>
#include <cstring>

namespace btsm::thermal {
namespace {

bool finite(double v) { return std::isfinite(v); }

// Rounds v * 2^frac to int32 (nearest, ties away from zero); false if it does not fit.
bool to_q(double v, int frac, int32_t& out) {
  const double s = std::ldexp(v, frac);
  const double r = std::round(s);  // ties away from zero
  if (!(r >= -2147483648.0 && r <= 2147483647.0)) return false;
  out = static_cast<int32_t>(r);
  return true;
}

// Rounds a physical value to an integer within [lo, hi] after scaling.
bool to_int(double v, double scale, int64_t lo, int64_t hi, int64_t& out) {
  if (!finite(v)) return false;
  const double s = std::round(v * scale);
  if (s < static_cast<double>(lo) - 0.5 || s > static_cast<double>(hi) + 0.5) return false;
  out = static_cast<int64_t>(s);
  return true;
}

}  // namespace

uint8_t role_for_node(const std::string& node_name) {
  for (uint8_t r = 0; r < wire::kChannelRoleCount; ++r) {
    const char* name = wire::channel_role_name(r);
    if (wire::is_thermal_role(r) && name != nullptr && node_name == name) return r;
  }
  return kModelRoleUnchecked;
}

double evidence_units(double K_min, uint16_t dt_ms) {
  // K min -> mK samples: x 1000 mK/K x (60000 / dt_ms) samples per minute.
  return K_min * 1000.0 * (60000.0 / dt_ms) / kEvidenceUnitMkSamples;
}

double evidence_K_min(uint16_t units, uint16_t dt_ms) {
  return units * static_cast<double>(kEvidenceUnitMkSamples) / 1000.0 * dt_ms / 60000.0;
}

void init_at_ambient(const ReducedModelF64& m, ReducedModelF64State& st, double ambient_c) {
  (void)m;
  for (double& t : st.t_c) t = ambient_c;
  st.stopped_s = 1e300;
}

ChannelUpdate channel_update(const ReducedModelF64& m, int j, double speed_rpm, double stopped_s) {
  const uint8_t n = m.n_breakpoints;
  ChannelUpdate u;
  if (speed_rpm > 0.0) {
    uint8_t lo = 0, hi = 0;
    double f = 0.0;
    if (n > 0) {
      if (speed_rpm >= m.speed_rpm[n - 1]) {
        lo = hi = static_cast<uint8_t>(n - 1);
      } else {
        while (lo + 1 < n && m.speed_rpm[lo + 1] <= speed_rpm) ++lo;
        hi = static_cast<uint8_t>(lo + 1);
        f = (speed_rpm - m.speed_rpm[lo]) / (static_cast<double>(m.speed_rpm[hi]) - m.speed_rpm[lo]);
      }
    }
    u.a = m.a[lo][j] + (m.a[hi][j] - m.a[lo][j]) * f;
    u.b_K = m.b_K[lo][j] + (m.b_K[hi][j] - m.b_K[lo][j]) * f;
    return u;
  }
  u.a = m.a[0][j];
  for (int k = 0; k < kModelEarlyStopPhases; ++k)
    if (m.stop_end_s[k] != 0 && stopped_s < m.stop_end_s[k]) {
      u.a = m.stop_a[k][j];
      break;
    }
  return u;
}

void step(const ReducedModelF64& m, ReducedModelF64State& st, double speed_rpm, double ambient_c,
          double predicted_c[kModelChannels]) {
  double before[kModelChannels];
  for (uint8_t j = 0; j < kModelChannels; ++j) before[j] = st.t_c[j];
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    if (((m.enabled_mask >> j) & 1U) == 0 || !finite(ambient_c)) {
      predicted_c[j] = NAN;
      continue;
    }
    if (j == m.ambient_channel) {
      predicted_c[j] = ambient_c;
      continue;
    }
    predicted_c[j] = st.t_c[j];
    const ChannelUpdate u = channel_update(m, j, speed_rpm, st.stopped_s);
    const double carried = m.carrier[j] != kModelNoCarrier ? m.couple[j] * (before[m.carrier[j] - 1] - ambient_c) : 0.0;
    st.t_c[j] = ambient_c + u.a * (st.t_c[j] - ambient_c) + carried + u.b_K;
  }
  st.stopped_s = speed_rpm > 0.0 ? 0.0 : st.stopped_s + m.dt_ms * 1e-3;
}

ModelCheck quantize_fields(const ReducedModelF64& f, ReducedModel& out) {
  std::memset(&out, 0, sizeof(out));
  out.version = kReducedModelVersion;
  ModelSchedule& s = out.schedule;
  if (f.n_breakpoints < kModelMinBreakpoints || f.n_breakpoints > kModelMaxBreakpoints)
    return model_check(ModelStatus::kBadBreakpointCount);
  s.n_breakpoints = f.n_breakpoints;
  s.ambient_channel = f.ambient_channel;
  s.enabled_mask = f.enabled_mask;
  s.dt_ms = f.dt_ms;
  for (int k = 0; k < kModelEarlyStopPhases; ++k) s.stop_end_s[k] = f.stop_end_s[k];
  for (int j = 0; j < kModelChannels; ++j) {
    s.role[j] = f.role[j];
    s.coupling.carrier[j] = f.carrier[j];
    if (f.carrier[j] == kModelNoCarrier) continue;
    if (!finite(f.couple[j])) return model_check(ModelStatus::kNotFinite, 0xFF, static_cast<uint8_t>(j));
    if (!(f.couple[j] >= 0.0 && f.couple[j] < 1.0) || !to_q(f.couple[j], kPoleFracBits, s.coupling.c_q30[j]))
      return model_check(ModelStatus::kBadCarrier, 0xFF, static_cast<uint8_t>(j));
  }
  const double state_scale = 1000.0 * (1 << kStateFracBits);  // K -> Q21.10 mK
  for (uint8_t i = 0; i < f.n_breakpoints; ++i) {
    s.speed_rpm[i] = f.speed_rpm[i];
    for (uint8_t j = 0; j < kModelChannels; ++j) {
      if (!model_predicts(f.enabled_mask, f.ambient_channel, j)) continue;
      if (!finite(f.a[i][j]) || !finite(f.b_K[i][j])) return model_check(ModelStatus::kNotFinite, i, j);
      if (!(f.a[i][j] >= 0.0 && f.a[i][j] < 1.0) || !to_q(f.a[i][j], kPoleFracBits, out.bp[i].ch[j].a_q30))
        return model_check(ModelStatus::kUnstablePole, i, j);
      int64_t b = 0;
      if (!to_int(f.b_K[i][j], state_scale, -2147483647LL, 2147483647LL, b))
        return model_check(ModelStatus::kGainOutOfRange, i, j);
      out.bp[i].ch[j].b = static_cast<int32_t>(b);
    }
  }
  for (int k = 0; k < kModelEarlyStopPhases; ++k)
    for (uint8_t j = 0; j < kModelChannels; ++j) {
      if (f.stop_end_s[k] == 0 || !model_predicts(f.enabled_mask, f.ambient_channel, j)) continue;
      if (!finite(f.stop_a[k][j])) return model_check(ModelStatus::kNotFinite, 0, j);
      if (!(f.stop_a[k][j] >= 0.0 && f.stop_a[k][j] < 1.0) || !to_q(f.stop_a[k][j], kPoleFracBits, out.stop_a_q30[k][j]))
        return model_check(ModelStatus::kUnstablePole, 0, j);
    }
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    if (((f.enabled_mask >> j) & 1U) == 0) continue;
    const ChannelDetector& d = f.detector[j];
    ChannelLimits& l = out.limits[j];
    int64_t v = 0;
    if (!to_int(d.abs_limit_c, 1000.0, kModelMinAbsLimitMk, kModelMaxAbsLimitMk, v))
      return model_check(ModelStatus::kLimitOutOfRange, 0xFF, j);
    l.abs_limit_mK = static_cast<int32_t>(v);
    if (j == f.ambient_channel) continue;
    int64_t drift = 0, low_drift = 0, warn = 0, alarm = 0, low = 0, rise = 0;
    if (!to_int(d.drift_K, 1000.0, 0, 65535, drift) || !to_int(d.low_drift_K, 1000.0, 0, 65535, low_drift) ||
        !to_int(evidence_units(d.warn_evidence_K_min, f.dt_ms), 1.0, 0, 65535, warn) ||
        !to_int(evidence_units(d.alarm_evidence_K_min, f.dt_ms), 1.0, 0, 65535, alarm) ||
        !to_int(evidence_units(d.low_warn_evidence_K_min, f.dt_ms), 1.0, 0, 65535, low) ||
        !to_int(d.max_rise_K_per_min, 1000.0, 0, 65535, rise))
      return model_check(ModelStatus::kLimitOutOfRange, 0xFF, j);
    l.drift_mK = static_cast<uint16_t>(drift);
    l.low_drift_mK = static_cast<uint16_t>(low_drift);
    l.warn_evidence = static_cast<uint16_t>(warn);
    l.alarm_evidence = static_cast<uint16_t>(alarm);
    l.low_warn_evidence = static_cast<uint16_t>(low);
    l.max_rise_mK_per_min = static_cast<uint16_t>(rise);
  }
  return model_check(ModelStatus::kOk);
}

ModelCheck quantize(const ReducedModelF64& f, ReducedModel& out) {
  const ModelCheck c = quantize_fields(f, out);
  return c.ok() ? validate(out) : c;
}

}  // namespace btsm::thermal
