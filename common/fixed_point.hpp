// Fixed-point arithmetic for the firmware (ATmega328P has no FPU; float costs ~100 cycles per op and
// its 24-bit mantissa is too coarse for a pole at 0.9981 iterated 17280 times a day).
//
// Three layers:
//   1. Raw helpers on int64_t: shift_right_round(), div_round(), rescale(), saturate<T>(). Every
//      rounding is named (Rounding::k...), every narrowing saturates and reports it.
//   2. Fixed<Storage, FracBits>: a Q format over int8_t/int16_t/int32_t storage (value = raw / 2^F)
//      with from_double/from_int/to_double, and free functions fx_mul/fx_div/fx_convert/fx_add/fx_sub
//      that take the result type as a template argument so no precision is lost implicitly.
//   3. 32-bit kernels for the MCU's sample path (mul_hi_round, frac_q32, isqrt32, sqrt_mul, ...):
//      no int64 division and no float, see their section below.
//
// Errors are reported through an optional `FxStatus*` that is STICKY: it is only ever written when
// something went wrong, so one status variable can collect a whole computation. The value returned
// on overflow is the saturated bound (never a wrapped-around number).
//
// Rounding modes (q = exact quotient):
//   kTowardZero        trunc(q)              C integer division semantics
//   kNearestHalfAway   round(q), ties away   2.5 -> 3, -2.5 -> -3 (what printf/lround do)
//   kFloor             floor(q)              what an arithmetic right shift does
//
// C++14, no standard library; compiles with avr-g++ 5.4 and g++ 12. Right shifts of negative
// values are arithmetic on every GCC target (documented GCC behaviour); left shifts of negative
// values are avoided (undefined in C++14) by multiplying instead.
#ifndef BTSM_COMMON_FIXED_POINT_HPP
#define BTSM_COMMON_FIXED_POINT_HPP

#include <stdint.h>

#include "platform.hpp"

