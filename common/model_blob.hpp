// The reduced-model blob the host flashes into the module (format version 2): its fixed-point
// content, validation, and the little-endian codec in a checked pair. The evaluation is in
// model_step.hpp; the host's double-precision reference and quantizer in host/thermal.
//
// ---------------------------------------------------------------------------------------------
// THE MODEL: one first-order model per diagnosed channel (own pole, own gains)
//
//   Channel j predicts the temperature of one node of the fitted network (the channel map: which
//   module channel role the model was reduced for, below). Its state is that temperature itself,
//   T_j, in degC. Each model step of dt:
//       predicted_j = T_j
//       T_j' = T_amb + a_j (T_j - T_amb) + u b_j
//   with u = 1 while the spindle turns. So the ambient enters through the channel's own pole (the
//   steady state follows it with gain 1, and a drifting ambient reaches the prediction with the
//   channel's lag, not at once), and the heat of the running spindle through b_j: the steady
//   rise is b_j / (1 - a_j) (DC-matched to the full network by the host). A speed change changes
//   a and b, never T: the prediction does not jump.
//
//   Coefficients (a_j, b_j) come from breakpoints at speeds s_0 = 0 < s_1 < ... < s_{n-1} (rpm):
//     speed == 0            -> breakpoint 0 (stopped: b = 0), with the stop phases below
//     speed >= s_{n-1}      -> breakpoint n-1 (held, never extrapolated)
//     s_i <= speed < s_{i+1} -> linear interpolation of a and b, f = (speed - s_i)/(s_{i+1} - s_i)
//   The steady rise b/(1-a) of an interpolated point lies between its breakpoints' (a linear-
//   fractional function of f is monotone), so validating breakpoints bounds every point.
//   Stop phases: the first minutes of a stop redistribute heat inside the spindle (a bearing
//   cools into the housing, faster than the whole spindle cools to ambient), which one pole
//   cannot follow. So while stopped, the pole also depends on the time since the stop:
//     [0, stop_end_s[0])            a = stop_a[0][j]
//     [stop_end_s[0], stop_end_s[1]) a = stop_a[1][j]
//     later                          a = breakpoint 0's a_j
//   stop_end_s[0] == 0: no early phases; stop_end_s[1] == 0: only the first one.
//   The first-order form and the time-scheduled stop pole are what keeps each channel ONE state.
//
//   Carrier (optional, per channel): channel j may ride on the model of a slower channel h (its
//   carrier, e.g. a bearing on the housing or the shaft):
//       T_j' = T_amb + a_j (T_j - T_amb) + c_j (T_h - T_amb) + u b_j        (T_h before the step)
//   with a constant coupling 0 <= c_j < 1 per step. Why: after a stop a bearing does not cool (or
//   warm, when the shaft is hotter) towards the ambient but towards what the housing or shaft
//   around it holds, and after a restart it warms back towards that in minutes; how far it has to
//   go depends on how long and from which speed it stopped, which no pole scheduled on the time
//   since the stop or start can know, but the carrier's state does. Still one state per channel
//   and first order in it; the carrier has no carrier of its own (a cascade: stable whenever every
//   pole is). The host DC-matches b_j with the carrier's steady rise: (b_j + c_j R_h)/(1 - a_j) =
//   R_j at every breakpoint. Carrier byte 0 = none (then c_j = 0): a model without carriers is
//   exactly the plain one.
//
// FIXED POINT (why):
//   T, b     int32 Q21.10 mK (LSB 2^-10 mK ~ 1 uK, range +-2^30 LSB = +-1048 K): the ambient in
//            mK becomes a state value by a shift, and the prediction is T rounded to mK.
//   a        int32 Q1.30, 0 <= a < 1 (a = exp(-dt/tau) of a first-order pole): a T stays between
//            T_amb and T, so the update cannot overflow.
//   f        uint16 Q0.16 interpolation fraction, floor((s - s_i) 2^16 / (s_{i+1} - s_i)).
//   One rounding per step (nearest, ties away from zero) of a (T - T_amb): its error accumulates
//   to at most 0.5 LSB / (1 - a) = 0.26 mK at tau = 45 min, dt = 5 s, even with equal signs.
//
// THE DETECTOR PARAMETERS (per channel; the module's evidence, common/diagnosis.hpp):
//   drift_mK           residual (measured - predicted) the upper evidence forgives per sample
//   low_drift_mK       the same for the lower evidence (a model error's two signs differ in size)
//   warn_evidence      upper evidence above -> WARN        (units: 128 mK x samples, a shift on the MCU)
//   alarm_evidence     upper evidence above -> ALARM       (> warn_evidence)
//   low_warn_evidence  lower evidence above -> WARN only   (0 = off): a probe colder than its model
//   abs_limit_mK       measured above -> ALARM (degC * 1000)
//   max_rise_mK_per_min rate of rise above -> ALARM; 0 = off
//
// THE CHANNEL MAP: role[j] = the module channel role (wire ChannelRole code) of the node channel j
//   predicts, so the module and the host can check it against the module's configured roles:
//     0 (disabled) = channel not modelled; 1 (ambient) = the ambient channel; a thermal role code
//     (2..6, 8) = that node; kModelRoleUnchecked = a node with no role name (custom networks).
//
// ---------------------------------------------------------------------------------------------
// THE BLOB (little-endian, fixed size kReducedModelBlobSize = 464 bytes, CRC-32 last)
//   off  size  field
//     0     4  magic 0x4D525442 (bytes "BTRM")
//     4     1  version (kReducedModelVersion = 2; version 1 had one state shared by all channels)
//     5     1  n_breakpoints (2..7)
//     6     1  ambient_channel (0..4, or 0xFF = none)
//     7     1  enabled_mask (bit j = channel j has a prediction, the ambient channel included)
//     8     2  dt_ms (100..60000): the sample period the poles were discretised for
//    10     4  stop_end_s[2]  u16 (see stop phases)
//    14    14  speed_rpm[7]   u16; entry 0 = 0, strictly ascending up to n-1, unused entries 0
//    28   280  breakpoint[7], 40 bytes each: per channel a (i32 Q1.30), b (i32 Q21.10 mK)
//   308    40  stop_a[2][5]   i32 Q1.30, the early stop-phase poles per channel
//   348     5  role[5]        u8 channel map
//   353    10  drift_mK[5]             u16
//   363    10  low_drift_mK[5]         u16
//   373    10  warn_evidence[5]        u16
//   383    10  alarm_evidence[5]       u16
//   393    10  low_warn_evidence[5]    u16
//   403    20  abs_limit_mK[5]         i32
//   423    10  max_rise_mK_per_min[5]  u16
//   433     5  carrier[5]     u8: 0 = none, h + 1 = channel h is channel j's carrier
//   438    20  coupling[5]    i32 Q1.30, c_j (0 <= c_j < 1; 0 without a carrier)
//   458     2  reserved, zero
//   460     4  crc32 (IEEE, reflected, as btsm::crc32) over bytes 0..459 (at the same offset in
//              version 1, so INFO's model_crc names a blob of either version)
//   Unmodelled channels (disabled, ambient) have all-zero coefficients and detector fields.
//   Bytes 433..457 were reserved (zero) in the first version-2 layout: such a blob is the same
//   model without carriers.
//
// C++14, no standard library, header-only: shared by the firmware (avr-g++ 5.4) and the host.
#ifndef BTSM_COMMON_MODEL_BLOB_HPP
#define BTSM_COMMON_MODEL_BLOB_HPP

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "byte_order.hpp"
#include "channels.hpp"
#include "crc.hpp"
#include "platform.hpp"
#include "wire_messages.hpp"

