// Speed-scheduled first-order reduced thermal model: the coefficient blob the host flashes, its
// double-precision host form, quantisation, codec with validation, and fixed-point evaluation.
//
// ---------------------------------------------------------------------------------------------
// THE MODEL (one scalar state x shared by all channels, in kelvin)
//
//   Breakpoints i = 0..n-1 at speeds s_0 = 0 < s_1 < ... < s_{n-1} (rpm). Breakpoint 0 is natural
//   cooling (spindle stopped). Each breakpoint holds, for the blob's sample period dt:
//     a    discrete pole, x_{k+1} = a x_k + b u_k           (|a| < 1)
//     b    input gain (K per sample at u = 1)
//     c_j  output gain of channel j (K/K)
//     d_j  feed-through of channel j (K at u = 1)
//   u = 1 while the spindle turns (speed > 0), u = 0 when stopped. b_0 and d_0 must be 0 (no heat
//   when stopped).
//
//   Each sample k, given speed s_k and ambient T_amb,k:
//     1. Parameters p in {a, b, c_j, d_j} at s_k:
//          s_k == 0            -> breakpoint 0, u = 0
//          s_k >= s_{n-1}      -> breakpoint n-1 (held, never extrapolated)
//          s_i <= s_k < s_{i+1} -> p = p_i + (p_{i+1} - p_i) * f,  f = (s_k - s_i)/(s_{i+1} - s_i)
//        Linear interpolation of every coefficient (not of the continuous pole): between 0 rpm and
//        s_1 the input gains therefore ramp up from 0, which is continuous in speed. The steady
//        state b/(1-a) of an interpolated point lies between the end points' (a linear-fractional
//        function of f is monotone), so validating breakpoints bounds every interpolated point.
//     2. Output:  theta_j = c_j x_k + d_j u_k;  predicted_j = T_amb + theta_j  (ambient channel:
//                 predicted = T_amb; disabled channels: kModelNoPrediction)
//     3. Update:  x_{k+1} = a x_k + b u_k
//   The state basis must be the SAME at every breakpoint (the host normalises, e.g. c = 1 for one
//   reference channel at every breakpoint), otherwise interpolating c between breakpoints is
//   meaningless. x = 0 means "everything at ambient" (cold start).
//
// FIXED-POINT FORMATS (why): a = exp(-3.8e-4/s * 5 s) = 0.99810; the error of x after settling is
//   ~ (per-step error) / (1 - a) = 526 x per-step error, and a 24 h run is 17280 steps.
//     a        int32 Q1.30   LSB 9.3e-10; steady-state error from quantising a: x_ss*2^-31/(1-a)
//                            = 20 K * 4.7e-10 / 1.9e-3 = 5e-6 K
//     b, c, d  int32 Q7.24   range +-128, LSB 6e-8; b error -> 6e-8*526/2 = 1.6e-5 K
//     x        int32 Q11.20  range +-2048 K, LSB 9.5e-7 K; rounding per step (nearest) accumulates
//                            at most 526 * 0.5 LSB = 2.5e-4 K even if every rounding had the same sign
//     f        uint16 Q0.16  interpolation fraction, floor((s - s_i) * 2^16 / (s_{i+1} - s_i))
//   Products are formed exactly in int64 (32x32 widening multiplies) and rounded once (nearest,
//   ties away); interpolation is exact 32-bit arithmetic (detail_rm). No 64-bit division
//   is used (the fraction is a 32-bit division), which keeps the AVR image small.
//   Measured deviation from the double reference: see tests/unit/common_numeric (reduced model test).
//
// ---------------------------------------------------------------------------------------------
// THE BLOB (little-endian, fixed size kReducedModelBlobSize = 464 bytes, CRC-32 last)
//   off  size  field
//     0     4  magic 0x4D525442 (bytes "BTRM")
//     4     1  version (kReducedModelVersion = 1)
//     5     1  n_breakpoints (2..8)
//     6     1  ambient_channel (0..4, or 0xFF = none: caller supplies ambient from elsewhere)
//     7     1  enabled_mask (bit j = channel j enabled; bits 5..7 must be 0)
//     8     2  dt_ms (100..60000) sample period the poles were discretised for
//    10    16  speed_rpm[8]   u16; entry 0 = 0, strictly ascending up to n-1, unused entries 0
//    26   384  breakpoint[8], 48 bytes each: a (i32 Q1.30), b (i32 Q7.24), c[5] (i32 Q7.24),
//              d[5] (i32 Q7.24); unused breakpoints all zero
//   410    10  warn_band_mK[5]          u16  |residual| above this -> WARN
//   420    10  alarm_band_mK[5]         u16  |residual| above this -> ALARM (> warn band)
//   430    20  abs_limit_mK[5]          i32  absolute temperature limit (degC * 1000)
//   450    10  max_rise_mK_per_min[5]   u16  0 = rate check disabled
//   460     4  crc32 (IEEE, reflected, as btsm::crc32) over bytes 0..459
//
// C++14, no standard library, header-only: shared by the firmware (avr-g++ 5.4, where double is
// 32-bit: ReducedModelF64 is host-side only) and the host tool.
#ifndef BTSM_COMMON_REDUCED_MODEL_HPP
#define BTSM_COMMON_REDUCED_MODEL_HPP

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "byte_order.hpp"
#include "channels.hpp"
#include "crc.hpp"
#include "fixed_point.hpp"
#include "platform.hpp"

