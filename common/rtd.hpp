// Platinum RTD: Callendar–Van Dusen resistance <-> temperature over the full IEC 60751 range.
//
//   R(t) = R0 (1 + A t + B t^2 + C (t - 100) t^3)      C used only for t < 0 degC
//   IEC 60751 / ITS-90: A = 3.9083e-3 /degC, B = -5.775e-7 /degC^2, C = -4.183e-12 /degC^4
//
// t(R) is the exact inverse of R(t), not an approximation:
//   R >= R0: closed-form root of B t^2 + A t - (r - 1) = 0 (r = R/R0), written as
//            t = 2 (r - 1) / (A + sqrt(A^2 + 4 B (r - 1)))  -- no cancellation between A and the root
//   R <  R0: Newton on the full quartic, started from that quadratic root (which is within 2.5 degC
//            at -200 degC), stopped when the step is below the working precision; <= 8 iterations.
// The polynomial is evaluated on R - R0 with the coefficients scaled by R0 (RtdInverse) rather
// than on R/R0 - 1: R - R0 is exact in binary floating point for R within a factor 2 of R0
// (Sterbenz), which matters in float on the MCU, and no division by R0 is needed.
//
// Both directions are templates over Real: float on the MCU (avr-g++: double is 32-bit there
// anyway), double on the host. Inputs outside -200...850 degC (or the resistances they map to),
// NaN and bad coefficient sets return an error status and a NaN value, never a plausible number.
// Measured float-vs-double error: see tests/unit/common_numeric/rtd_test.cpp (printed there).
//
// C++14, no standard library.
#ifndef BTSM_COMMON_RTD_HPP
#define BTSM_COMMON_RTD_HPP

#include <math.h>
#include <stdint.h>

#include "fixed_point.hpp"
#include "platform.hpp"