namespace btsm {

const uint8_t kModelChannels = kChannels;  // one model per module channel (common/channels.hpp)
const uint8_t kModelMaxBreakpoints = 7;
const uint8_t kModelMinBreakpoints = 2;  // stopped + at least one running speed
const uint8_t kModelEarlyStopPhases = 2;
const uint32_t kReducedModelMagic = 0x4D525442UL;  // "BTRM" in byte order
const uint8_t kReducedModelVersion = 2;
const size_t kReducedModelBlobSize = 464;
const uint8_t kModelAmbientNone = 0xFF;
const uint16_t kModelMinDtMs = 100;
const uint16_t kModelMaxDtMs = 60000;
const uint8_t kModelRoleNotModelled = 0;  // = wire ChannelRole::Disabled
const uint8_t kModelRoleAmbient = 1;      // = wire ChannelRole::Ambient
const uint8_t kModelRoleUnchecked = 0xFF;

const int kPoleFracBits = 30;   // a: Q1.30
const int kStateFracBits = 10;  // T, b: Q21.10 mK (model_step.hpp's shr10/shl10 are for 10)
const int kSpeedFracBits = 16;  // interpolation fraction: Q0.16
const int32_t kEvidenceUnitMkSamples = 128;  // one unit of the evidence thresholds (2^kEvidenceUnitShift)
const int kEvidenceUnitShift = 7;

// A threshold in evidence units as mK x samples (u << 7), and the evidence cap of a channel:
// 2 x its ALARM threshold = u << 8 (below 2^24 for any u16). On the AVR a 32-bit shift by 7 is a
// 7-turn bit loop; as a byte move and one bit it is a few instructions (the empty asm keeps
// avr-gcc from folding the two shifts back into one).
inline int32_t evidence_mk_samples(uint16_t units) {
#if defined(__AVR__)
  uint32_t v = static_cast<uint32_t>(units) << 8;
  __asm__("" : "+r"(v));
  return static_cast<int32_t>(v >> 1);
#else
  return static_cast<int32_t>(static_cast<uint32_t>(units) << kEvidenceUnitShift);
#endif
}
inline int32_t evidence_cap_mk_samples(uint16_t alarm_units) {
  return static_cast<int32_t>(static_cast<uint32_t>(alarm_units) << (kEvidenceUnitShift + 1));
}

// Validation bounds (the host's quantizer applies them too).
const int32_t kModelMaxSteadyRiseMk = 1000000;  // |b / (1 - a)| <= 1000 K
const int32_t kModelMinAbsLimitMk = -200000;    // IEC 60751 range of the probes
const int32_t kModelMaxAbsLimitMk = 850000;

// Prediction value for "no prediction" (unmodelled channel, missing ambient); equals the wire's
// kMissing (-2^23) so it can be sent as is.
const int32_t kModelNoPrediction = -8388608L;

// Blob layout offsets.
const size_t kBlobOffMagic = 0;
const size_t kBlobOffVersion = 4;
const size_t kBlobOffBreakpointCount = 5;
const size_t kBlobOffAmbientChannel = 6;
const size_t kBlobOffEnabledMask = 7;
const size_t kBlobOffDtMs = 8;
const size_t kBlobOffStopEnds = 10;
const size_t kBlobOffSpeeds = 14;
const size_t kBlobOffBreakpoints = 28;
const size_t kBlobChannelCoeffSize = 8;
const size_t kBlobBreakpointSize = kModelChannels * kBlobChannelCoeffSize;  // 40
const size_t kBlobOffStopPoles = 308;
const size_t kBlobOffRoles = 348;
const size_t kBlobOffDrift = 353;
const size_t kBlobOffLowDrift = 363;
const size_t kBlobOffWarnEvidence = 373;
const size_t kBlobOffAlarmEvidence = 383;
const size_t kBlobOffLowWarnEvidence = 393;
const size_t kBlobOffAbsLimits = 403;
const size_t kBlobOffMaxRise = 423;
const size_t kBlobOffCarriers = 433;
const size_t kBlobOffCouplings = 438;
const size_t kBlobOffReserved = 458;
const size_t kBlobOffCrc = 460;
static_assert(kBlobOffSpeeds + 2 * kModelMaxBreakpoints == kBlobOffBreakpoints, "blob layout");
static_assert(kBlobOffBreakpoints + kModelMaxBreakpoints * kBlobBreakpointSize == kBlobOffStopPoles, "blob layout");
static_assert(kBlobOffStopPoles + 4 * kModelEarlyStopPhases * kModelChannels == kBlobOffRoles, "blob layout");
static_assert(kBlobOffMaxRise + 2 * kModelChannels == kBlobOffCarriers, "blob layout");
static_assert(kBlobOffCarriers + kModelChannels == kBlobOffCouplings, "blob layout");
static_assert(kBlobOffCouplings + 4 * kModelChannels == kBlobOffReserved, "blob layout");
static_assert(kBlobOffCrc + 4 == kReducedModelBlobSize, "blob layout");

// ---- status -------------------------------------------------------------------------------------

enum class ModelStatus : uint8_t {
  kOk = 0,
  kBadLength = 1,           // blob is not kReducedModelBlobSize bytes
  kBadCrc = 2,              // stored CRC-32 does not match
  kBadMagic = 3,
  kBadVersion = 4,          // another format version (ModelCheck::channel holds it)
  kBadBreakpointCount = 5,  // n outside 2..7
  kBadSpeeds = 6,           // speed[0] != 0, not strictly ascending, or unused entry != 0
  kBadDt = 7,               // dt_ms outside 100..60000
  kNotFinite = 8,           // NaN/inf in the double model (quantize only)
  kUnstablePole = 9,        // a outside [0, 1) (or a does not fit Q1.30)
  kGainOutOfRange = 10,     // b beyond Q21.10
  kSteadyStateOutOfRange = 11,  // |b / (1 - a)| > 1000 K
  kInputAtStandstill = 12,  // b of breakpoint 0 not zero
  kBadAmbientChannel = 13,  // not 0..4/0xFF, or ambient channel not enabled
  kBadChannelMask = 14,     // bits 5..7 set or no channel enabled
  kBadDetector = 15,        // drift or warn evidence 0, alarm evidence <= warn evidence, or lower side without its drift
  kLimitOutOfRange = 16,    // absolute limit outside -200..850 degC, or a value beyond its field
  kUnusedNotZero = 17,      // coefficients of an unused breakpoint, phase or channel, or reserved bytes, not zero
  kBadStopPhases = 18,      // stop_end_s[1] set without [0], or not after it
  kBadChannelMap = 19,      // role[j] does not fit the channel (ambient/modelled/not modelled)
  kBadCarrier = 20,         // carrier not a modelled channel, itself carried, the channel itself, or coupling outside [0, 1)
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
    case ModelStatus::kBadVersion: return "unsupported blob format version (this firmware and tool read version 2)";
    case ModelStatus::kBadBreakpointCount: return "breakpoint count outside 2..7";
    case ModelStatus::kBadSpeeds:
      return "breakpoint speeds must start at 0 rpm and ascend strictly (unused = 0)";
    case ModelStatus::kBadDt: return "sample period dt_ms outside 100..60000";
    case ModelStatus::kNotFinite: return "coefficient is NaN or infinite";
    case ModelStatus::kUnstablePole: return "pole a outside [0, 1)";
    case ModelStatus::kGainOutOfRange: return "heat gain b outside its fixed-point range";
    case ModelStatus::kSteadyStateOutOfRange: return "steady rise |b / (1 - a)| > 1000 K";
    case ModelStatus::kInputAtStandstill: return "breakpoint 0 (0 rpm) must have b = 0";
    case ModelStatus::kBadAmbientChannel:
      return "ambient channel must be 0..4 (and enabled) or 0xFF (none)";
    case ModelStatus::kBadChannelMask: return "enabled-channel mask empty or has bits above channel 5";
    case ModelStatus::kBadDetector:
      return "detector: drift and warn evidence must be > 0, alarm evidence > warn evidence, a lower warn needs its drift";
    case ModelStatus::kLimitOutOfRange:
      return "limit out of range (absolute -200..850 degC; drift, evidence and rise 0..65535)";
    case ModelStatus::kUnusedNotZero: return "unused coefficients, detector fields or reserved bytes are not all zero";
    case ModelStatus::kBadStopPhases: return "stop phase ends must be 0, or ascending with the first one set";
    case ModelStatus::kBadChannelMap:
      return "channel map: ambient channel must have role ambient, modelled channels a thermal role, others none";
    case ModelStatus::kBadCarrier:
      return "carrier: must be another modelled channel without a carrier of its own, coupling in [0, 1) (0 without a carrier)";
  }
  return "unknown status";
}