namespace btsm {

const uint8_t kModelChannels = kChannels;  // one column per module channel (common/channels.hpp)
const uint8_t kModelMaxBreakpoints = 8;
const uint8_t kModelMinBreakpoints = 2;  // natural cooling + at least one running speed
const uint32_t kReducedModelMagic = 0x4D525442UL;  // "BTRM" in byte order
const uint8_t kReducedModelVersion = 1;
const size_t kReducedModelBlobSize = 464;
const uint8_t kModelAmbientNone = 0xFF;
const uint16_t kModelMinDtMs = 100;
const uint16_t kModelMaxDtMs = 60000;

const int kPoleFracBits = 30;   // a: Q1.30
const int kGainFracBits = 24;   // b, c, d: Q7.24
const int kStateFracBits = 20;  // x: Q11.20 (kelvin)
const int kSpeedFracBits = 16;  // interpolation fraction: Q0.16

// Validation bounds (also applied by quantize()).
const int32_t kModelMaxSteadyStateMk = 1000000;     // |b/(1-a)| and |c x_ss + d| <= 1000 K
const int32_t kModelMinAbsLimitMk = -200000;        // IEC 60751 range of the probes
const int32_t kModelMaxAbsLimitMk = 850000;

// Prediction value for "no prediction" (disabled channel, missing ambient); equals the wire's
// kMissing (-2^23) so it can be sent as is.
const int32_t kModelNoPrediction = -8388608L;

// Blob layout offsets.
const size_t kBlobOffMagic = 0;
const size_t kBlobOffVersion = 4;
const size_t kBlobOffBreakpointCount = 5;
const size_t kBlobOffAmbientChannel = 6;
const size_t kBlobOffEnabledMask = 7;
const size_t kBlobOffDtMs = 8;
const size_t kBlobOffSpeeds = 10;
const size_t kBlobOffBreakpoints = 26;
const size_t kBlobBreakpointSize = 48;
const size_t kBlobOffWarnBands = 410;
const size_t kBlobOffAlarmBands = 420;
const size_t kBlobOffAbsLimits = 430;
const size_t kBlobOffMaxRise = 450;
const size_t kBlobOffCrc = 460;
static_assert(kBlobOffBreakpoints + kModelMaxBreakpoints * kBlobBreakpointSize == kBlobOffWarnBands,
              "blob layout");
static_assert(kBlobOffCrc + 4 == kReducedModelBlobSize, "blob layout");

// ---- status -------------------------------------------------------------------------------------

enum class ModelStatus : uint8_t {
  kOk = 0,
  kBadLength = 1,           // blob is not kReducedModelBlobSize bytes
  kBadCrc = 2,              // stored CRC-32 does not match
  kBadMagic = 3,
  kBadVersion = 4,
  kBadBreakpointCount = 5,  // n outside 2..8
  kBadSpeeds = 6,           // speed[0] != 0, not strictly ascending, or unused entry != 0
  kBadDt = 7,               // dt_ms outside 100..60000
  kNotFinite = 8,           // NaN/inf in the double model (quantize only)
  kUnstablePole = 9,        // |a| >= 1 (or a does not fit Q1.30)
  kGainOutOfRange = 10,     // b/c/d beyond Q7.24, or |c x_ss + d| > 1000 K
  kSteadyStateOutOfRange = 11,  // |b/(1-a)| > 1000 K
  kInputAtStandstill = 12,  // b or d of breakpoint 0 not zero
  kBadAmbientChannel = 13,  // not 0..4/0xFF, or ambient channel not enabled
  kBadChannelMask = 14,     // bits 5..7 set or no channel enabled
  kBadBands = 15,           // warn band 0 or alarm band <= warn band (enabled non-ambient channel)
  kLimitOutOfRange = 16,    // absolute limit outside -200..850 degC, or band/rate beyond u16
  kUnusedNotZero = 17,      // coefficients of an unused breakpoint slot not zero
};

// How a status maps onto the wire's NACK classes.
enum class ModelStatusClass : uint8_t { kOk, kLength, kCrc, kVersion, kInvalid };

inline ModelStatusClass model_status_class(ModelStatus s) {
  switch (s) {
    case ModelStatus::kOk: return ModelStatusClass::kOk;
    case ModelStatus::kBadLength: return ModelStatusClass::kLength;
    case ModelStatus::kBadCrc: return ModelStatusClass::kCrc;
    case ModelStatus::kBadVersion: return ModelStatusClass::kVersion;
    default: return ModelStatusClass::kInvalid;
  }
}

inline const char* model_status_name(ModelStatus s) {
  switch (s) {
    case ModelStatus::kOk: return "ok";
    case ModelStatus::kBadLength: return "blob length is not 464 bytes";
    case ModelStatus::kBadCrc: return "blob CRC-32 mismatch";
    case ModelStatus::kBadMagic: return "bad magic (not a BTSM reduced-model blob)";
    case ModelStatus::kBadVersion: return "unsupported blob version";
    case ModelStatus::kBadBreakpointCount: return "breakpoint count outside 2..8";
    case ModelStatus::kBadSpeeds:
      return "breakpoint speeds must start at 0 rpm and ascend strictly (unused = 0)";
    case ModelStatus::kBadDt: return "sample period dt_ms outside 100..60000";
    case ModelStatus::kNotFinite: return "coefficient is NaN or infinite";
    case ModelStatus::kUnstablePole: return "pole a outside (-1, 1)";
    case ModelStatus::kGainOutOfRange:
      return "gain outside Q7.24 (|b|,|c|,|d| < 128) or steady output |c*x_ss + d| > 1000 K";
    case ModelStatus::kSteadyStateOutOfRange: return "steady state |b/(1-a)| > 1000 K";
    case ModelStatus::kInputAtStandstill: return "breakpoint 0 (0 rpm) must have b = 0 and d = 0";
    case ModelStatus::kBadAmbientChannel:
      return "ambient channel must be 0..4 (and enabled) or 0xFF (none)";
    case ModelStatus::kBadChannelMask: return "enabled-channel mask empty or has bits above channel 5";
    case ModelStatus::kBadBands: return "warn band must be > 0 and alarm band > warn band";
    case ModelStatus::kLimitOutOfRange:
      return "limit out of range (absolute -200..850 degC, bands and rise 0..65535 mK)";
    case ModelStatus::kUnusedNotZero: return "unused breakpoint slot is not all zero";
  }
  return "unknown status";
}

// Status plus where: breakpoint index or channel index (0xFF when not applicable). Firmware can
// send `detail = status | index << 8` in its NACK.
struct ModelCheck {
  ModelStatus status;
  uint8_t breakpoint;
  uint8_t channel;
  bool ok() const { return status == ModelStatus::kOk; }
  uint16_t detail() const {
    const uint8_t where = breakpoint != 0xFF ? breakpoint : channel;
    return static_cast<uint16_t>(static_cast<uint16_t>(status) | (static_cast<uint16_t>(where) << 8));
  }
};

inline ModelCheck model_check(ModelStatus s, uint8_t bp = 0xFF, uint8_t ch = 0xFF) {
  ModelCheck c;
  c.status = s;
  c.breakpoint = bp;
  c.channel = ch;
  return c;
}

// ---- fixed-point model (what the firmware runs) ------------------------------------------------

struct ModelBreakpoint {
  int32_t a_q30;                  // pole, Q1.30
  int32_t b_q24;                  // K per sample at u = 1, Q7.24
  int32_t c_q24[kModelChannels];  // K/K, Q7.24
  int32_t d_q24[kModelChannels];  // K at u = 1, Q7.24
};

struct ChannelLimits {
  uint16_t warn_band_mK;         // |measured - predicted| above -> WARN
  uint16_t alarm_band_mK;        // |measured - predicted| above -> ALARM
  int32_t abs_limit_mK;          // measured above -> ALARM (degC * 1000)
  uint16_t max_rise_mK_per_min;  // rate of rise above -> ALARM; 0 = disabled
};

struct ReducedModel {
  uint8_t version;
  uint8_t n_breakpoints;
  uint8_t ambient_channel;  // 0..4 or kModelAmbientNone
  uint8_t enabled_mask;
  uint16_t dt_ms;
  uint16_t speed_rpm[kModelMaxBreakpoints];
  ModelBreakpoint bp[kModelMaxBreakpoints];
  ChannelLimits limits[kModelChannels];
};

struct ReducedModelState {
  int32_t x_q20;  // state in kelvin, Q11.20; 0 = at ambient
};

// ---- double-precision model (host side; double is 32-bit on AVR) ------------------------------

struct ReducedModelF64 {
  uint16_t dt_ms = 5000;
  uint8_t n_breakpoints = 0;
  uint8_t ambient_channel = 3;   // default channel roles: ch4 (index 3) is ambient
  uint8_t enabled_mask = 0x1F;
  uint16_t speed_rpm[kModelMaxBreakpoints] = {};
  double a[kModelMaxBreakpoints] = {};
  double b[kModelMaxBreakpoints] = {};
  double c[kModelMaxBreakpoints][kModelChannels] = {};
  double d[kModelMaxBreakpoints][kModelChannels] = {};
  double warn_band_k[kModelChannels] = {1.0, 1.0, 1.0, 1.0, 1.0};
  double alarm_band_k[kModelChannels] = {3.0, 3.0, 3.0, 3.0, 3.0};
  double abs_limit_c[kModelChannels] = {80.0, 80.0, 80.0, 80.0, 80.0};
  double max_rise_k_per_min[kModelChannels] = {2.0, 2.0, 2.0, 2.0, 2.0};
};

struct ReducedModelF64State {
  double x = 0.0;  // kelvin
};

// ---- validation ---------------------------------------------------------------------------------

namespace detail_rm {
inline int64_t abs64(int64_t v) { return v < 0 ? -v : v; }

// floor(n * 2^16 / d) for n < d: the quotient has 16 bits, so 16 steps of restoring division
// (libgcc's 32-bit division on the AVR runs 32, ~700 cycles). The remainder stays below d, so
// doubling it needs 17 bits.
inline uint16_t fraction_q16(uint16_t n, uint16_t d) {
  uint32_t r = n;
  uint16_t q = 0;
  for (uint8_t i = 0; i < 16; ++i) {
    r <<= 1;
    q = static_cast<uint16_t>(q << 1);
    if (r >= d) {
      r -= d;
      q |= 1U;
    }
  }
  return q;
}
}  // namespace detail_rm

// Checks every constraint listed in ModelStatus, in three parts that need different fields, so the
// firmware can validate a blob streamed from EEPROM one breakpoint at a time (a whole ReducedModel
// is 456 bytes of its 2 KB of SRAM). validate() runs them in this order on a whole model.

// The schedule: breakpoint count, sample period, channel mask, ambient channel, speeds.
inline ModelCheck validate_schedule(uint8_t n_breakpoints, uint16_t dt_ms, uint8_t enabled_mask,
                                    uint8_t ambient_channel, const uint16_t speed_rpm[kModelMaxBreakpoints]) {
  if (n_breakpoints < kModelMinBreakpoints || n_breakpoints > kModelMaxBreakpoints)
    return model_check(ModelStatus::kBadBreakpointCount);
  if (dt_ms < kModelMinDtMs || dt_ms > kModelMaxDtMs) return model_check(ModelStatus::kBadDt);
  if ((enabled_mask & 0xE0U) != 0 || (enabled_mask & 0x1FU) == 0) return model_check(ModelStatus::kBadChannelMask);
  if (ambient_channel != kModelAmbientNone &&
      (ambient_channel >= kModelChannels || ((enabled_mask >> ambient_channel) & 1U) == 0))
    return model_check(ModelStatus::kBadAmbientChannel);
  if (speed_rpm[0] != 0) return model_check(ModelStatus::kBadSpeeds, 0);
  for (uint8_t i = 1; i < kModelMaxBreakpoints; ++i) {
    if (i < n_breakpoints) {
      if (speed_rpm[i] <= speed_rpm[i - 1]) return model_check(ModelStatus::kBadSpeeds, i);
    } else if (speed_rpm[i] != 0) {
      return model_check(ModelStatus::kBadSpeeds, i);
    }
  }
  return model_check(ModelStatus::kOk);
}

// Breakpoint i of a model with n_breakpoints (unused ones must be all zero). Kept out of line:
// avr-gcc inlines its 64-bit arithmetic into the caller's breakpoint loop at ~700 B more flash.
#if defined(__GNUC__)
__attribute__((noinline))
#endif
inline ModelCheck validate_breakpoint(const ModelBreakpoint& p, uint8_t i, uint8_t n_breakpoints) {
  using detail_rm::abs64;
  if (i >= n_breakpoints) {
    bool zero = p.a_q30 == 0 && p.b_q24 == 0;
    for (uint8_t j = 0; j < kModelChannels; ++j) zero = zero && p.c_q24[j] == 0 && p.d_q24[j] == 0;
    return zero ? model_check(ModelStatus::kOk) : model_check(ModelStatus::kUnusedNotZero, i);
  }
  const int32_t one_q30 = static_cast<int32_t>(fx::pow2(kPoleFracBits));
  if (p.a_q30 >= one_q30 || p.a_q30 <= -one_q30) return model_check(ModelStatus::kUnstablePole, i);
  if (i == 0) {
    bool zero = p.b_q24 == 0;
    for (uint8_t j = 0; j < kModelChannels; ++j) zero = zero && p.d_q24[j] == 0;
    if (!zero) return model_check(ModelStatus::kInputAtStandstill, 0);
  }
  // x_ss = b / (1 - a): |b| * 2^6 <= 1000 * (2^30 - a)  (Q24 -> Q30 for b). All in int64.
  const int64_t one_minus_a = one_q30 - static_cast<int64_t>(p.a_q30);  // in (0, 2^31)
  const int64_t b_q30 = static_cast<int64_t>(p.b_q24) * fx::pow2(kPoleFracBits - kGainFracBits);
  if (abs64(b_q30) > (kModelMaxSteadyStateMk / 1000) * one_minus_a)
    return model_check(ModelStatus::kSteadyStateOutOfRange, i);
  // Steady output per channel: |c x_ss + d| <= 1000 K, x_ss in Q20 computed once here.
  const int64_t x_ss_q20 =
      fx::div_round(b_q30 * fx::pow2(kStateFracBits), one_minus_a, fx::Rounding::kNearestHalfAway);
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    const int64_t theta_q44 = static_cast<int64_t>(p.c_q24[j]) * x_ss_q20 +
                              static_cast<int64_t>(p.d_q24[j]) * fx::pow2(kStateFracBits);
    if (abs64(theta_q44) > static_cast<int64_t>(kModelMaxSteadyStateMk / 1000) *
                               fx::pow2(kGainFracBits + kStateFracBits))
      return model_check(ModelStatus::kGainOutOfRange, i, j);
  }
  return model_check(ModelStatus::kOk);
}