namespace btsm {

enum class RtdStatus : uint8_t {
  kOk = 0,
  kBelowRange = 1,       // t < -200 degC or R < R(-200 degC)
  kAboveRange = 2,       // t > 850 degC or R > R(850 degC)
  kNotANumber = 3,       // NaN input
  kBadCoefficients = 4,  // R0 <= 0, A <= 0, non-finite, or a set whose R(t) is not increasing
  kNoConvergence = 5,    // Newton did not converge (cannot happen with IEC coefficients)
};

inline const char* rtd_status_name(RtdStatus s) {
  switch (s) {
    case RtdStatus::kOk: return "ok";
    case RtdStatus::kBelowRange: return "below the IEC 60751 range (-200 degC)";
    case RtdStatus::kAboveRange: return "above the IEC 60751 range (850 degC)";
    case RtdStatus::kNotANumber: return "not a number";
    case RtdStatus::kBadCoefficients: return "invalid Callendar-Van Dusen coefficients";
    case RtdStatus::kNoConvergence: return "inverse did not converge";
  }
  return "unknown RTD status";
}

template <class Real>
struct RtdCoefficients {
  Real r0_ohm;   // resistance at 0 degC (100 Pt100, 1000 Pt1000)
  Real a;        // 1/degC
  Real b;        // 1/degC^2
  Real c;        // 1/degC^4, below 0 degC only
};

// IEC 60751 coefficients for any R0 (default Pt1000, the BTSM probe).
template <class Real>
inline RtdCoefficients<Real> iec60751(Real r0_ohm = Real(1000)) {
  RtdCoefficients<Real> k;
  k.r0_ohm = r0_ohm;
  k.a = Real(3.9083e-3);
  k.b = Real(-5.775e-7);
  k.c = Real(-4.183e-12);
  return k;
}

const int16_t kRtdMinC = -200;
const int16_t kRtdMaxC = 850;
// The inverse accepts resistances up to this far (degC) beyond the range ends, because a reading
// of an end point carries rounding/noise (the IEC table itself lists R(-200) = 18.52 ohm, which is
// -200.0002 degC exactly). Results there lie within the margin of the end point; anything further
// out is an error.
const float kRtdInverseMarginC = 0.02f;

template <class Real>
struct RtdResult {
  RtdStatus status;
  Real value;  // degC or ohm; NaN unless status == kOk
  bool ok() const { return status == RtdStatus::kOk; }
};

namespace detail_rtd {
inline float rsqrt(float v) { return sqrtf(v); }
inline double rsqrt(double v) { return sqrt(v); }
inline float rabs(float v) { return fabsf(v); }
inline double rabs(double v) { return fabs(v); }
inline float rnan(float) { return NAN; }
inline double rnan(double) { return static_cast<double>(NAN); }
template <class Real>
inline bool finite(Real v) { return v == v && v - v == Real(0); }
// Keeps the value argument out of template deduction: Real comes from the coefficients, and a
// literal like 20.0 or NAN converts to it.
template <class T>
struct NonDeduced {
  typedef T type;
};

template <class Real>
inline RtdResult<Real> fail(RtdStatus s) {
  RtdResult<Real> r;
  r.status = s;
  r.value = rnan(Real(0));
  return r;
}
template <class Real>
inline RtdResult<Real> good(Real v) {
  RtdResult<Real> r;
  r.status = RtdStatus::kOk;
  r.value = v;
  return r;
}

// (R - R0)/R0 as a function of t: A t + B t^2 [+ C (t - 100) t^3 for t < 0].
template <class Real>
inline Real relative_rise(const RtdCoefficients<Real>& k, Real t) {
  Real p = t * (k.a + k.b * t);
  if (t < Real(0)) p += k.c * (t - Real(100)) * t * t * t;
  return p;
}

template <class Real>
inline Real relative_rise_slope(const RtdCoefficients<Real>& k, Real t) {
  Real s = k.a + Real(2) * k.b * t;
  if (t < Real(0)) s += k.c * t * t * (Real(4) * t - Real(300));
  return s;
}

// Checks that matter for a well-defined inverse: positive R0 and A, finite values, and R(t)
// strictly increasing over the whole range (slope > 0 at both ends is sufficient for the IEC form
// because the slope is monotone on each side of 0 for any set with B <= 0 and C <= 0; for other
// sets the slope is also checked at 0).
template <class Real>
inline bool coefficients_ok(const RtdCoefficients<Real>& k) {
  if (!finite(k.r0_ohm) || !finite(k.a) || !finite(k.b) || !finite(k.c)) return false;
  if (!(k.r0_ohm > Real(0)) || !(k.a > Real(0))) return false;
  return relative_rise_slope(k, Real(kRtdMinC)) > Real(0) && relative_rise_slope(k, Real(0)) > Real(0) &&
         relative_rise_slope(k, Real(kRtdMaxC)) > Real(0);
}
}  // namespace detail_rtd

// R(t) in ohm for t in [-200, 850] degC.
template <class Real>
inline RtdResult<Real> rtd_resistance(const RtdCoefficients<Real>& k,
                                      typename detail_rtd::NonDeduced<Real>::type t_c) {
  using namespace detail_rtd;
  if (!coefficients_ok(k)) return fail<Real>(RtdStatus::kBadCoefficients);
  if (t_c != t_c) return fail<Real>(RtdStatus::kNotANumber);
  if (t_c < Real(kRtdMinC)) return fail<Real>(RtdStatus::kBelowRange);
  if (t_c > Real(kRtdMaxC)) return fail<Real>(RtdStatus::kAboveRange);
  return good<Real>(k.r0_ohm + k.r0_ohm * relative_rise(k, t_c));
}

// The inverse t(R), prepared once for a coefficient set: the coefficient check and the range
// limits are evaluated in the constructor, so a conversion costs one square root, one division and
// a handful of multiply-adds (on the ATmega328P ~1.3k cycles instead of ~4k with the checks
// repeated per call). The arithmetic works on d = R - R0 with the coefficients scaled by R0
// (A' = R0 A, B' = R0 B, C' = R0 C): R - R0 is exact, and the division x = d / R0 (and its rounding)
// is gone. With d, relative_rise on the scaled set is R0 * relative_rise, so the roots are the same:
//   d >= 0: t = 2 d / (A' + sqrt(A'^2 + 4 B' d))
//   d <  0: Newton on R0 * relative_rise(t) - d from that start.
// Float error over -40...150 degC: tests/unit/common_numeric/rtd_test.cpp (prints it).
template <class Real>
class RtdInverse {
 public:
  explicit RtdInverse(const RtdCoefficients<Real>& k) {
    using namespace detail_rtd;
    ok_ = coefficients_ok(k);
    s_.r0_ohm = k.r0_ohm;
    s_.a = k.r0_ohm * k.a;
    s_.b = k.r0_ohm * k.b;
    s_.c = k.r0_ohm * k.c;
    half_a_ = Real(0.5) * s_.a;
    quarter_a2_ = half_a_ * half_a_;
    d_min_ = relative_rise(s_, Real(kRtdMinC) - Real(kRtdInverseMarginC));
    d_max_ = relative_rise(s_, Real(kRtdMaxC) + Real(kRtdInverseMarginC));
    // The discriminant is linear in d: non-negative at both ends of the range means non-negative
    // everywhere in it, and the per-call check can go (it folds away for constant coefficients).
    disc_ok_ = quarter_a2_ + s_.b * d_min_ >= Real(0) && quarter_a2_ + s_.b * d_max_ >= Real(0);
  }

