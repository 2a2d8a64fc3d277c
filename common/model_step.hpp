// The module's evaluation of the reduced model (definition and fixed-point formats in
// model_blob.hpp): coefficients at a speed and stop phase, one step of every channel's
// first-order model, and the start from measured temperatures.
//
// Bit-exact contract (tests/unit/common_numeric): step_with() equals forming a (T - T_amb)
// exactly in int64 and rounding it once to nearest (ties away from zero), then adding T_amb and
// b (and a carrier's c (T_h - T_amb), formed and rounded the same way) and saturating the state
// to +-(2^30 - 1) LSB; interpolation equals p0 + round((p1 - p0) f /
// 2^16) in int64. The code below gets the same integers with 32-bit words and byte moves: on the
// AVR every 64-bit shift is a bit-serial library loop (~130 cycles), every 32-bit shift by a count
// that is not a multiple of 8 a bit loop too.
//
// C++14, no standard library, header-only.
#ifndef BTSM_COMMON_MODEL_STEP_HPP
#define BTSM_COMMON_MODEL_STEP_HPP

#include <stdint.h>
#include <string.h>

#include "model_blob.hpp"
#include "platform.hpp"

namespace btsm {

// State of every channel's model: the predicted temperature T_j (Q21.10 mK), and how long the
// spindle has been stopped (selects the stop phase).
struct ReducedModelState {
  int32_t t[kModelChannels];
  uint32_t stopped_ms;  // saturating; kModelLongStopped = stopped longer than every stop phase
};

const int32_t kModelStateLimit = (1L << 30) - 1;          // +-1048 K in Q21.10 mK
const int32_t kModelAmbientLimitMk = (1L << 20) - 1;      // ambient clamp, mK: its state value fits
const uint32_t kModelLongStopped = 0xFFFFFFFFUL;

// ---- where a speed falls -----------------------------------------------------------------------

struct SpeedSegment {
  uint8_t lo;
  uint8_t hi;
  uint16_t frac_q16;  // 0 when lo == hi
  bool running;       // u
};

namespace detail_rm {
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

// Stop phase 0 or 1 (the early poles stop_a[phase]) or kModelEarlyStopPhases (breakpoint 0's
// poles), after stopped_ms of standstill, for the schedule's stop_end_s.
inline uint8_t stop_phase(const uint16_t stop_end_s[kModelEarlyStopPhases], uint32_t stopped_ms) {
  for (uint8_t k = 0; k < kModelEarlyStopPhases; ++k)
    if (stop_end_s[k] != 0 && stopped_ms < static_cast<uint32_t>(stop_end_s[k]) * 1000UL) return k;
  return kModelEarlyStopPhases;
}

namespace detail_rm {

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

// A 64-bit two's-complement value as two 32-bit words, v = hi * 2^32 + lo.
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

// round(v / 2^30), ties away from zero, for |v| < 2^61: floor((v + 2^29 - [v < 0]) / 2^30) =
// 4 hi + 4 [carry of lo + half] + ((lo + half) >> 30), the last shift as a byte move and 6 bits.
BTSM_ALWAYS_INLINE int32_t round_q30(Wide p) {
  const uint32_t half = p.hi < 0 ? 0x1FFFFFFFUL : 0x20000000UL;
  const uint32_t t = p.lo + half;
  const uint8_t low = static_cast<uint8_t>((t < half ? 4U : 0U) + (static_cast<uint8_t>(t >> 24) >> 6));
  return static_cast<int32_t>((static_cast<uint32_t>(p.hi) << 2) + low);
}

inline int32_t clamp32(int32_t v, int32_t limit) { return v > limit ? limit : (v < -limit ? -limit : v); }

static_assert(kStateFracBits == 10, "shr10/shl10 are the state's scaling");
// floor(v / 2^10) and v * 2^10 (v within +-2^21). On the AVR a 32-bit shift by 10 is a 10-turn
// bit loop (~65 cycles); as a shift by 8 (byte moves) and one by 2 it is ~25. The empty asm keeps
// avr-gcc from folding the two shifts back into one; elsewhere the plain shift.
BTSM_ALWAYS_INLINE int32_t shr10(int32_t v) {
#if defined(__AVR__)
  int32_t s = v >> 8;
  __asm__("" : "+r"(s));
  return s >> 2;
#else
  return v >> 10;
#endif
}
BTSM_ALWAYS_INLINE int32_t shl10(int32_t v) {
#if defined(__AVR__)
  uint32_t s = static_cast<uint32_t>(v) << 2;
  __asm__("" : "+r"(s));
  return static_cast<int32_t>(s << 8);
#else
  return static_cast<int32_t>(static_cast<uint32_t>(v) << 10);
#endif
}

}  // namespace detail_rm

// Coefficients between two breakpoints (out may alias lo: each member is read before it is
// written). Member-wise as one loop over the ten int32 (lerp_q is inlined once, not ten times).
inline void interpolate(const ModelBreakpoint& lo, const ModelBreakpoint& hi, uint16_t frac_q16, ModelBreakpoint& out) {
  if (frac_q16 == 0) {  // exactly breakpoint lo (lerp_q(p0, p1, 0) == p0)
    out = lo;
    return;
  }
  static_assert(sizeof(ModelBreakpoint) == 2 * kModelChannels * sizeof(int32_t), "ModelBreakpoint: ten int32, no padding");
  const uint8_t* l = reinterpret_cast<const uint8_t*>(&lo);
  const uint8_t* h = reinterpret_cast<const uint8_t*>(&hi);
  uint8_t* o = reinterpret_cast<uint8_t*>(&out);
  for (uint8_t k = 0; k < 2 * kModelChannels; ++k, l += 4, h += 4, o += 4) {
    int32_t p0, p1;
    memcpy(&p0, l, 4);
    memcpy(&p1, h, 4);
    p0 = detail_rm::lerp_q(p0, p1, frac_q16);
    memcpy(o, &p0, 4);
  }
}

// The model's coefficients at `speed_rpm` after `stopped_ms` of standstill; returns u (running).
inline bool coefficients_at(const ReducedModel& m, uint16_t speed_rpm, uint32_t stopped_ms, ModelBreakpoint& out) {
  const SpeedSegment seg = find_segment(m.schedule.speed_rpm, m.schedule.n_breakpoints, speed_rpm);
  interpolate(m.bp[seg.lo], m.bp[seg.hi], seg.frac_q16, out);
  const uint8_t phase = stop_phase(m.schedule.stop_end_s, stopped_ms);
  if (!seg.running && phase < kModelEarlyStopPhases)
    for (uint8_t j = 0; j < kModelChannels; ++j) out.ch[j].a_q30 = m.stop_a_q30[phase][j];
  return seg.running;
}

// The start: every modelled channel's state = its measured temperature (the model then predicts
// from where the spindle is, whatever it did before), or the ambient where the channel has no
// valid reading; stopped for longer than every stop phase. False (state untouched) without an
// ambient reading.
inline bool init_from_measurement(uint8_t ambient_channel, uint8_t enabled_mask, ReducedModelState& st,
                                  int32_t ambient_mK, const int32_t measured_mK[kModelChannels]) {
  if (ambient_mK == kModelNoPrediction) return false;
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    const int32_t v = measured_mK[j] != kModelNoPrediction && model_predicts(enabled_mask, ambient_channel, j)
                          ? measured_mK[j]
                          : ambient_mK;
    st.t[j] = detail_rm::shl10(detail_rm::clamp32(v, kModelAmbientLimitMk));
  }
  st.stopped_ms = kModelLongStopped;
  return true;
}

// Every channel at `ambient_mK` (a cold machine), long stopped.
inline void init_at_ambient(ReducedModelState& st, int32_t ambient_mK) {
  const int32_t none[kModelChannels] = {kModelNoPrediction, kModelNoPrediction, kModelNoPrediction,
                                        kModelNoPrediction, kModelNoPrediction};
  init_from_measurement(kModelAmbientNone, 0, st, ambient_mK, none);
}

// One model step with coefficients `p` and carriers `k` (for a running spindle when `running`):
// writes the prediction of every channel (mK; kModelNoPrediction for unmodelled channels and for
// all while the ambient reading is missing, the ambient channel's own reading for it), then
// advances every modelled channel (a carrier term uses its carrier's state before the step).
// Without an ambient reading the states hold (they are absolute temperatures: nothing is known
// to move them). dt_ms advances the stop clock.
inline void step_with(const ModelBreakpoint& p, const ChannelCoupling& k, bool running, uint8_t ambient_channel,
                      uint8_t enabled_mask, uint16_t dt_ms, ReducedModelState& st, int32_t ambient_mK,
                      int32_t predicted_mK[kModelChannels]) {
  using namespace detail_rm;
  const bool have_ambient = ambient_mK != kModelNoPrediction;
  // The ambient as a state value (a shift: the state's unit is 2^-10 mK).
  const int32_t amb = shl10(clamp32(ambient_mK, kModelAmbientLimitMk));
  int32_t before[kModelChannels];  // the states before this step (carrier inputs)
  memcpy(before, st.t, sizeof before);
  uint8_t bit = 1;
  for (uint8_t j = 0; j < kModelChannels; ++j, bit = static_cast<uint8_t>(bit << 1)) {
    if ((enabled_mask & bit) == 0 || !have_ambient) {
      predicted_mK[j] = kModelNoPrediction;
      continue;
    }
    if (j == ambient_channel) {
      predicted_mK[j] = ambient_mK;
      continue;
    }
    const int32_t t = before[j];
    predicted_mK[j] = shr10(t + (1L << (kStateFracBits - 1)));  // nearest mK, ties up
    // T' = T_amb + round(a (T - T_amb)) + u b. With 0 <= a < 1 the first two terms lie between
    // T_amb and T (|.| <= 2^30), |b| < 2^30 by validation: no 32-bit overflow before the clamp.
    int32_t next = amb + round_q30(mul_wide(p.ch[j].a_q30, t - amb));
    if (running) next += p.ch[j].b;
    // + round(c (T_h - T_amb)): |.| < 2^31 (0 <= c < 1), so the sum saturates instead of wrapping
    // (the same as the exact sum clamped).
    const uint8_t carrier = k.carrier[j];
    if (carrier != kModelNoCarrier) {
      const int32_t ct = round_q30(mul_wide(k.c_q30[j], before[carrier - 1] - amb));
      if (__builtin_add_overflow(next, ct, &next)) next = ct > 0 ? kModelStateLimit : -kModelStateLimit;
    }
    st.t[j] = clamp32(next, kModelStateLimit);
  }
  if (running) {
    st.stopped_ms = 0;
  } else if (st.stopped_ms <= kModelLongStopped - dt_ms) {
    st.stopped_ms += dt_ms;
  } else {
    st.stopped_ms = kModelLongStopped;
  }
}

// One step of model m at `speed_rpm`.
inline void step(const ReducedModel& m, ReducedModelState& st, uint16_t speed_rpm, int32_t ambient_mK,
                 int32_t predicted_mK[kModelChannels]) {
  ModelBreakpoint p;
  const bool running = coefficients_at(m, speed_rpm, st.stopped_ms, p);
  step_with(p, m.schedule.coupling, running, m.schedule.ambient_channel, m.schedule.enabled_mask, m.schedule.dt_ms, st,
            ambient_mK, predicted_mK);
}

}  // namespace btsm

#endif  // BTSM_COMMON_MODEL_STEP_HPP
