// Ratiometric RTD measurement with the AD7794: 24-bit code -> ratio R_rtd/R_ref -> resistance.
//
// The excitation current flows through the probe and the reference resistor in series; the ADC
// measures the probe voltage against the reference voltage, so the current cancels:
//   unipolar:               ratio_raw = code / 2^24 / G           (0x000000 = 0, 0xFFFFFF = +FS)
//   bipolar (offset binary): ratio_raw = (code - 2^23) / 2^23 / G  (0x800000 = 0)
//   calibrated:             ratio = (ratio_raw - offset_ratio) * gain_correction   (per channel)
//   R_rtd = R_ref * ratio
// The per-channel calibration model is a straight line fitted from two readings: a zero reading
// (shorted input / AIN(-)-AIN(-) channel, or the ADC's zero-scale calibration) and a reading of a
// known resistance; make_calibration() builds it and refuses degenerate inputs.
//
// Anything that would turn a broken measurement into a plausible resistance is an error instead:
// the ADC's ERR flag (over/under-range, missing reference), a code on a rail (the AD7794 clamps to
// all 0s/1s on over-range, an open probe with burnout current pulls to full scale, a shorted or
// unexcited probe reads 0), a negative ratio (reversed wiring), and a calibrated ratio beyond the
// input range of the selected gain (the code cannot mean what it says).
//
// Template over Real: float on the MCU (a 24-bit code is exact in float), double on the host.
// C++14, no standard library.
#ifndef BTSM_COMMON_RATIOMETRIC_HPP
#define BTSM_COMMON_RATIOMETRIC_HPP

#include <stdint.h>

#include "fixed_point.hpp"