// Status plus where: breakpoint index or channel index (0xFF when not applicable). Firmware can
// send `detail = status | index << 8` in its NACK. For kBadVersion the channel field holds the
// version found in the blob, so the NACK names it.
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

// ---- the fixed-point model ---------------------------------------------------------------------

struct ChannelCoeffs {
  int32_t a_q30;  // pole, Q1.30, 0 <= a < 1
  int32_t b;      // heat per step while running, Q21.10 mK
};

struct ModelBreakpoint {
  ChannelCoeffs ch[kModelChannels];
};

struct ChannelLimits {
  uint16_t drift_mK;             // residual the upper evidence forgives per sample
  uint16_t low_drift_mK;         // the same for the lower evidence
  uint16_t warn_evidence;        // upper evidence -> WARN, units of kEvidenceUnitMkSamples
  uint16_t alarm_evidence;       // upper evidence -> ALARM
  uint16_t low_warn_evidence;    // lower evidence -> WARN; 0 = off
  int32_t abs_limit_mK;          // measured above -> ALARM (degC * 1000)
  uint16_t max_rise_mK_per_min;  // rate of rise above -> ALARM; 0 = disabled
};

// Carriers and couplings of every channel (kModelNoCarrier / 0 = none).
const uint8_t kModelNoCarrier = 0;
struct ChannelCoupling {
  uint8_t carrier[kModelChannels];  // 0 = none, h + 1 = channel h
  int32_t c_q30[kModelChannels];    // Q1.30, 0 <= c < 1
};