  // t(R) in degC for R in [R(-200 - margin), R(850 + margin)] (see kRtdInverseMarginC).
  RtdResult<Real> temperature(Real r_ohm) const {
    using namespace detail_rtd;
    if (!ok_) return fail<Real>(RtdStatus::kBadCoefficients);
    const Real d = r_ohm - s_.r0_ohm;  // exact near R0 (Sterbenz)
    // NaN fails this comparison too; telling it apart costs a compare only on failure.
    if (!(d >= d_min_)) return fail<Real>(r_ohm != r_ohm ? RtdStatus::kNotANumber : RtdStatus::kBelowRange);
    if (d > d_max_) return fail<Real>(RtdStatus::kAboveRange);
    // t = 2 d / (A' + sqrt(A'^2 + 4 B' d)) with numerator and denominator halved: the halving and
    // quartering are exact in binary floating point (sqrt(x / 4) = sqrt(x) / 2 exactly), so this
    // is bit-identical and saves two multiplications.
    const Real disc = quarter_a2_ + s_.b * d;
    if (!disc_ok_ && !(disc >= Real(0))) return fail<Real>(RtdStatus::kBadCoefficients);
    Real t = d / (half_a_ + rsqrt(disc));
    if (d >= Real(0) || s_.c == Real(0)) return good<Real>(t);
    // Below 0 degC: Newton on the quartic. The start is already close (quadratic root), and
    // relative_rise is smooth and monotone there, so it converges quadratically.
    // Stop when the step is a few ulps of t: the next one would be below rounding noise (and in
    // float could oscillate by one ulp forever).
    const Real eps = sizeof(Real) >= 8 ? Real(2.220446049250313e-16) : Real(1.1920929e-7);
    for (uint8_t i = 0; i < 8; ++i) {
      const Real step = (relative_rise(s_, t) - d) / relative_rise_slope(s_, t);
      t -= step;
      if (rabs(step) <= Real(16) * eps * (rabs(t) + Real(1))) {
        return good<Real>(t);
      }
    }
    return fail<Real>(RtdStatus::kNoConvergence);
  }