namespace btsm {

const uint32_t kAdcFullScaleCode = 0xFFFFFFUL;
const uint32_t kAdcMidScaleCode = 0x800000UL;

enum class RatioStatus : uint8_t {
  kOk = 0,
  kAdcError = 1,         // ERR bit of the AD7794 status register was set with this result
  kRailLow = 2,          // code at (or within the margin of) 0: short, no excitation, under-range
  kRailHigh = 3,         // code at (or within the margin of) full scale: open probe, lost reference
  kNegative = 4,         // ratio below 0 (bipolar: below mid-scale): reversed or crossed wiring
  kBeyondGainRange = 5,  // calibrated ratio outside [0, 1/G): inconsistent with the input range
  kBadCode = 6,          // code has bits above bit 23
  kBadConfig = 7,        // gain not 1,2,4..128, R_ref <= 0, or a degenerate calibration
};

inline const char* ratio_status_name(RatioStatus s) {
  switch (s) {
    case RatioStatus::kOk: return "ok";
    case RatioStatus::kAdcError: return "ADC reported an error (ERR flag)";
    case RatioStatus::kRailLow: return "code at zero scale (short or no excitation)";
    case RatioStatus::kRailHigh: return "code at full scale (open probe or lost reference)";
    case RatioStatus::kNegative: return "negative ratio (wiring reversed)";
    case RatioStatus::kBeyondGainRange: return "ratio beyond the input range of the gain";
    case RatioStatus::kBadCode: return "code is not a 24-bit value";
    case RatioStatus::kBadConfig: return "invalid ADC configuration or calibration";
  }
  return "unknown ratio status";
}

template <class Real>
struct RatiometricConfig {
  Real r_ref_ohm = Real(6800);    // reference resistor (BTSM: 6.80 kOhm on REFIN1)
  uint8_t gain = 4;               // in-amp gain 1, 2, 4, ..., 128 (BTSM: 4)
  bool bipolar = false;           // coding (BTSM: unipolar)
  uint32_t rail_margin_codes = 0; // codes within this distance of a rail count as saturated
};

// ratio = (ratio_raw - offset_ratio) * gain_correction
template <class Real>
struct ChannelCalibration {
  Real offset_ratio = Real(0);     // ratio_raw read with zero input
  Real gain_correction = Real(1);  // true ratio / (ratio_raw - offset) of a known resistance
};

template <class Real>
struct RatioResult {
  RatioStatus status;
  Real ratio;  // calibrated R_rtd / R_ref; 0 unless kOk
  Real r_ohm;  // R_ref * ratio;             0 unless kOk
  bool ok() const { return status == RatioStatus::kOk; }
};

inline bool valid_adc_gain(uint8_t g) { return g != 0 && (g & (g - 1U)) == 0; }  // 1..128

namespace detail_ratio {
template <class Real>
inline RatioResult<Real> fail(RatioStatus s) {
  RatioResult<Real> r;
  r.status = s;
  r.ratio = Real(0);
  r.r_ohm = Real(0);
  return r;
}
}  // namespace detail_ratio

// Uncalibrated ratio of a code (no checks): the inverse of ideal_code().
// code <= kAdcFullScaleCode and gain valid (valid_adc_gain). The result is exactly code / (2^24 G) (bipolar: centred /
// (2^23 G)), computed without a floating-point division (~500 cycles on the ATmega328P, which has
// no FPU): 128 / G is an integer power of two, code * (128 / G) < 2^31 keeps code's 24 significant
// bits (exact in float), and the final scaling is by the power of two 2^-31 (bipolar 2^-30).
template <class Real>
inline Real raw_ratio(uint32_t code, uint8_t gain, bool bipolar) {
  const uint8_t up = static_cast<uint8_t>(128U / gain);
  if (bipolar) {
    const int32_t centred = static_cast<int32_t>(code) - static_cast<int32_t>(kAdcMidScaleCode);
    return static_cast<Real>(centred * up) * Real(9.31322574615478515625e-10);  // 2^-30
  }
  return static_cast<Real>(code * up) * Real(4.656612873077392578125e-10);  // 2^-31
}

template <class Real>
inline RatioResult<Real> code_to_resistance(uint32_t code, bool adc_error_flag, const RatiometricConfig<Real>& cfg,
                                            const ChannelCalibration<Real>& cal) {
  using detail_ratio::fail;
  if (!valid_adc_gain(cfg.gain) || !(cfg.r_ref_ohm > Real(0)) || !(cal.gain_correction > Real(0)) ||
      !(cal.offset_ratio == cal.offset_ratio))
    return fail<Real>(RatioStatus::kBadConfig);
  if (code > kAdcFullScaleCode) return fail<Real>(RatioStatus::kBadCode);
  if (adc_error_flag) return fail<Real>(RatioStatus::kAdcError);
  if (code <= cfg.rail_margin_codes) return fail<Real>(RatioStatus::kRailLow);
  if (code >= kAdcFullScaleCode - cfg.rail_margin_codes) return fail<Real>(RatioStatus::kRailHigh);
  const Real raw = raw_ratio<Real>(code, cfg.gain, cfg.bipolar);
  if (raw < Real(0)) return fail<Real>(RatioStatus::kNegative);
  const Real ratio = (raw - cal.offset_ratio) * cal.gain_correction;
  if (!(ratio >= Real(0)) || !(ratio * static_cast<Real>(cfg.gain) < Real(1)))
    return fail<Real>(RatioStatus::kBeyondGainRange);
  RatioResult<Real> r;
  r.status = RatioStatus::kOk;
  r.ratio = ratio;
  r.r_ohm = cfg.r_ref_ohm * ratio;
  return r;
}

// Two-point calibration: `raw_zero` = raw ratio read with zero input, `raw_known` = raw ratio read
// on a known resistance `known_ohm`. Returns false (cal untouched) if the points are degenerate
// (known reading not above zero reading, or non-positive resistances).
template <class Real>
inline bool make_calibration(Real raw_zero, Real raw_known, Real known_ohm, Real r_ref_ohm,
                             ChannelCalibration<Real>& cal) {
  const Real span = raw_known - raw_zero;
  if (!(span > Real(0)) || !(known_ohm > Real(0)) || !(r_ref_ohm > Real(0))) return false;
  cal.offset_ratio = raw_zero;
  cal.gain_correction = (known_ohm / r_ref_ohm) / span;
  return true;
}

// ---- Fixed point (the MCU) ---------------------------------------------------------------------
// The same unipolar conversion R = R_ref code / (2^24 G) without float: R in ohm x 2^16 (uint32,
// resolution 15 uohm, i.e. ~4 uK of a Pt1000, up to 65535 ohm), R_ref in ohm x 2^16 from the
// configuration's milliohms. code 2^(8 - log2 G) < 2^32 for every code and gain, so the quotient is
// one 32x32 product whose high word is the result, rounded once to nearest: exactly
// round(R_ref_q16 code / 2^(24 + log2 G)) (tests/unit/common_numeric/ratiometric_test.cpp).

// R_ref in ohm x 2^16 from milliohms, nearest (mohm < 65536000, i.e. R_ref < 65536 ohm):
// mohm x 65.536 as 65 mohm + mohm x 0.536, the fraction as a 32-bit constant through one product.
// The exact value mohm 8192 / 125 is a multiple of 1/125, at least 0.004 from a rounding tie, and
// the constant's error is below 0.002 over the range: the rounding is the exact value's.
inline uint32_t ohm_q16_from_milliohm(uint32_t mohm) {
  return mohm * 65U + fx::mul_hi_round(mohm, 2302102471UL);  // 0.536 x 2^32 = 2302102470.66
}

// R in ohm x 2^16 of a unipolar 24-bit code at gain 2^gain_log2 (gain_log2 = the AD7794 gain code,
// 0..7), nearest. No checks: code <= kAdcFullScaleCode (the rails are the caller's, as in
// code_to_resistance).
inline uint32_t code_to_ohm_q16(uint32_t code, uint8_t gain_log2, uint32_t r_ref_q16) {
  return fx::mul_hi_round(code << (8U - gain_log2), r_ref_q16);
}

// Ideal (noise-free, uncalibrated) code for a probe resistance, rounded to nearest and clamped
// to the rails like the AD7794 does on over-range. For tests and simulations (host, double).
inline uint32_t ideal_code(double r_ohm, double r_ref_ohm, uint8_t gain, bool bipolar) {
  const double ratio = r_ohm / r_ref_ohm * gain;
  double code = bipolar ? 8388608.0 + ratio * 8388608.0 : ratio * 16777216.0;
  code += 0.5;
  if (!(code >= 0.0)) return 0;
  if (code >= 16777215.0) return kAdcFullScaleCode;
  return static_cast<uint32_t>(code);
}

}  // namespace btsm

#endif  // BTSM_COMMON_RATIOMETRIC_HPP