// The schedule: everything but the coefficients (what the firmware keeps in RAM, see
// firmware/model_store.hpp; the coefficients stay in EEPROM).
struct ModelSchedule {
  uint8_t n_breakpoints;
  uint8_t ambient_channel;  // 0..4 or kModelAmbientNone
  uint8_t enabled_mask;
  uint16_t dt_ms;
  uint16_t stop_end_s[kModelEarlyStopPhases];
  uint16_t speed_rpm[kModelMaxBreakpoints];
  uint8_t role[kModelChannels];
  ChannelCoupling coupling;
};

struct ReducedModel {
  uint8_t version;
  ModelSchedule schedule;
  ModelBreakpoint bp[kModelMaxBreakpoints];
  int32_t stop_a_q30[kModelEarlyStopPhases][kModelChannels];
  ChannelLimits limits[kModelChannels];
};

// Channel j has a model of its own (enabled and not the ambient channel).
inline bool model_predicts(uint8_t enabled_mask, uint8_t ambient_channel, uint8_t j) {
  return ((enabled_mask >> j) & 1U) != 0 && j != ambient_channel;
}

// ---- validation ---------------------------------------------------------------------------------
// In three parts that need different fields, so the firmware can validate a blob streamed from
// EEPROM one breakpoint at a time (a whole ReducedModel is 428 bytes of its 2 KB of SRAM).
// validate() runs them in this order on a whole model.

