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
#include <string.h>

#if defined(__AVR__)
#include <avr/pgmspace.h>
#endif

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

// ---- Fast Pt1000 inverse for the MCU ----------------------------------------------------------
//
// t(R) for the IEC 60751 Pt1000 as a piecewise quadratic over R in [512, 2048) ohm, i.e.
// -118 ... +275 degC, which holds every temperature a spindle probe sees; any other R (and NaN)
// goes to the exact RtdInverse (range errors included). The segments are the float's own grid:
// every R in [512, 2048) has the sign/exponent byte 0x44, the next 5 bits (exponent LSB and top 4
// mantissa bits) select one of 32 segments of 1/16 binade (32 ohm below 1024 ohm, 64 ohm above),
// and the remaining 19 mantissa bits are the offset from the segment centre in units of the
// binade's ulp (s, exact in float). So a conversion is t = a0 + s (a1 + s a2): one int-to-float
// conversion, two multiply-adds and a 12-byte table read, no division and no square root (on the
// ATmega328P ~650 cycles instead of ~1550 for RtdInverse's sqrt + division path).
// The coefficients interpolate the exact inverse (double) at the three Chebyshev nodes of each
// segment (near-minimax): fit error <= 9.2e-6 degC, and with float evaluation <= 2.3e-5 degC over
// -40...150 degC (RtdInverse<float>: 1.9e-5). tests/unit/common_numeric/rtd_test.cpp recomputes
// every coefficient from the exact inverse and measures the error over the whole table range.
namespace detail_rtd {
struct QuadSegment {
  float a0;  // t at the segment centre, degC
  float a1;  // degC per ulp
  float a2;  // degC per ulp^2
};
const uint8_t kPt1000Segments = 32;
const uint8_t kPt1000TableExponentByte = 0x44;  // R in [512, 2048): float bits 0x44000000..0x44FFFFFF
const int32_t kPt1000SegmentHalfUlps = 0x40000;  // half a segment: 2^18 ulps

inline const QuadSegment* pt1000_segments() {
  static const QuadSegment kTable[kPt1000Segments]
#if defined(__AVR__)
      PROGMEM
#endif
      = {
      {-118.313263f, 1.49221105e-05f, 5.86486494e-14f},  // R from 512 ohm
      {-110.473831f, 1.49823927e-05f, 5.63399594e-14f},  // R from 544 ohm
      {-102.603424f, 1.50402893e-05f, 5.40989982e-14f},  // R from 576 ohm
      {-94.7032776f, 1.50958767e-05f, 5.19373532e-14f},  // R from 608 ohm
      {-86.7745667f, 1.5149245e-05f, 4.98663441e-14f},  // R from 640 ohm
      {-78.8184433f, 1.52004932e-05f, 4.78969789e-14f},  // R from 672 ohm
      {-70.8359833f, 1.5249735e-05f, 4.60399134e-14f},  // R from 704 ohm
      {-62.8282013f, 1.52970933e-05f, 4.43054271e-14f},  // R from 736 ohm
      {-54.7960625f, 1.53427009e-05f, 4.27034134e-14f},  // R from 768 ohm
      {-46.7404442f, 1.53867022e-05f, 4.12433759e-14f},  // R from 800 ohm
      {-38.6621437f, 1.5429252e-05f, 3.99344254e-14f},  // R from 832 ohm
      {-30.5618839f, 1.54705122e-05f, 3.878531e-14f},  // R from 864 ohm
      {-22.4402943f, 1.55106554e-05f, 3.78044492e-14f},  // R from 896 ohm
      {-14.2979155f, 1.55498619e-05f, 3.69999577e-14f},  // R from 928 ohm
      {-6.13518906f, 1.55883208e-05f, 3.63797127e-14f},  // R from 960 ohm
      {2.04754519f, 1.56262668e-05f, 3.61060736e-14f},  // R from 992 ohm
      {14.3589458f, 3.13667806e-05f, 1.45999478e-13f},  // R from 1024 ohm
      {30.8444653f, 3.15210018e-05f, 1.48163599e-13f},  // R from 1088 ohm
      {47.411438f, 3.16775222e-05f, 1.50381728e-13f},  // R from 1152 ohm
      {64.0610886f, 3.18363964e-05f, 1.52655761e-13f},  // R from 1216 ohm
      {80.7946625f, 3.19976862e-05f, 1.5498769e-13f},  // R from 1280 ohm
      {97.6134491f, 3.21614534e-05f, 1.57379589e-13f},  // R from 1344 ohm
      {114.518753f, 3.232776e-05f, 1.59833653e-13f},  // R from 1408 ohm
      {131.511932f, 3.2496675e-05f, 1.62352174e-13f},  // R from 1472 ohm
      {148.59436f, 3.26682639e-05f, 1.64937535e-13f},  // R from 1536 ohm
      {165.767487f, 3.28425995e-05f, 1.67592245e-13f},  // R from 1600 ohm
      {183.03273f, 3.30197581e-05f, 1.70318946e-13f},  // R from 1664 ohm
      {200.391617f, 3.31998126e-05f, 1.73120388e-13f},  // R from 1728 ohm
      {217.845673f, 3.33828466e-05f, 1.75999487e-13f},  // R from 1792 ohm
      {235.3965f, 3.35689401e-05f, 1.78959278e-13f},  // R from 1856 ohm
      {253.045715f, 3.37581841e-05f, 1.82002972e-13f},  // R from 1920 ohm
      {270.794983f, 3.39506623e-05f, 1.85133931e-13f},  // R from 1984 ohm
  };
  return kTable;
}
}  // namespace detail_rtd

inline RtdResult<float> pt1000_temperature_fast(float r_ohm) {
  using namespace detail_rtd;
  uint32_t bits;
  memcpy(&bits, &r_ohm, sizeof bits);
  if (static_cast<uint8_t>(bits >> 24) != kPt1000TableExponentByte) {
    return RtdInverse<float>(iec60751<float>(1000.0f)).temperature(r_ohm);
  }
  const uint8_t seg = static_cast<uint8_t>(static_cast<uint8_t>(bits >> 16) >> 3);
  const float s = static_cast<float>(static_cast<int32_t>(bits & 0x7FFFFUL) - kPt1000SegmentHalfUlps);
  const QuadSegment* q = pt1000_segments() + seg;
#if defined(__AVR__)
  const float a0 = pgm_read_float(&q->a0), a1 = pgm_read_float(&q->a1), a2 = pgm_read_float(&q->a2);
#else
  const float a0 = q->a0, a1 = q->a1, a2 = q->a2;
#endif
  return good<float>(a0 + s * (a1 + s * a2));
}

}  // namespace btsm

#endif  // BTSM_COMMON_RTD_HPP