namespace btsm {
namespace fx {

enum class Rounding : uint8_t { kTowardZero = 0, kNearestHalfAway = 1, kFloor = 2 };

enum class FxStatus : uint8_t {
  kOk = 0,
  kSaturated = 1,      // the exact result did not fit; the bound was returned
  kNotANumber = 2,     // NaN input (from_double); 0 returned
  kDivideByZero = 3,   // divisor 0; the bound with the sign of the dividend returned
};

inline void fx_flag(FxStatus* st, FxStatus what) {
  if (st != nullptr && *st == FxStatus::kOk) *st = what;
}

const int64_t kInt64Max = 0x7FFFFFFFFFFFFFFFLL;
const int64_t kInt64Min = -kInt64Max - 1;

// Limits and the double-width type of each supported storage type (own traits: no <limits>).
template <class T>
struct IntTraits;
template <>
struct IntTraits<int8_t> {
  static constexpr int8_t max() { return 127; }
  static constexpr int8_t min() { return -128; }
  static constexpr int bits() { return 8; }
};
template <>
struct IntTraits<int16_t> {
  static constexpr int16_t max() { return 32767; }
  static constexpr int16_t min() { return -32767 - 1; }
  static constexpr int bits() { return 16; }
};
template <>
struct IntTraits<int32_t> {
  static constexpr int32_t max() { return 2147483647L; }
  static constexpr int32_t min() { return -2147483647L - 1; }
  static constexpr int bits() { return 32; }
};

// 2^n as int64 for n in [0, 62].
inline constexpr int64_t pow2(int n) { return static_cast<int64_t>(1) << n; }

// Narrow v to T, saturating at T's bounds.
template <class T>
inline T saturate(int64_t v, FxStatus* st = nullptr) {
  if (v > static_cast<int64_t>(IntTraits<T>::max())) {
    fx_flag(st, FxStatus::kSaturated);
    return IntTraits<T>::max();
  }
  if (v < static_cast<int64_t>(IntTraits<T>::min())) {
    fx_flag(st, FxStatus::kSaturated);
    return IntTraits<T>::min();
  }
  return static_cast<T>(v);
}

// v / 2^s rounded as requested, for s in [0, 62]. Overflow-free for every int64 v, INT64_MIN
// included: floor first (arithmetic shift), then correct with the discarded remainder.
// Not inlined: on the AVR every inlined copy of this 64-bit code costs ~200 bytes of flash.
__attribute__((noinline)) inline int64_t shift_right_round(int64_t v, int s, Rounding r) {
  if (s <= 0) return v;
  const int64_t q = v >> s;                                   // floor(v / 2^s)
  const uint64_t mask = (static_cast<uint64_t>(1) << s) - 1U;
  const uint64_t rem = static_cast<uint64_t>(v) & mask;       // v - q*2^s, in [0, 2^s)
  if (rem == 0U) return q;
  switch (r) {
    case Rounding::kFloor:
      return q;
    case Rounding::kTowardZero:
      return v < 0 ? q + 1 : q;
    case Rounding::kNearestHalfAway: {
      const uint64_t half = static_cast<uint64_t>(1) << (s - 1);
      if (rem > half) return q + 1;
      if (rem < half) return q;
      return v < 0 ? q : q + 1;  // tie: floor is already "away" for negatives
    }
  }
  return q;
}

// num / den rounded as requested. den == 0 flags kDivideByZero and returns the bound with the sign
// of num (0 for 0/0). INT64_MIN / -1 saturates.
inline int64_t div_round(int64_t num, int64_t den, Rounding r, FxStatus* st = nullptr) {
  if (den == 0) {
    fx_flag(st, FxStatus::kDivideByZero);
    return num > 0 ? kInt64Max : (num < 0 ? kInt64Min : 0);
  }
  if (den == -1) {
    if (num == kInt64Min) {
      fx_flag(st, FxStatus::kSaturated);
      return kInt64Max;
    }
    return -num;
  }
  const int64_t q = num / den;  // truncates toward zero
  const int64_t rem = num % den;
  if (rem == 0) return q;
  const bool negative = (num < 0) != (den < 0);
  switch (r) {
    case Rounding::kTowardZero:
      return q;
    case Rounding::kFloor:
      return negative ? q - 1 : q;
    case Rounding::kNearestHalfAway: {
      // |rem| >= |den| - |rem|  <=>  2|rem| >= |den|, written without overflow. |den| >= 2 here,
      // and den != INT64_MIN is not required: |rem| < |den| keeps both sides representable as
      // unsigned magnitudes.
      const uint64_t arem = rem < 0 ? 0U - static_cast<uint64_t>(rem) : static_cast<uint64_t>(rem);
      const uint64_t aden = den < 0 ? 0U - static_cast<uint64_t>(den) : static_cast<uint64_t>(den);
      if (arem >= aden - arem) return negative ? q - 1 : q + 1;
      return q;
    }
  }
  return q;
}

// Re-express v (with `from` fractional bits) with `to` fractional bits. Going up multiplies
// (saturating at int64 bounds), going down rounds.
inline int64_t rescale(int64_t v, int from, int to, Rounding r, FxStatus* st = nullptr) {
  if (to >= from) {
    const int s = to - from;
    if (s == 0) return v;
    if (s > 62 || v > (kInt64Max >> s) || v < (kInt64Min >> s)) {
      if (v != 0) {
        fx_flag(st, FxStatus::kSaturated);
        return v > 0 ? kInt64Max : kInt64Min;
      }
      return 0;
    }
    return v * pow2(s);
  }
  const int s = from - to;
  if (s > 62) return shift_right_round(shift_right_round(v, 62, Rounding::kFloor), s - 62, r);
  return shift_right_round(v, s, r);
}

// Q format: value = raw / 2^FracBits. FracBits may exceed the storage width (pure fraction with
// leading zeros) or be negative is NOT supported; 0 <= FracBits < bits.
template <class Storage, int FracBits>
class Fixed {
  static_assert(FracBits >= 0 && FracBits < IntTraits<Storage>::bits(),
                "FracBits must be in [0, storage bits)");

 public:
  typedef Storage storage_type;
  static constexpr int frac_bits() { return FracBits; }
  static constexpr Storage raw_max() { return IntTraits<Storage>::max(); }
  static constexpr Storage raw_min() { return IntTraits<Storage>::min(); }

  constexpr Fixed() : raw_(0) {}
  static constexpr Fixed from_raw(Storage raw) { return Fixed(raw, 0); }
  static Fixed max() { return from_raw(raw_max()); }
  static Fixed min() { return from_raw(raw_min()); }
  static Fixed lsb() { return from_raw(1); }