// The schedule: breakpoint count, sample period, channel mask, ambient channel, speeds, stop
// phases, channel map.
inline ModelCheck validate_schedule(const ModelSchedule& s) {
  if (s.n_breakpoints < kModelMinBreakpoints || s.n_breakpoints > kModelMaxBreakpoints)
    return model_check(ModelStatus::kBadBreakpointCount);
  if (s.dt_ms < kModelMinDtMs || s.dt_ms > kModelMaxDtMs) return model_check(ModelStatus::kBadDt);
  if ((s.enabled_mask & 0xE0U) != 0 || (s.enabled_mask & 0x1FU) == 0) return model_check(ModelStatus::kBadChannelMask);
  if (s.ambient_channel != kModelAmbientNone &&
      (s.ambient_channel >= kModelChannels || ((s.enabled_mask >> s.ambient_channel) & 1U) == 0))
    return model_check(ModelStatus::kBadAmbientChannel);
  if (s.speed_rpm[0] != 0) return model_check(ModelStatus::kBadSpeeds, 0);
  for (uint8_t i = 1; i < kModelMaxBreakpoints; ++i) {
    if (i < s.n_breakpoints) {
      if (s.speed_rpm[i] <= s.speed_rpm[i - 1]) return model_check(ModelStatus::kBadSpeeds, i);
    } else if (s.speed_rpm[i] != 0) {
      return model_check(ModelStatus::kBadSpeeds, i);
    }
  }
  if ((s.stop_end_s[0] == 0 && s.stop_end_s[1] != 0) || (s.stop_end_s[1] != 0 && s.stop_end_s[1] <= s.stop_end_s[0]))
    return model_check(ModelStatus::kBadStopPhases);
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    const uint8_t r = s.role[j];
    bool fits;
    if (j == s.ambient_channel) {
      fits = r == kModelRoleAmbient;
    } else if (((s.enabled_mask >> j) & 1U) != 0) {
      fits = r == kModelRoleUnchecked || (r < wire::kChannelRoleCount && wire::is_thermal_role(r));
    } else {
      fits = r == kModelRoleNotModelled;
    }
    if (!fits) return model_check(ModelStatus::kBadChannelMap, 0xFF, j);
  }
  const int32_t one_q30 = static_cast<int32_t>(1L << kPoleFracBits);
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    const uint8_t v = s.coupling.carrier[j];
    const int32_t c = s.coupling.c_q30[j];
    bool fits;
    if (v == kModelNoCarrier) {
      fits = c == 0;
    } else {
      const uint8_t h = static_cast<uint8_t>(v - 1);
      fits = h < kModelChannels && h != j && model_predicts(s.enabled_mask, s.ambient_channel, j) &&
             model_predicts(s.enabled_mask, s.ambient_channel, h) && s.coupling.carrier[h] == kModelNoCarrier &&
             c >= 0 && c < one_q30;
    }
    if (!fits) return model_check(ModelStatus::kBadCarrier, 0xFF, j);
  }
  return model_check(ModelStatus::kOk);
}