// The diagnosis limits of the enabled channels (no residual bands on the ambient channel).
inline ModelCheck validate_limits(const ChannelLimits limits[kModelChannels], uint8_t enabled_mask,
                                  uint8_t ambient_channel) {
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    if (((enabled_mask >> j) & 1U) == 0) continue;
    const ChannelLimits& l = limits[j];
    if (l.abs_limit_mK < kModelMinAbsLimitMk || l.abs_limit_mK > kModelMaxAbsLimitMk)
      return model_check(ModelStatus::kLimitOutOfRange, 0xFF, j);
    if (j == ambient_channel) continue;
    if (l.warn_band_mK == 0 || l.alarm_band_mK <= l.warn_band_mK)
      return model_check(ModelStatus::kBadBands, 0xFF, j);
  }
  return model_check(ModelStatus::kOk);
}

// The whole model (decode() calls it).
inline ModelCheck validate(const ReducedModel& m) {
  ModelCheck c = validate_schedule(m.n_breakpoints, m.dt_ms, m.enabled_mask, m.ambient_channel, m.speed_rpm);
  for (uint8_t i = 0; i < kModelMaxBreakpoints && c.ok(); ++i) c = validate_breakpoint(m.bp[i], i, m.n_breakpoints);
  return c.ok() ? validate_limits(m.limits, m.enabled_mask, m.ambient_channel) : c;
}