  static Fixed from_int(int32_t v, FxStatus* st = nullptr) {
    return from_raw(saturate<Storage>(rescale(v, 0, FracBits, Rounding::kFloor, st), st));
  }

  // NaN -> 0 with kNotANumber; +-inf and out-of-range values saturate with kSaturated.
  static Fixed from_double(double v, Rounding r, FxStatus* st = nullptr) {
    if (v != v) {
      fx_flag(st, FxStatus::kNotANumber);
      return Fixed();
    }
    const double scaled = v * static_cast<double>(pow2(FracBits));
    // Compare in double before converting: a double -> int conversion out of range is undefined.
    if (scaled >= static_cast<double>(raw_max()) + 1.0) {
      fx_flag(st, FxStatus::kSaturated);
      return max();
    }
    if (scaled < static_cast<double>(raw_min()) - 1.0) {
      fx_flag(st, FxStatus::kSaturated);
      return min();
    }
    double whole = static_cast<double>(static_cast<int64_t>(scaled));  // toward zero
    const double frac = scaled - whole;
    switch (r) {
      case Rounding::kTowardZero:
        break;
      case Rounding::kFloor:
        if (frac < 0.0) whole -= 1.0;
        break;
      case Rounding::kNearestHalfAway:
        if (frac >= 0.5) whole += 1.0;
        if (frac <= -0.5) whole -= 1.0;
        break;
    }
    return from_raw(saturate<Storage>(static_cast<int64_t>(whole), st));
  }

  constexpr Storage raw() const { return raw_; }
  double to_double() const { return static_cast<double>(raw_) / static_cast<double>(pow2(FracBits)); }
  float to_float() const { return static_cast<float>(raw_) / static_cast<float>(pow2(FracBits)); }
  int32_t to_int(Rounding r) const {
    return static_cast<int32_t>(shift_right_round(raw_, FracBits, r));
  }

  friend bool operator==(Fixed a, Fixed b) { return a.raw_ == b.raw_; }
  friend bool operator!=(Fixed a, Fixed b) { return a.raw_ != b.raw_; }
  friend bool operator<(Fixed a, Fixed b) { return a.raw_ < b.raw_; }
  friend bool operator>(Fixed a, Fixed b) { return a.raw_ > b.raw_; }
  friend bool operator<=(Fixed a, Fixed b) { return a.raw_ <= b.raw_; }
  friend bool operator>=(Fixed a, Fixed b) { return a.raw_ >= b.raw_; }