namespace detail_rm {
inline int64_t abs64(int64_t v) { return v < 0 ? -v : v; }

// One channel's pole (0 <= a < 1) and, while running, |b / (1 - a)| <= 1000 K, all in int64:
// |b| 2^30 <= 1000 K * 2^10 * 1000 * (2^30 - a).
inline ModelStatus check_coeffs(int32_t a_q30, int32_t b) {
  const int32_t one_q30 = static_cast<int32_t>(1L << kPoleFracBits);
  if (a_q30 < 0 || a_q30 >= one_q30) return ModelStatus::kUnstablePole;
  const int64_t lhs = abs64(static_cast<int64_t>(b)) << kPoleFracBits;
  const int64_t rhs = static_cast<int64_t>(kModelMaxSteadyRiseMk) * (1L << kStateFracBits) *
                      (static_cast<int64_t>(one_q30) - a_q30);
  return lhs > rhs ? ModelStatus::kSteadyStateOutOfRange : ModelStatus::kOk;
}
}  // namespace detail_rm

// Breakpoint i of a model (unused slots and unmodelled channels must be all zero). Out of line:
// avr-gcc would inline its 64-bit arithmetic into the caller's breakpoint loop.
BTSM_NOINLINE inline ModelCheck validate_breakpoint(const ModelBreakpoint& p, uint8_t i, const ModelSchedule& s) {
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    const ChannelCoeffs& c = p.ch[j];
    if (i >= s.n_breakpoints || !model_predicts(s.enabled_mask, s.ambient_channel, j)) {
      if (c.a_q30 != 0 || c.b != 0) return model_check(ModelStatus::kUnusedNotZero, i, j);
      continue;
    }
    if (i == 0 && c.b != 0) return model_check(ModelStatus::kInputAtStandstill, 0, j);
    const ModelStatus st = detail_rm::check_coeffs(c.a_q30, c.b);
    if (st != ModelStatus::kOk) return model_check(st, i, j);
  }
  return model_check(ModelStatus::kOk);
}

// The early stop-phase poles (zero where the phase is unused or the channel has no model).
inline ModelCheck validate_stop_poles(const int32_t stop_a_q30[kModelEarlyStopPhases][kModelChannels],
                                      const ModelSchedule& s) {
  for (uint8_t k = 0; k < kModelEarlyStopPhases; ++k)
    for (uint8_t j = 0; j < kModelChannels; ++j) {
      const int32_t a = stop_a_q30[k][j];
      if (s.stop_end_s[k] == 0 || !model_predicts(s.enabled_mask, s.ambient_channel, j)) {
        if (a != 0) return model_check(ModelStatus::kUnusedNotZero, 0xFF, j);
      } else if (detail_rm::check_coeffs(a, 0) != ModelStatus::kOk) {
        return model_check(ModelStatus::kUnstablePole, 0, j);
      }
    }
  return model_check(ModelStatus::kOk);
}

// The detector parameters and limits of each channel (only the absolute limit on the ambient
// channel; nothing on unmodelled ones).
inline ModelCheck validate_limits(const ChannelLimits limits[kModelChannels], const ModelSchedule& s) {
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    const ChannelLimits& l = limits[j];
    const bool evidence_zero =
        l.drift_mK == 0 && l.low_drift_mK == 0 && l.warn_evidence == 0 && l.alarm_evidence == 0 && l.low_warn_evidence == 0;
    if (((s.enabled_mask >> j) & 1U) == 0) {
      if (!evidence_zero || l.abs_limit_mK != 0 || l.max_rise_mK_per_min != 0)
        return model_check(ModelStatus::kUnusedNotZero, 0xFF, j);
      continue;
    }
    if (l.abs_limit_mK < kModelMinAbsLimitMk || l.abs_limit_mK > kModelMaxAbsLimitMk)
      return model_check(ModelStatus::kLimitOutOfRange, 0xFF, j);
    if (j == s.ambient_channel) {
      if (!evidence_zero) return model_check(ModelStatus::kUnusedNotZero, 0xFF, j);
      continue;
    }
    if (l.drift_mK == 0 || l.warn_evidence == 0 || l.alarm_evidence <= l.warn_evidence ||
        (l.low_warn_evidence != 0 && l.low_drift_mK == 0))
      return model_check(ModelStatus::kBadDetector, 0xFF, j);
  }
  return model_check(ModelStatus::kOk);
}

// The whole model (decode() calls it).
inline ModelCheck validate(const ReducedModel& m) {
  ModelCheck c = validate_schedule(m.schedule);
  for (uint8_t i = 0; i < kModelMaxBreakpoints && c.ok(); ++i) c = validate_breakpoint(m.bp[i], i, m.schedule);
  if (c.ok()) c = validate_stop_poles(m.stop_a_q30, m.schedule);
  return c.ok() ? validate_limits(m.limits, m.schedule) : c;
}

// ---- codec --------------------------------------------------------------------------------------