// ---- codec --------------------------------------------------------------------------------------

inline void encode_breakpoint(const ModelBreakpoint& p, uint8_t* out /* 48 bytes */) {
  put_le32(out, static_cast<uint32_t>(p.a_q30));
  put_le32(out + 4, static_cast<uint32_t>(p.b_q24));
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    put_le32(out + 8 + 4 * j, static_cast<uint32_t>(p.c_q24[j]));
    put_le32(out + 28 + 4 * j, static_cast<uint32_t>(p.d_q24[j]));
  }
}

// Lets the firmware read just two breakpoints per step straight from the EEPROM blob image.
inline void decode_breakpoint(const uint8_t* in /* 48 bytes */, ModelBreakpoint& p) {
  p.a_q30 = static_cast<int32_t>(get_le32(in));
  p.b_q24 = static_cast<int32_t>(get_le32(in + 4));
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    p.c_q24[j] = static_cast<int32_t>(get_le32(in + 8 + 4 * j));
    p.d_q24[j] = static_cast<int32_t>(get_le32(in + 28 + 4 * j));
  }
}

// Writes exactly kReducedModelBlobSize bytes (CRC included). Encodes what it is given: call
// validate() first if the model did not come from quantize().
inline void encode(const ReducedModel& m, uint8_t* out) {
  memset(out, 0, kReducedModelBlobSize);
  put_le32(out + kBlobOffMagic, kReducedModelMagic);
  out[kBlobOffVersion] = kReducedModelVersion;
  out[kBlobOffBreakpointCount] = m.n_breakpoints;
  out[kBlobOffAmbientChannel] = m.ambient_channel;
  out[kBlobOffEnabledMask] = m.enabled_mask;
  put_le16(out + kBlobOffDtMs, m.dt_ms);
  for (uint8_t i = 0; i < kModelMaxBreakpoints; ++i) {
    put_le16(out + kBlobOffSpeeds + 2 * i, m.speed_rpm[i]);
    encode_breakpoint(m.bp[i], out + kBlobOffBreakpoints + kBlobBreakpointSize * i);
  }
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    put_le16(out + kBlobOffWarnBands + 2 * j, m.limits[j].warn_band_mK);
    put_le16(out + kBlobOffAlarmBands + 2 * j, m.limits[j].alarm_band_mK);
    put_le32(out + kBlobOffAbsLimits + 4 * j, static_cast<uint32_t>(m.limits[j].abs_limit_mK));
    put_le16(out + kBlobOffMaxRise + 2 * j, m.limits[j].max_rise_mK_per_min);
  }
  put_le32(out + kBlobOffCrc, crc32(out, kBlobOffCrc));
}

// CRC of a complete blob as stored in it (the INFO message's model_crc).
inline uint32_t blob_stored_crc(const uint8_t* blob) { return get_le32(blob + kBlobOffCrc); }

// Order of checks: length, CRC, magic, version, then content (validate()). `out` is written only
// when the status is kOk.
inline ModelCheck decode(const uint8_t* blob, size_t len, ReducedModel& out) {
  if (blob == nullptr || len != kReducedModelBlobSize) return model_check(ModelStatus::kBadLength);
  if (crc32(blob, kBlobOffCrc) != get_le32(blob + kBlobOffCrc)) return model_check(ModelStatus::kBadCrc);
  if (get_le32(blob + kBlobOffMagic) != kReducedModelMagic) return model_check(ModelStatus::kBadMagic);
  if (blob[kBlobOffVersion] != kReducedModelVersion) return model_check(ModelStatus::kBadVersion);
  ReducedModel m;
  m.version = blob[kBlobOffVersion];
  m.n_breakpoints = blob[kBlobOffBreakpointCount];
  m.ambient_channel = blob[kBlobOffAmbientChannel];
  m.enabled_mask = blob[kBlobOffEnabledMask];
  m.dt_ms = get_le16(blob + kBlobOffDtMs);
  for (uint8_t i = 0; i < kModelMaxBreakpoints; ++i) {
    m.speed_rpm[i] = get_le16(blob + kBlobOffSpeeds + 2 * i);
    decode_breakpoint(blob + kBlobOffBreakpoints + kBlobBreakpointSize * i, m.bp[i]);
  }
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    m.limits[j].warn_band_mK = get_le16(blob + kBlobOffWarnBands + 2 * j);
    m.limits[j].alarm_band_mK = get_le16(blob + kBlobOffAlarmBands + 2 * j);
    m.limits[j].abs_limit_mK = static_cast<int32_t>(get_le32(blob + kBlobOffAbsLimits + 4 * j));
    m.limits[j].max_rise_mK_per_min = get_le16(blob + kBlobOffMaxRise + 2 * j);
  }
  const ModelCheck c = validate(m);
  if (c.ok()) out = m;
  return c;
}

