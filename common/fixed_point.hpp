// Fixed-point arithmetic for the firmware (ATmega328P has no FPU; float costs ~100 cycles per op and
// its 24-bit mantissa is too coarse for a pole at 0.9981 iterated 17280 times a day).
//
// Two layers:
//   1. Raw helpers on int64_t: shift_right_round(), div_round(), rescale(), saturate<T>(). Every
//      rounding is named (Rounding::k...), every narrowing saturates and reports it.
//   2. Fixed<Storage, FracBits>: a Q format over int8_t/int16_t/int32_t storage (value = raw / 2^F)
//      with from_double/from_int/to_double, and free functions fx_mul/fx_div/fx_convert/fx_add/fx_sub
//      that take the result type as a template argument so no precision is lost implicitly.
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

}  // namespace fx
}  // namespace btsm

#endif  // BTSM_COMMON_FIXED_POINT_HPP