inline void encode_breakpoint(const ModelBreakpoint& p, uint8_t* out /* 40 bytes */) {
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    put_le32(out + kBlobChannelCoeffSize * j, static_cast<uint32_t>(p.ch[j].a_q30));
    put_le32(out + kBlobChannelCoeffSize * j + 4, static_cast<uint32_t>(p.ch[j].b));
  }
}

inline void decode_breakpoint(const uint8_t* in /* 40 bytes */, ModelBreakpoint& p) {
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    p.ch[j].a_q30 = static_cast<int32_t>(get_le32(in + kBlobChannelCoeffSize * j));
    p.ch[j].b = static_cast<int32_t>(get_le32(in + kBlobChannelCoeffSize * j + 4));
  }
}

// The schedule's fields from a blob header (bytes 0..kBlobOffBreakpoints) and back.
inline void encode_schedule(const ModelSchedule& s, uint8_t* blob) {
  blob[kBlobOffBreakpointCount] = s.n_breakpoints;
  blob[kBlobOffAmbientChannel] = s.ambient_channel;
  blob[kBlobOffEnabledMask] = s.enabled_mask;
  put_le16(blob + kBlobOffDtMs, s.dt_ms);
  for (uint8_t k = 0; k < kModelEarlyStopPhases; ++k) put_le16(blob + kBlobOffStopEnds + 2 * k, s.stop_end_s[k]);
  for (uint8_t i = 0; i < kModelMaxBreakpoints; ++i) put_le16(blob + kBlobOffSpeeds + 2 * i, s.speed_rpm[i]);
}
inline void decode_schedule(const uint8_t* blob, ModelSchedule& s) {
  s.n_breakpoints = blob[kBlobOffBreakpointCount];
  s.ambient_channel = blob[kBlobOffAmbientChannel];
  s.enabled_mask = blob[kBlobOffEnabledMask];
  s.dt_ms = get_le16(blob + kBlobOffDtMs);
  for (uint8_t k = 0; k < kModelEarlyStopPhases; ++k) s.stop_end_s[k] = get_le16(blob + kBlobOffStopEnds + 2 * k);
  for (uint8_t i = 0; i < kModelMaxBreakpoints; ++i) s.speed_rpm[i] = get_le16(blob + kBlobOffSpeeds + 2 * i);
}

// The carriers and couplings (bytes kBlobOffCarriers..kBlobOffReserved of a blob) and back.
inline void encode_coupling(const ChannelCoupling& k, uint8_t* blob) {
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    blob[kBlobOffCarriers + j] = k.carrier[j];
    put_le32(blob + kBlobOffCouplings + 4 * j, static_cast<uint32_t>(k.c_q30[j]));
  }
}
// From those 25 bytes alone (the firmware reads just them from EEPROM).
inline void decode_coupling_from_fields(const uint8_t* fields, ChannelCoupling& k) {
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    k.carrier[j] = fields[j];
    k.c_q30[j] = static_cast<int32_t>(get_le32(fields + (kBlobOffCouplings - kBlobOffCarriers) + 4 * j));
  }
}

// Channel j's detector fields at their offsets in a blob.
inline void encode_limits(const ChannelLimits& l, uint8_t j, uint8_t* blob) {
  put_le16(blob + kBlobOffDrift + 2 * j, l.drift_mK);
  put_le16(blob + kBlobOffLowDrift + 2 * j, l.low_drift_mK);
  put_le16(blob + kBlobOffWarnEvidence + 2 * j, l.warn_evidence);
  put_le16(blob + kBlobOffAlarmEvidence + 2 * j, l.alarm_evidence);
  put_le16(blob + kBlobOffLowWarnEvidence + 2 * j, l.low_warn_evidence);
  put_le32(blob + kBlobOffAbsLimits + 4 * j, static_cast<uint32_t>(l.abs_limit_mK));
  put_le16(blob + kBlobOffMaxRise + 2 * j, l.max_rise_mK_per_min);
}
// From the detector fields alone (`fields` = the blob's bytes kBlobOffDrift..kBlobOffCarriers: the
// firmware reads just those from EEPROM).
inline void decode_limits_from_fields(const uint8_t* fields, uint8_t j, ChannelLimits& l) {
  l.drift_mK = get_le16(fields + (kBlobOffDrift - kBlobOffDrift) + 2 * j);
  l.low_drift_mK = get_le16(fields + (kBlobOffLowDrift - kBlobOffDrift) + 2 * j);
  l.warn_evidence = get_le16(fields + (kBlobOffWarnEvidence - kBlobOffDrift) + 2 * j);
  l.alarm_evidence = get_le16(fields + (kBlobOffAlarmEvidence - kBlobOffDrift) + 2 * j);
  l.low_warn_evidence = get_le16(fields + (kBlobOffLowWarnEvidence - kBlobOffDrift) + 2 * j);
  l.abs_limit_mK = static_cast<int32_t>(get_le32(fields + (kBlobOffAbsLimits - kBlobOffDrift) + 4 * j));
  l.max_rise_mK_per_min = get_le16(fields + (kBlobOffMaxRise - kBlobOffDrift) + 2 * j);
}
inline void decode_limits(const uint8_t* blob, uint8_t j, ChannelLimits& l) {
  decode_limits_from_fields(blob + kBlobOffDrift, j, l);
}