// ---- quantisation (host side) -------------------------------------------------------------------

namespace detail_rm {
inline bool finite(double v) { return v == v && v - v == 0.0; }

// Rounds v * 2^frac to int32; false if it does not fit.
inline bool to_q(double v, int frac, int32_t& out) {
  fx::FxStatus st = fx::FxStatus::kOk;
  out = fx::Fixed<int32_t, 0>::from_double(v * static_cast<double>(fx::pow2(frac)),
                                           fx::Rounding::kNearestHalfAway, &st).raw();
  return st == fx::FxStatus::kOk;
}

// Rounds a physical value (K or degC) to integer mK within [lo, hi].
inline bool to_mk(double v_k, int32_t lo, int32_t hi, int32_t& out) {
  if (!finite(v_k)) return false;
  const double mk = v_k * 1000.0;
  if (mk < static_cast<double>(lo) - 0.5 || mk > static_cast<double>(hi) + 0.5) return false;
  out = static_cast<int32_t>(mk < 0 ? mk - 0.5 : mk + 0.5);
  if (out < lo) out = lo;
  if (out > hi) out = hi;
  return true;
}
}  // namespace detail_rm

// Converts the host's double model to the fixed-point model and validates it. On error `out` is
// unspecified and the check names the status and the breakpoint/channel at fault.
inline ModelCheck quantize(const ReducedModelF64& f, ReducedModel& out) {
  using detail_rm::finite;
  using detail_rm::to_mk;
  using detail_rm::to_q;
  memset(&out, 0, sizeof(out));
  out.version = kReducedModelVersion;
  if (f.n_breakpoints < kModelMinBreakpoints || f.n_breakpoints > kModelMaxBreakpoints)
    return model_check(ModelStatus::kBadBreakpointCount);
  out.n_breakpoints = f.n_breakpoints;
  out.ambient_channel = f.ambient_channel;
  out.enabled_mask = f.enabled_mask;
  out.dt_ms = f.dt_ms;
  for (uint8_t i = 0; i < f.n_breakpoints; ++i) {
    out.speed_rpm[i] = f.speed_rpm[i];
    if (!finite(f.a[i]) || !finite(f.b[i])) return model_check(ModelStatus::kNotFinite, i);
    for (uint8_t j = 0; j < kModelChannels; ++j)
      if (!finite(f.c[i][j]) || !finite(f.d[i][j])) return model_check(ModelStatus::kNotFinite, i, j);
    if (!(f.a[i] > -1.0 && f.a[i] < 1.0) || !to_q(f.a[i], kPoleFracBits, out.bp[i].a_q30))
      return model_check(ModelStatus::kUnstablePole, i);
    if (!to_q(f.b[i], kGainFracBits, out.bp[i].b_q24)) return model_check(ModelStatus::kGainOutOfRange, i);
    for (uint8_t j = 0; j < kModelChannels; ++j) {
      if (!to_q(f.c[i][j], kGainFracBits, out.bp[i].c_q24[j]) ||
          !to_q(f.d[i][j], kGainFracBits, out.bp[i].d_q24[j]))
        return model_check(ModelStatus::kGainOutOfRange, i, j);
    }
  }
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    if (((f.enabled_mask >> j) & 1U) == 0) continue;
    int32_t warn = 0, alarm = 0, limit = 0, rise = 0;
    if (!to_mk(f.warn_band_k[j], 0, 65535, warn) || !to_mk(f.alarm_band_k[j], 0, 65535, alarm) ||
        !to_mk(f.abs_limit_c[j], kModelMinAbsLimitMk, kModelMaxAbsLimitMk, limit) ||
        !to_mk(f.max_rise_k_per_min[j], 0, 65535, rise))
      return model_check(ModelStatus::kLimitOutOfRange, 0xFF, j);
    out.limits[j].warn_band_mK = static_cast<uint16_t>(warn);
    out.limits[j].alarm_band_mK = static_cast<uint16_t>(alarm);
    out.limits[j].abs_limit_mK = limit;
    out.limits[j].max_rise_mK_per_min = static_cast<uint16_t>(rise);
  }
  return validate(out);
}

// ---- evaluation ---------------------------------------------------------------------------------

// Where speed s falls: lower breakpoint index, Q0.16 fraction towards the next one, and u.
struct SpeedSegment {
  uint8_t lo;
  uint8_t hi;
  uint16_t frac_q16;  // 0 when lo == hi
  bool running;       // u
};

inline SpeedSegment find_segment(const uint16_t* speeds, uint8_t n, uint16_t speed_rpm) {
  SpeedSegment s;
  s.running = speed_rpm > 0;
  s.frac_q16 = 0;
  s.lo = s.hi = 0;
  if (!s.running || n == 0) return s;
  if (speed_rpm >= speeds[n - 1]) {
    s.lo = s.hi = static_cast<uint8_t>(n - 1);
    return s;
  }
  uint8_t i = 0;
  while (i + 1 < n && speeds[i + 1] <= speed_rpm) ++i;
  s.lo = i;
  s.hi = static_cast<uint8_t>(i + 1);
  s.frac_q16 = detail_rm::fraction_q16(static_cast<uint16_t>(speed_rpm - speeds[i]),
                                       static_cast<uint16_t>(speeds[i + 1] - speeds[i]));
  return s;
}