 private:
  constexpr Fixed(Storage raw, int) : raw_(raw) {}
  Storage raw_;
};

// Common formats.
typedef Fixed<int16_t, 15> Q15;      // [-1, 1)
typedef Fixed<int32_t, 31> Q31;      // [-1, 1)
typedef Fixed<int32_t, 30> Q1_30;    // [-2, 2)
typedef Fixed<int32_t, 16> Q16_16;   // [-32768, 32768)

// Result type first: fx_convert<Q16_16>(x, Rounding::kNearestHalfAway, &st).
template <class R, class A>
inline R fx_convert(A a, Rounding r, FxStatus* st = nullptr) {
  return R::from_raw(saturate<typename R::storage_type>(
      rescale(a.raw(), A::frac_bits(), R::frac_bits(), r, st), st));
}

// a * b, computed exactly in int64 (both storages are at most 32 bits) and rounded once.
template <class R, class A, class B>
inline R fx_mul(A a, B b, Rounding r, FxStatus* st = nullptr) {
  const int64_t p = static_cast<int64_t>(a.raw()) * static_cast<int64_t>(b.raw());
  return R::from_raw(saturate<typename R::storage_type>(
      rescale(p, A::frac_bits() + B::frac_bits(), R::frac_bits(), r, st), st));
}

// a / b rounded once: the dividend is scaled up to carry R's fractional bits before dividing.
template <class R, class A, class B>
inline R fx_div(A a, B b, Rounding r, FxStatus* st = nullptr) {
  // raw_R = raw_a * 2^(FR + FB - FA) / raw_b
  const int up = R::frac_bits() + B::frac_bits() - A::frac_bits();
  int64_t num = a.raw();
  int64_t den = b.raw();
  if (up >= 0) {
    num = rescale(num, 0, up, Rounding::kFloor, st);  // |raw_a| < 2^31, up <= 61: exact
  } else {
    den = rescale(den, 0, -up, Rounding::kFloor, st);
  }
  if (den == 0) {
    fx_flag(st, FxStatus::kDivideByZero);
    if (a.raw() > 0) return R::max();
    if (a.raw() < 0) return R::min();
    return R();
  }
  return R::from_raw(saturate<typename R::storage_type>(div_round(num, den, r, st), st));
}

template <class T>
inline T fx_add(T a, T b, FxStatus* st = nullptr) {
  return T::from_raw(saturate<typename T::storage_type>(
      static_cast<int64_t>(a.raw()) + static_cast<int64_t>(b.raw()), st));
}

template <class T>
inline T fx_sub(T a, T b, FxStatus* st = nullptr) {
  return T::from_raw(saturate<typename T::storage_type>(
      static_cast<int64_t>(a.raw()) - static_cast<int64_t>(b.raw()), st));
}

// ---- 32-bit kernels for the MCU's sample path --------------------------------------------------
// The ATmega328P has a hardware 8x8 multiplier but no divider: a 32x32 -> 64 product is a few
// hundred cycles, a 64-bit division a few thousand, a float operation ~100-300 plus the soft-float
// library in flash. These kernels keep the per-sample arithmetic (ratiometric resistance, RTD
// inverse, Kalman filter) in integers: products through the high word of a 64-bit product, the
// rare quotients by shift-and-subtract loops that need no libgcc 64-bit division.

// round(u * f / 2^32), ties up: the high word of the 64-bit product. With f a 32-bit fraction
// (f / 2^32 in [0, 1)) this is u scaled by that fraction, rounded to nearest. On the AVR sixteen
// hardware 8 x 8 multiplications in place (~110 cycles, no stack frame): avr-gcc 5.4 compiles the
// portable form into a libgcc __umulsidi3 call whose 64-bit result goes through the stack
// (~250 cycles with the frame). The host never compiles the assembly:
// tests/simavr/sim/avr_numeric_test.cpp runs it on the simulated ATmega328P against exact results.
// Out of line on the AVR: 180 bytes of code, called from the whole sample path.
#if defined(__AVR__)
__attribute__((noinline))
#endif
inline uint32_t mul_hi_round(uint32_t u, uint32_t f) {
#if defined(__AVR__)
  uint32_t hi, lo;  // product bytes P7..P4 and P3..P0
  uint8_t zero;
  // Diagonal products first (each a register pair), 2^31 added (the rounding), then the cross
  // products u_i f_j at byte i + j with the carry run up to P7. r1 (the compiler's zero register)
  // is the multiplier's high byte: cleared at the end.
  __asm__(
      "clr  %[z]"            "\n\t"
      "mul  %A[u], %A[f]"    "\n\t"  // u0 f0 -> P1:P0
      "movw %A[lo], r0"      "\n\t"
      "mul  %B[u], %B[f]"    "\n\t"  // u1 f1 -> P3:P2
      "movw %C[lo], r0"      "\n\t"
      "mul  %C[u], %C[f]"    "\n\t"  // u2 f2 -> P5:P4
      "movw %A[hi], r0"      "\n\t"
      "mul  %D[u], %D[f]"    "\n\t"  // u3 f3 -> P7:P6
      "movw %C[hi], r0"      "\n\t"
      "ldi  %[z], 0x80"      "\n\t"  // + 2^31
      "add  %D[lo], %[z]"    "\n\t"
      "clr  %[z]"            "\n\t"
      "adc  %A[hi], %[z]"    "\n\t"
      "adc  %B[hi], %[z]"    "\n\t"
      "adc  %C[hi], %[z]"    "\n\t"
      "adc  %D[hi], %[z]"    "\n\t"
      "mul  %A[u], %B[f]"    "\n\t"  // u0 f1 -> P2:P1
      "add  %B[lo], r0"      "\n\t"
      "adc  %C[lo], r1"      "\n\t"
      "adc  %D[lo], %[z]"    "\n\t"
      "adc  %A[hi], %[z]"    "\n\t"
      "adc  %B[hi], %[z]"    "\n\t"
      "adc  %C[hi], %[z]"    "\n\t"
      "adc  %D[hi], %[z]"    "\n\t"
      "mul  %B[u], %A[f]"    "\n\t"  // u1 f0 -> P2:P1
      "add  %B[lo], r0"      "\n\t"
      "adc  %C[lo], r1"      "\n\t"
      "adc  %D[lo], %[z]"    "\n\t"
      "adc  %A[hi], %[z]"    "\n\t"
      "adc  %B[hi], %[z]"    "\n\t"
      "adc  %C[hi], %[z]"    "\n\t"
      "adc  %D[hi], %[z]"    "\n\t"
      "mul  %A[u], %C[f]"    "\n\t"  // u0 f2 -> P3:P2
      "add  %C[lo], r0"      "\n\t"
      "adc  %D[lo], r1"      "\n\t"
      "adc  %A[hi], %[z]"    "\n\t"
      "adc  %B[hi], %[z]"    "\n\t"
      "adc  %C[hi], %[z]"    "\n\t"
      "adc  %D[hi], %[z]"    "\n\t"
      "mul  %C[u], %A[f]"    "\n\t"  // u2 f0 -> P3:P2
      "add  %C[lo], r0"      "\n\t"
      "adc  %D[lo], r1"      "\n\t"
      "adc  %A[hi], %[z]"    "\n\t"
      "adc  %B[hi], %[z]"    "\n\t"
      "adc  %C[hi], %[z]"    "\n\t"
      "adc  %D[hi], %[z]"    "\n\t"
      "mul  %A[u], %D[f]"    "\n\t"  // u0 f3 -> P4:P3
      "add  %D[lo], r0"      "\n\t"
      "adc  %A[hi], r1"      "\n\t"
      "adc  %B[hi], %[z]"    "\n\t"
      "adc  %C[hi], %[z]"    "\n\t"
      "adc  %D[hi], %[z]"    "\n\t"
      "mul  %D[u], %A[f]"    "\n\t"  // u3 f0 -> P4:P3
      "add  %D[lo], r0"      "\n\t"
      "adc  %A[hi], r1"      "\n\t"
      "adc  %B[hi], %[z]"    "\n\t"
      "adc  %C[hi], %[z]"    "\n\t"
      "adc  %D[hi], %[z]"    "\n\t"
      "mul  %B[u], %C[f]"    "\n\t"  // u1 f2 -> P4:P3
      "add  %D[lo], r0"      "\n\t"
      "adc  %A[hi], r1"      "\n\t"
      "adc  %B[hi], %[z]"    "\n\t"
      "adc  %C[hi], %[z]"    "\n\t"
      "adc  %D[hi], %[z]"    "\n\t"
      "mul  %C[u], %B[f]"    "\n\t"  // u2 f1 -> P4:P3
      "add  %D[lo], r0"      "\n\t"
      "adc  %A[hi], r1"      "\n\t"
      "adc  %B[hi], %[z]"    "\n\t"
      "adc  %C[hi], %[z]"    "\n\t"
      "adc  %D[hi], %[z]"    "\n\t"
      "mul  %B[u], %D[f]"    "\n\t"  // u1 f3 -> P5:P4
      "add  %A[hi], r0"      "\n\t"
      "adc  %B[hi], r1"      "\n\t"
      "adc  %C[hi], %[z]"    "\n\t"
      "adc  %D[hi], %[z]"    "\n\t"
      "mul  %D[u], %B[f]"    "\n\t"  // u3 f1 -> P5:P4
      "add  %A[hi], r0"      "\n\t"
      "adc  %B[hi], r1"      "\n\t"
      "adc  %C[hi], %[z]"    "\n\t"
      "adc  %D[hi], %[z]"    "\n\t"
      "mul  %C[u], %D[f]"    "\n\t"  // u2 f3 -> P6:P5
      "add  %B[hi], r0"      "\n\t"
      "adc  %C[hi], r1"      "\n\t"
      "adc  %D[hi], %[z]"    "\n\t"
      "mul  %D[u], %C[f]"    "\n\t"  // u3 f2 -> P6:P5
      "add  %B[hi], r0"      "\n\t"
      "adc  %C[hi], r1"      "\n\t"
      "adc  %D[hi], %[z]"    "\n\t"  // no carry out: u f + 2^31 < 2^64
      "clr  __zero_reg__"
      : [hi] "=&r"(hi), [lo] "=&r"(lo), [z] "=&d"(zero)
      : [u] "r"(u), [f] "r"(f)
      : "r0");
  (void)lo;
  return hi;
#elif BTSM_LITTLE_ENDIAN
  union {
    uint64_t v;
    uint32_t w[2];  // w[0] low, w[1] high
  } p;
  p.v = static_cast<uint64_t>(u) * f;
  return p.w[1] + (p.w[0] >> 31);
#else
  const uint64_t v = static_cast<uint64_t>(u) * f;
  return static_cast<uint32_t>(v >> 32) + static_cast<uint32_t>((v >> 31) & 1U);
#endif
}

// round(a * 2^32 / b) for a < b (b > 0): a ratio below 1 as a 32-bit fraction, by 32 steps of
// shift-and-subtract (no division instruction, no 64-bit libgcc division), ties up; 0xFFFFFFFF
// when the rounded ratio would be 1.
inline uint32_t frac_q32(uint32_t a, uint32_t b) {
  uint32_t q = 0, r = a;
  for (uint8_t i = 0; i < 32; ++i) {
    const bool carry = (r & 0x80000000UL) != 0;  // 2r >= 2^32 > b
    r <<= 1;
    q <<= 1;
    if (carry || r >= b) {
      r -= b;
      q |= 1U;
    }
  }
  // Round: remainder r / b >= 1/2.
  if ((r & 0x80000000UL) != 0 || (r << 1) >= b) q = q == 0xFFFFFFFFUL ? q : q + 1U;
  return q;
}

// floor(sqrt(v)), bit by bit (16 steps).
inline uint16_t isqrt32(uint32_t v) {
  uint32_t root = 0, bit = 1UL << 30;
  while (bit > v) bit >>= 2;
  while (bit != 0) {
    if (v >= root + bit) {
      v -= root + bit;
      root = (root >> 1) + bit;
    } else {
      root >>= 1;
    }
    bit >>= 2;
  }
  return static_cast<uint16_t>(root);
}

// v shifted left (by the count returned in *shift) until bit 31 is set; v > 0.
__attribute__((noinline)) inline uint32_t normalize(uint32_t v, uint8_t* shift) {
  uint8_t k = 0;
  while ((v & 0x80000000UL) == 0) v <<= 1, ++k;
  *shift = k;
  return v;
}

// v 2^sh, rounded to nearest for sh < 0 (ties up: the last bit shifted out), saturated at
// 0xFFFFFFFF for sh > 0. Out of line: variable shifts are bit loops on the AVR.
__attribute__((noinline)) inline uint32_t shift_round_sat(uint32_t v, int8_t sh) {
  for (; sh > 0; --sh) {
    if (v & 0x80000000UL) return 0xFFFFFFFFUL;
    v <<= 1;
  }
  uint32_t last = 0;
  for (; sh < 0; ++sh) {
    last = v & 1U;
    v >>= 1;
  }
  return v + last;
}

// v shifted left by an even count (returned in *shift) into [2^30, 2^32); v > 0.
__attribute__((noinline)) inline uint32_t normalize_even(uint32_t v, uint8_t* shift) {
  uint8_t k = 0;
  while (v < 0x40000000UL) v <<= 2, k = static_cast<uint8_t>(k + 2);
  *shift = k;
  return v;
}

// sqrt(a b) for a, b > 0 (a b < 2^64) to 2^-15 relative (floor), from the 16-bit integer roots of
// the two operands normalised into [2^30, 2^32): no 64-bit radicand. Enough for the Kalman
// filter's gates and steady state (a relative error of 3e-5 in a 5-sigma gate or in the steady
// gain moves the estimate by far less than its 4 uK resolution).
inline uint32_t sqrt_mul(uint32_t a, uint32_t b) {
  uint8_t i, j;
  const uint32_t sa = isqrt32(normalize_even(a, &i)), sb = isqrt32(normalize_even(b, &j));
  // sqrt(a b) = sa sb / 2^((i + j) / 2), sa sb < 2^32.
  return shift_round_sat(sa * sb, static_cast<int8_t>(-((i + j) >> 1)));
}

}  // namespace fx
}  // namespace btsm

#endif  // BTSM_COMMON_FIXED_POINT_HPP