 private:
  RtdCoefficients<Real> s_;  // R0 and the coefficients scaled by R0
  Real half_a_, quarter_a2_;  // A'/2, A'^2/4
  Real d_min_, d_max_;        // R - R0 at the ends of the accepted range
  bool ok_;
  bool disc_ok_;              // discriminant >= 0 over the whole range
};

// t(R) in degC for R in [R(-200 - margin), R(850 + margin)] (see kRtdInverseMarginC). Converting
// many readings with one coefficient set: keep an RtdInverse instead (this re-checks each call).
template <class Real>
inline RtdResult<Real> rtd_temperature(const RtdCoefficients<Real>& k,
                                       typename detail_rtd::NonDeduced<Real>::type r_ohm) {
  return RtdInverse<Real>(k).temperature(r_ohm);
}

// ---- Pt1000 inverse for the MCU, in fixed point --------------------------------------------------
//
// t(R) for the IEC 60751 Pt1000 from R in ohm x 2^16 (the acquisition's fixed-point resistance,
// common/ratiometric.hpp code_to_ohm_q16) to degC in 1/256 mK (the unit of the MCU's Kalman filter,
// kKalmanFixPerK per kelvin), as a piecewise quadratic over R in [512, 4096) ohm, i.e.
// -118.3 ... +850 degC: every temperature the IEC range holds above -118 degC. No float, no division,
// no square root: two 32x32 products (fx::mul_hi_round) and a 10-byte table read.
// Segments: 16 per binade ([512, 1024), [1024, 2048), [2048, 4096) ohm: 32, 64 and 128 ohm wide),
// selected by the bit length of R and its next four bits. With x = (R - start) / width in [0, 1)
// as the 32-bit fraction u (exact: the bits of R below the segment's),
//   t = d0 + x (d1 + x d2)   evaluated as   t = d0 + (mulhi(u, D1 + mulhi(u, D2)) + 128) / 256
// with D1 = 256 d1, D2 = 256 d2 (mulhi(a, b) = round(a b / 2^32)); d1, d2 > 0 (t(R) rises and is
// convex), so everything is unsigned. D2 is stored in 16 bits with a binade's scale (10-byte entries). The quadratic interpolates the exact inverse (double) at the
// three Chebyshev nodes of each segment (near-minimax): fit error <= 9.2e-6 degC below 2048 ohm
// (297 degC), 2.3e-4 degC above; with the integer evaluation 1.2e-5 degC below 2048 ohm and
// 1.1e-5 degC over -40...150 degC (the float table it replaced: 2.3e-5 degC there).
// tests/unit/common_numeric/rtd_test.cpp recomputes every coefficient from the exact inverse and
// measures the error over the whole table. Below 512 ohm the result is kBelowRange (the firmware
// reports a short), above R(850.02 degC) kAboveRange (open).
struct Pt1000FixedResult {
  RtdStatus status;
  int32_t t;  // degC x 256000 (1/256 mK); 0 unless status == kOk
  bool ok() const { return status == RtdStatus::kOk; }
};

namespace detail_rtd {
struct QuadSegmentFixed {
  int32_t d0;   // t at the segment start, 1/256 mK
  uint32_t d1;  // 256 x slope x width, 1/256 mK
  uint16_t d2;  // 256 x curvature x width^2 / 2, 1/256 mK, in units of 2^(5 + 2 binade): 10-byte
                // entries (the rounding adds at most 2^-4, 2^-2 and 1 of a unit to t)
};
const uint8_t kPt1000FixedSegments = 48;
const uint32_t kPt1000FixedMinQ16 = 512UL << 16;      // 512 ohm: -118.31 degC
const uint32_t kPt1000FixedMaxQ16 = 255909545UL;      // R(850 degC + kRtdInverseMarginC) x 2^16

inline const QuadSegmentFixed* pt1000_fixed_segments() {
  static const QuadSegmentFixed kTable[kPt1000FixedSegments] BTSM_FLASH = {
      {-31288570L, 511663278UL, 33016U},  // R from 512 ohm
      {-29285762L, 513776168UL, 31717U},  // R from 544 ohm
      {-27274862L, 515805849UL, 30455U},  // R from 576 ohm
      {-25256192L, 517754764UL, 29238U},  // R from 608 ohm
      {-23230061L, 519625769UL, 28072U},  // R from 640 ohm
      {-21196766L, 521422132UL, 26964U},  // R from 672 ohm
      {-19156593L, 523147516UL, 25918U},  // R from 704 ohm
      {-17109811L, 524805968UL, 24942U},  // R from 736 ohm
      {-15056672L, 526401904UL, 24040U},  // R from 768 ohm
      {-12997412L, 527940099UL, 23218U},  // R from 800 ohm
      {-10932246L, 529425669UL, 22481U},  // R from 832 ohm
      {-8861368L, 530864058UL, 21834U},  // R from 864 ohm
      {-6784953L, 532261025UL, 21282U},  // R from 896 ohm
      {-4703149L, 533622634UL, 20829U},  // R from 928 ohm
      {-2616083L, 534955239UL, 20480U},  // R from 960 ohm
      {-523854L, 536264036UL, 20326U},  // R from 992 ohm
      {1573470L, 1075124295UL, 20548U},  // R from 1024 ohm
      {5783451L, 1080384351UL, 20852U},  // R from 1088 ohm
      {10014132L, 1085722373UL, 21164U},  // R from 1152 ohm
      {14265820L, 1091140308UL, 21484U},  // R from 1216 ohm
      {18538833L, 1096640167UL, 21813U},  // R from 1280 ohm
      {22833493L, 1102224038UL, 22149U},  // R from 1344 ohm
      {27150134L, 1107894081UL, 22495U},  // R from 1408 ohm
      {31489096L, 1113652535UL, 22849U},  // R from 1472 ohm
      {35850730L, 1119501723UL, 23213U},  // R from 1536 ohm
      {40235394L, 1125444052UL, 23587U},  // R from 1600 ohm
      {44643457L, 1131482020UL, 23970U},  // R from 1664 ohm
      {49075297L, 1137618221UL, 24365U},  // R from 1728 ohm
      {53531305L, 1143855347UL, 24770U},  // R from 1792 ohm
      {58011879L, 1150196196UL, 25186U},  // R from 1856 ohm
      {62517431L, 1156643675UL, 25615U},  // R from 1920 ohm
      {67048382L, 1163200806UL, 26055U},  // R from 1984 ohm
      {71605184L, 2339674565UL, 26741U},  // R from 2048 ohm
      {80798060L, 2367053438UL, 27702U},  // R from 2176 ohm
      {90099810L, 2395416418UL, 28723U},  // R from 2304 ohm
      {99514396L, 2424823902UL, 29807U},  // R from 2432 ohm
      {109046028L, 2455341604UL, 30962U},  // R from 2560 ohm
      {118699181L, 2487041178UL, 32193U},  // R from 2688 ohm
      {128478627L, 2520000920UL, 33508U},  // R from 2816 ohm
      {138389455L, 2554306586UL, 34915U},  // R from 2944 ohm
      {148437109L, 2590052330UL, 36423U},  // R from 3072 ohm
      {158627415L, 2627341791UL, 38044U},  // R from 3200 ohm
      {168966629L, 2666289356UL, 39787U},  // R from 3328 ohm
      {179461475L, 2707021642UL, 41669U},  // R from 3456 ohm
      {190119200L, 2749679225UL, 43703U},  // R from 3584 ohm
      {200947633L, 2794418682UL, 45909U},  // R from 3712 ohm
      {211955248L, 2841415015UL, 48306U},  // R from 3840 ohm
      {223151247L, 2890864534UL, 50920U},  // R from 3968 ohm
  };
  return kTable;
}
}  // namespace detail_rtd

inline Pt1000FixedResult pt1000_temperature_q(uint32_t r_q16) {
  using namespace detail_rtd;
  Pt1000FixedResult r;
  r.t = 0;
  if (r_q16 < kPt1000FixedMinQ16) {
    r.status = RtdStatus::kBelowRange;
    return r;
  }
  if (r_q16 > kPt1000FixedMaxQ16) {
    r.status = RtdStatus::kAboveRange;
    return r;
  }
  // R normalised into [2^30, 2^31) by 5 - b left shifts, b the binade ([512 2^b, 1024 2^b) ohm):
  // then bits 29..26 are the segment and the 26 bits below the position in it.
  uint32_t v = r_q16;
  uint8_t b = 5;
  while (v < 0x40000000UL) v <<= 1, --b;
  const uint8_t k = static_cast<uint8_t>(static_cast<uint8_t>(v >> 24) >> 2) & 15U;
  const uint32_t u = v << 6;  // x as a 32-bit fraction (the segment bits shift out)
  const QuadSegmentFixed* q = pt1000_fixed_segments() + (16U * b + k);
  const int32_t d0 = flash_read_i32(&q->d0);
  const uint32_t d1 = flash_read_u32(&q->d1), d2 = static_cast<uint32_t>(flash_read_u16(&q->d2)) << (5 + 2 * b);
  r.status = RtdStatus::kOk;
  r.t = d0 + static_cast<int32_t>((fx::mul_hi_round(u, d1 + fx::mul_hi_round(u, d2)) + 128U) >> 8);
  return r;
}

}  // namespace btsm

#endif  // BTSM_COMMON_RTD_HPP