namespace detail_rm {
// The evaluation below is bit-identical to forming every product exactly in int64 and rounding
// it once with fx::shift_right_round(..., kNearestHalfAway) (tests/unit/common_numeric checks
// this against that reference on random operands), but avoids the AVR's slowest 64-bit paths:
// products are 32x32->64 widening multiplications (__mulsidi3, not the 64x64 __muldi3), the
// interpolation needs no 64-bit arithmetic at all, and the rounding shift is one add and one
// shift (fx::shift_right_round: three variable 64-bit shifts and 64-bit compares).

// round(v / 2^s), ties away from zero, for 1 <= s <= 62 and |v| < 2^63 - 2^(s-1) (no overflow of
// the addition; every call below is far inside that by the Q formats in the header: |c x| < 2^62,
// |d 2^20| < 2^51, |a x| < 2^61): floor((v + 2^(s-1) - [v < 0]) / 2^s).
inline int64_t round_shift(int64_t v, int s) {
  return (v + (fx::pow2(s - 1) - (v < 0 ? 1 : 0))) >> s;
}

// The 48-bit product d * f as its upper 32 bits (d * f) >> 16 and its low 16 bits. On the AVR
// eight hardware 8 x 8 multiplications in place (~45 cycles): avr-gcc 5.4 compiles the portable
// form into two __umulhisi3 calls whose 32-bit operands and results it spills to the stack
// (~330 cycles per interpolated coefficient). The host never compiles the assembly:
// tests/simavr/sim/avr_numeric_test.cpp runs it on the simulated ATmega328P against exact results.
BTSM_ALWAYS_INLINE void mul_u32_u16(uint32_t d, uint16_t f, uint32_t& high, uint16_t& low) {
#if defined(__AVR__)
  uint32_t h;
  uint16_t l;
  uint8_t zero;
  // Product bytes P0..P5: P1:P0 = l, P5..P2 = h. Partial products d_i f_j go to byte i + j.
  // r1 (the compiler's zero register) is the multiplier's high result byte: cleared at the end.
  __asm__(
      "clr  %[z]"            "\n\t"
      "mul  %A[d], %A[f]"    "\n\t"  // d0 f0 -> P1:P0
      "movw %A[l], r0"       "\n\t"
      "mul  %B[d], %B[f]"    "\n\t"  // d1 f1 -> P3:P2
      "movw %A[h], r0"       "\n\t"
      "mul  %D[d], %B[f]"    "\n\t"  // d3 f1 -> P5:P4
      "movw %C[h], r0"       "\n\t"
      "mul  %B[d], %A[f]"    "\n\t"  // d1 f0 -> P2:P1
      "add  %B[l], r0"       "\n\t"
      "adc  %A[h], r1"       "\n\t"
      "adc  %B[h], %[z]"     "\n\t"
      "adc  %C[h], %[z]"     "\n\t"
      "adc  %D[h], %[z]"     "\n\t"
      "mul  %A[d], %B[f]"    "\n\t"  // d0 f1 -> P2:P1
      "add  %B[l], r0"       "\n\t"
      "adc  %A[h], r1"       "\n\t"
      "adc  %B[h], %[z]"     "\n\t"
      "adc  %C[h], %[z]"     "\n\t"
      "adc  %D[h], %[z]"     "\n\t"
      "mul  %C[d], %A[f]"    "\n\t"  // d2 f0 -> P3:P2
      "add  %A[h], r0"       "\n\t"
      "adc  %B[h], r1"       "\n\t"
      "adc  %C[h], %[z]"     "\n\t"
      "adc  %D[h], %[z]"     "\n\t"
      "mul  %C[d], %B[f]"    "\n\t"  // d2 f1 -> P4:P3
      "add  %B[h], r0"       "\n\t"
      "adc  %C[h], r1"       "\n\t"
      "adc  %D[h], %[z]"     "\n\t"
      "mul  %D[d], %A[f]"    "\n\t"  // d3 f0 -> P4:P3
      "add  %B[h], r0"       "\n\t"
      "adc  %C[h], r1"       "\n\t"
      "adc  %D[h], %[z]"     "\n\t"  // no carry out: the product is below 2^48
      "clr  __zero_reg__"
      : [h] "=&r"(h), [l] "=&r"(l), [z] "=&r"(zero)
      : [d] "r"(d), [f] "r"(f)
      : "r0");
  high = h;
  low = l;
#else
  const uint32_t lo_part = static_cast<uint32_t>(static_cast<uint16_t>(d)) * f;  // < 2^32
  high = static_cast<uint32_t>(d >> 16) * f + (lo_part >> 16);                     // < 2^32
  low = static_cast<uint16_t>(lo_part);
#endif
}

// p0 + round((p1 - p0) * f / 2^16) in 32-bit arithmetic. The true difference d (33 bits) is
// dm - [p1 < p0] 2^32 with dm = (p1 - p0) mod 2^32, so d * f / 2^16 = (dm * f) / 2^16 -
// [p1 < p0] f 2^16; the result lies between p0 and p1, so computing modulo 2^32 gives it exactly.
// Forced inline: the firmware calls it from one loop (ModelStore::refresh_coefficients).
BTSM_ALWAYS_INLINE int32_t lerp_q(int32_t p0, int32_t p1, uint16_t f) {
  const bool negative = p1 < p0;
  const uint32_t dm = static_cast<uint32_t>(p1) - static_cast<uint32_t>(p0);  // d mod 2^32
  uint32_t high;
  uint16_t rem;
  mul_u32_u16(dm, f, high, rem);
  uint32_t r = static_cast<uint32_t>(p0) + high - (negative ? static_cast<uint32_t>(f) << 16 : 0U);
  if (rem > 0x8000U || (rem == 0x8000U && !negative)) ++r;  // ties away from zero
  return static_cast<int32_t>(r);
}

// A 64-bit two's-complement value as two 32-bit words, v = hi * 2^32 + lo. step_with works on
// these instead of int64_t: avr-gcc 5.4 has no inline 64-bit shifts (every shift of an int64 is a
// bit-serial library loop, ~130 cycles), and even 32-bit shifts by counts that are not multiples
// of 8 are bit loops; so every shift below is by 8, 16 or 24 bits (register moves) or by at most
// 6 bits. The arithmetic is exact (the same integers as the int64 form).
struct Wide {
  uint32_t lo;
  int32_t hi;
};

// a * b exactly. On a little-endian target the int64 product (libgcc's 32x32->64 __mulsidi3 on
// AVR) is read as its two words through a union -- no shift at all (GCC documents union type
// punning; on AVR the returned registers already are the two words).
BTSM_ALWAYS_INLINE Wide mul_wide(int32_t a, int32_t b) {
#if BTSM_LITTLE_ENDIAN
  union {
    int64_t v;
    Wide w;
  } u;
  u.v = static_cast<int64_t>(a) * b;
  return u.w;
#else
  const int64_t v = static_cast<int64_t>(a) * b;
  Wide w;
  w.lo = static_cast<uint32_t>(v);
  w.hi = static_cast<int32_t>(v >> 32);
  return w;
#endif
}

// round((c x + [running] d 2^20) / 2^24) (= round_shift(.., 24)) for p = c x, when
// |c x| < 2^54 (|theta| < 1024 K): returns true and stores it; false otherwise.
//   c x = q 2^24 + r (0 <= r < 2^24: q is a byte move of the words), d 2^20 = (d >> 4) 2^24 +
//   (d mod 16) 2^20; then value = q 2^24 + r with 0 <= r < 2^24 and the sign of the value is the
//   sign of q, so rounding half away from zero adds 1 when r > 2^23, or r == 2^23 and q >= 0.
BTSM_ALWAYS_INLINE bool theta_q20(Wide p, int32_t d, bool running, int32_t& out) {
  if (static_cast<uint32_t>(static_cast<uint32_t>(p.hi) + 0x400000UL) >= 0x800000UL) return false;  // hi outside [-2^22, 2^22)
  int32_t q = static_cast<int32_t>((static_cast<uint32_t>(p.hi) << 8) | (p.lo >> 24));
  uint32_t r = p.lo & 0x00FFFFFFUL;
  if (running) {
    q += d >> 4;
    r += static_cast<uint32_t>(static_cast<uint8_t>(static_cast<uint8_t>(d) << 4)) << 16;
    if (r >= 0x1000000UL) {
      ++q;
      r &= 0x00FFFFFFUL;
    }
  }
  if (r > 0x800000UL || (r == 0x800000UL && q >= 0)) ++q;
  out = q;
  return true;
}

// round(t * 1000 / 2^20) = round(t * 125 / 2^17) (= round_shift(t * 1000, 20): the two floors
// agree because dividing numerator and denominator by 8 moves the -[neg] term by less than 1).
//   t * 125 = a 2^16 + b (0 <= b < 2^16; a from the high half times 125 plus the carry of the
//   low half), a = 2 h + a0: value / 2^17 = h + (a0 2^16 + b) / 2^17, sign of the value = sign of a.
BTSM_ALWAYS_INLINE int32_t q20_to_mk(int32_t t) {
  const uint32_t low = static_cast<uint32_t>(static_cast<uint16_t>(t)) * 125U;  // < 2^23
  const int32_t a = static_cast<int32_t>(static_cast<int16_t>(static_cast<uint32_t>(t) >> 16)) * 125 +
                    static_cast<int32_t>(low >> 16);
  const uint32_t rest = (static_cast<uint32_t>(a & 1) << 16) + static_cast<uint16_t>(low);  // < 2^17
  const int32_t h = a >> 1;  // floor
  return h + ((rest > 0x10000UL || (rest == 0x10000UL && a >= 0)) ? 1 : 0);
}

// saturate<int32>(round((a x + [running] b 2^26) / 2^30)) for p = a x (|a x| <= 2^62).
//   value = q 2^32 + r (0 <= r < 2^32) with b 2^26 = (b >> 6) 2^32 + (b mod 64) 2^26; then
//   result = 4 q + floor((r + 2^29 - [q < 0]) / 2^30), that floor in 0..4 (a carry and two bits).
BTSM_ALWAYS_INLINE int32_t next_state_q20(Wide p, int32_t b, bool running) {
  int32_t q = p.hi;
  uint32_t r = p.lo;
  if (running) {
    q += b >> 6;
    const uint32_t add = static_cast<uint32_t>(static_cast<uint8_t>(static_cast<uint8_t>(b) << 2)) << 24;
    r += add;
    if (r < add) ++q;
  }
  if (q >= 0x20000000L) return 0x7FFFFFFFL;       // value >= 2^61: beyond int32
  if (q < -0x20000000L) return -0x7FFFFFFFL - 1;  // value < -2^61
  const uint32_t half = q < 0 ? 0x1FFFFFFFUL : 0x20000000UL;
  const uint32_t t = r + half;
  const uint8_t carry = static_cast<uint8_t>((t < half ? 4U : 0U) + (static_cast<uint8_t>(t >> 24) >> 6));
  const uint32_t v = (static_cast<uint32_t>(q) << 2) + carry;
  if (q >= 0 && static_cast<int32_t>(v) < 0) return 0x7FFFFFFFL;  // 4 q + 4 = 2^31
  return static_cast<int32_t>(v);
}

// The channels step_with does not predict: a disabled channel, every channel while the ambient
// reading is missing (kModelNoPrediction), and the ambient channel (its "prediction" is its own
// reading). True for those, with their value in `out`; `bit` is 1 << j.
BTSM_ALWAYS_INLINE bool unmodelled_channel(uint8_t j, uint8_t bit, uint8_t enabled_mask, uint8_t ambient_channel,
                                       int32_t ambient_mK, int32_t& out) {
  if ((enabled_mask & bit) == 0 || ambient_mK == kModelNoPrediction) {
    out = kModelNoPrediction;
    return true;
  }
  if (j == ambient_channel) {
    out = ambient_mK;
    return true;
  }
  return false;
}

}  // namespace detail_rm