// Writes exactly kReducedModelBlobSize bytes (CRC included). Encodes what it is given: call
// validate() first if the model did not come from the host's quantizer.
inline void encode(const ReducedModel& m, uint8_t* out) {
  memset(out, 0, kReducedModelBlobSize);
  put_le32(out + kBlobOffMagic, kReducedModelMagic);
  out[kBlobOffVersion] = kReducedModelVersion;
  encode_schedule(m.schedule, out);
  for (uint8_t i = 0; i < kModelMaxBreakpoints; ++i)
    encode_breakpoint(m.bp[i], out + kBlobOffBreakpoints + kBlobBreakpointSize * i);
  for (uint8_t k = 0; k < kModelEarlyStopPhases; ++k)
    for (uint8_t j = 0; j < kModelChannels; ++j)
      put_le32(out + kBlobOffStopPoles + 4 * (kModelChannels * k + j), static_cast<uint32_t>(m.stop_a_q30[k][j]));
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    out[kBlobOffRoles + j] = m.schedule.role[j];
    encode_limits(m.limits[j], j, out);
  }
  encode_coupling(m.schedule.coupling, out);
  put_le32(out + kBlobOffCrc, crc32(out, kBlobOffCrc));
}

// CRC of a complete blob as stored in it (the INFO message's model_crc), for either version.
inline uint32_t blob_stored_crc(const uint8_t* blob) { return get_le32(blob + kBlobOffCrc); }

// The format version byte of a blob with the right magic (0 when it is not a model blob at all):
// lets the host name the version of a blob it cannot read.
inline uint8_t blob_version(const uint8_t* blob, size_t len) {
  if (blob == nullptr || len <= kBlobOffVersion || get_le32(blob + kBlobOffMagic) != kReducedModelMagic) return 0;
  return blob[kBlobOffVersion];
}

// Order of checks: length, CRC, magic, version, reserved bytes, then content (validate()). `out`
// is written only when the status is kOk. A blob of another version (1 had one shared state) is
// refused as kBadVersion, its version in ModelCheck::channel, never read as this layout.
inline ModelCheck decode(const uint8_t* blob, size_t len, ReducedModel& out) {
  if (blob == nullptr || len != kReducedModelBlobSize) return model_check(ModelStatus::kBadLength);
  if (crc32(blob, kBlobOffCrc) != get_le32(blob + kBlobOffCrc)) return model_check(ModelStatus::kBadCrc);
  if (get_le32(blob + kBlobOffMagic) != kReducedModelMagic) return model_check(ModelStatus::kBadMagic);
  if (blob[kBlobOffVersion] != kReducedModelVersion) return model_check(ModelStatus::kBadVersion, 0xFF, blob[kBlobOffVersion]);
  for (size_t i = kBlobOffReserved; i < kBlobOffCrc; ++i)
    if (blob[i] != 0) return model_check(ModelStatus::kUnusedNotZero);
  ReducedModel m;
  m.version = blob[kBlobOffVersion];
  decode_schedule(blob, m.schedule);
  for (uint8_t i = 0; i < kModelMaxBreakpoints; ++i)
    decode_breakpoint(blob + kBlobOffBreakpoints + kBlobBreakpointSize * i, m.bp[i]);
  for (uint8_t k = 0; k < kModelEarlyStopPhases; ++k)
    for (uint8_t j = 0; j < kModelChannels; ++j)
      m.stop_a_q30[k][j] = static_cast<int32_t>(get_le32(blob + kBlobOffStopPoles + 4 * (kModelChannels * k + j)));
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    m.schedule.role[j] = blob[kBlobOffRoles + j];
    decode_limits(blob, j, m.limits[j]);
  }
  decode_coupling_from_fields(blob + kBlobOffCarriers, m.schedule.coupling);
  const ModelCheck c = validate(m);
  if (c.ok()) out = m;
  return c;
}

}  // namespace btsm

#endif  // BTSM_COMMON_MODEL_BLOB_HPP