// Coefficients at one speed (linear interpolation between two breakpoints, see header).
inline void interpolate(const ModelBreakpoint& lo, const ModelBreakpoint& hi, uint16_t frac_q16,
                        ModelBreakpoint& out) {
  if (frac_q16 == 0) {  // exactly breakpoint lo (lerp_q(p0, p1, 0) == p0)
    out = lo;
    return;
  }
  // Member-wise as one loop over the twelve int32 (lerp_q is inlined once, not twelve times);
  // out may alias lo: each member is read before it is written.
  static_assert(sizeof(ModelBreakpoint) == 12 * sizeof(int32_t), "ModelBreakpoint: twelve int32, no padding");
  const uint8_t* l = reinterpret_cast<const uint8_t*>(&lo);
  const uint8_t* h = reinterpret_cast<const uint8_t*>(&hi);
  uint8_t* o = reinterpret_cast<uint8_t*>(&out);
  for (uint8_t k = 0; k < 12; ++k, l += 4, h += 4, o += 4) {
    int32_t p0, p1;
    memcpy(&p0, l, 4);
    memcpy(&p1, h, 4);
    p0 = detail_rm::lerp_q(p0, p1, frac_q16);
    memcpy(o, &p0, 4);
  }
}

inline void reset(ReducedModelState& st) { st.x_q20 = 0; }

// One sample with already interpolated coefficients `p` (for firmware that reads breakpoints from
// EEPROM itself). Writes predicted temperatures (mK, degC*1000) for every channel, then advances
// the state. ambient_mK == kModelNoPrediction -> all predictions kModelNoPrediction (the state
// still advances: it is relative to ambient).
//
// Bit-identical to forming every product exactly in int64 and rounding it once (round_shift)
// while |c x| < 1024 K (beyond, which no real temperature reaches, the prediction saturates):
// tests/unit/common_numeric compares it with that int64 form on random states and coefficients.
// The sums and roundings work on the 32-bit words of the products (detail_rm::Wide) with byte-move
// shifts: on the AVR the int64 form spent ~5k cycles per step in libgcc's bit-serial 64-bit
// shifts (__ashrdi3/__lshrdi3/__ashldi3).
inline void step_with(const ModelBreakpoint& p, bool running, uint8_t ambient_channel,
                      uint8_t enabled_mask, ReducedModelState& st, int32_t ambient_mK,
                      int32_t predicted_mK[kModelChannels]) {
  using namespace detail_rm;
  const int32_t x = st.x_q20;
  // Beyond +-2^30 mK any ambient + theta (|theta| < 2^21 mK here) ends up clamped to the wire's
  // range anyway, so clamping the ambient first changes nothing and keeps the sums in 32 bits.
  const int32_t amb = ambient_mK > 0x40000000L ? 0x40000000L : (ambient_mK < -0x40000000L ? -0x40000000L : ambient_mK);
  uint8_t bit = 1;
  for (uint8_t j = 0; j < kModelChannels; ++j, bit = static_cast<uint8_t>(bit << 1)) {
    if (unmodelled_channel(j, bit, enabled_mask, ambient_channel, ambient_mK, predicted_mK[j])) continue;
    // theta (Q44) = c (Q24) * x (Q20) + d (Q24) * u * 2^20; |theta| < 2^62 by the Q ranges.
    const Wide cx = mul_wide(p.c_q24[j], x);
    int32_t t_q20;
    int32_t v;
    if (theta_q20(cx, p.d_q24[j], running, t_q20)) {
      v = amb + q20_to_mk(t_q20);
      // Keep the result inside the wire's i24 range and off the kMissing code.
      if (v > kInt24Max) v = kInt24Max;
      if (v <= kModelNoPrediction) v = kModelNoPrediction + 1;
    } else {
      // |c x| >= 1024 K: no temperature a probe can have (validated models keep |c x_ss + d| <=
      // 1000 K); the prediction saturates at the end of the wire's range on that side.
      v = cx.hi < 0 ? kModelNoPrediction + 1 : kInt24Max;
    }
    predicted_mK[j] = v;
  }
  // x' = a x + b u, one rounding from Q50, saturated to int32 (as fx::saturate).
  st.x_q20 = next_state_q20(mul_wide(p.a_q30, x), p.b_q24, running);
}

// One sample of the model at spindle speed `speed_rpm` (see the header for the definition).
inline void step(const ReducedModel& m, ReducedModelState& st, uint16_t speed_rpm, int32_t ambient_mK,
                 int32_t predicted_mK[kModelChannels]) {
  const SpeedSegment seg = find_segment(m.speed_rpm, m.n_breakpoints, speed_rpm);
  ModelBreakpoint p;
  interpolate(m.bp[seg.lo], m.bp[seg.hi], seg.frac_q16, p);
  step_with(p, seg.running, m.ambient_channel, m.enabled_mask, st, ambient_mK, predicted_mK);
}

// Initialise the state from one set of measured temperatures (mK) instead of assuming the machine
// is at ambient: least squares x = sum c_j (theta_j - d_j u) / sum c_j^2 over enabled, non-ambient
// channels with a valid reading (!= kModelNoPrediction), with already interpolated coefficients
// `p` (as step_with). Float is fine here: it runs once and the result is only a starting point.
// Returns false (state untouched) when no channel qualifies.
inline bool init_from_measurement_with(const ModelBreakpoint& p, bool running, uint8_t ambient_channel,
                                       uint8_t enabled_mask, ReducedModelState& st, int32_t ambient_mK,
                                       const int32_t measured_mK[kModelChannels]) {
  if (ambient_mK == kModelNoPrediction) return false;
  float num = 0.0f, den = 0.0f;
  const float gain_scale = 1.0f / static_cast<float>(fx::pow2(kGainFracBits));
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    if (((enabled_mask >> j) & 1U) == 0 || j == ambient_channel) continue;
    if (measured_mK[j] == kModelNoPrediction) continue;
    const float c = static_cast<float>(p.c_q24[j]) * gain_scale;
    const float d = running ? static_cast<float>(p.d_q24[j]) * gain_scale : 0.0f;
    const float theta = static_cast<float>(measured_mK[j] - ambient_mK) * 0.001f;
    num += c * (theta - d);
    den += c * c;
  }
  if (!(den > 1e-6f)) return false;
  const float x = num / den;
  const float limit = 2047.0f;
  const float xc = x > limit ? limit : (x < -limit ? -limit : x);
  st.x_q20 = static_cast<int32_t>(xc * static_cast<float>(fx::pow2(kStateFracBits)));
  return true;
}

// The same at spindle speed `speed_rpm`.
inline bool init_from_measurement(const ReducedModel& m, ReducedModelState& st, uint16_t speed_rpm,
                                  int32_t ambient_mK, const int32_t measured_mK[kModelChannels]) {
  if (ambient_mK == kModelNoPrediction) return false;
  const SpeedSegment seg = find_segment(m.speed_rpm, m.n_breakpoints, speed_rpm);
  ModelBreakpoint p;
  interpolate(m.bp[seg.lo], m.bp[seg.hi], seg.frac_q16, p);
  return init_from_measurement_with(p, seg.running, m.ambient_channel, m.enabled_mask, st, ambient_mK, measured_mK);
}

// ---- double reference (host side) --------------------------------------------------------------

// Same definition as step() in double with the exact interpolation fraction: the reference the
// fixed-point evaluation is tested against, and what the host uses to predict.
inline void step(const ReducedModelF64& m, ReducedModelF64State& st, double speed_rpm, double ambient_c,
                 double predicted_c[kModelChannels]) {
  const uint8_t n = m.n_breakpoints;
  const bool running = speed_rpm > 0.0;
  uint8_t lo = 0, hi = 0;
  double f = 0.0;
  if (running && n > 0) {
    if (speed_rpm >= m.speed_rpm[n - 1]) {
      lo = hi = static_cast<uint8_t>(n - 1);
    } else {
      while (lo + 1 < n && m.speed_rpm[lo + 1] <= speed_rpm) ++lo;
      hi = static_cast<uint8_t>(lo + 1);
      f = (speed_rpm - m.speed_rpm[lo]) / (static_cast<double>(m.speed_rpm[hi]) - m.speed_rpm[lo]);
    }
  }
  const double u = running ? 1.0 : 0.0;
  const double a = m.a[lo] + (m.a[hi] - m.a[lo]) * f;
  const double b = m.b[lo] + (m.b[hi] - m.b[lo]) * f;
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    if (((m.enabled_mask >> j) & 1U) == 0) {
      predicted_c[j] = NAN;
      continue;
    }
    if (j == m.ambient_channel) {
      predicted_c[j] = ambient_c;
      continue;
    }
    const double c = m.c[lo][j] + (m.c[hi][j] - m.c[lo][j]) * f;
    const double d = m.d[lo][j] + (m.d[hi][j] - m.d[lo][j]) * f;
    predicted_c[j] = ambient_c + c * st.x + d * u;
  }
  st.x = a * st.x + b * u;
}

}  // namespace btsm

#endif  // BTSM_COMMON_REDUCED_MODEL_HPP
