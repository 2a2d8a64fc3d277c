// Fixed point: every rounding mode on both signs and ties, saturation at the int32/int16/int8
// edges (INT32_MIN/MAX, -1 LSB, ...), mul/div/convert, and an exhaustive check of shift rounding
// against exact rational arithmetic.
#include "common/fixed_point.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <random>

namespace btsm::fx {
namespace {

constexpr int32_t kI32Max = 2147483647;
constexpr int32_t kI32Min = -2147483647 - 1;

TEST(FixedRounding, ShiftRightRoundAllModesOnTiesAndBothSigns) {
  // v / 4 for v = -10..10 against hand-computed values.
  struct Row { int64_t v; int64_t tz, near, floor; };
  const Row rows[] = {
      {10, 2, 3, 2},    // 2.5
      {-10, -2, -3, -3},  // -2.5: tie away from zero
      {9, 2, 2, 2},     // 2.25
      {-9, -2, -2, -3},
      {11, 2, 3, 2},    // 2.75
      {-11, -2, -3, -3},
      {2, 0, 1, 0},     // 0.5
      {-2, 0, -1, -1},  // -0.5
      {-1, 0, 0, -1},   // -0.25: -1 LSB input
      {0, 0, 0, 0},
  };
  for (const Row& r : rows) {
    EXPECT_EQ(shift_right_round(r.v, 2, Rounding::kTowardZero), r.tz) << r.v;
    EXPECT_EQ(shift_right_round(r.v, 2, Rounding::kNearestHalfAway), r.near) << r.v;
    EXPECT_EQ(shift_right_round(r.v, 2, Rounding::kFloor), r.floor) << r.v;
  }
}

TEST(FixedRounding, ShiftRightRoundMatchesExactArithmeticExhaustively) {
  for (int s = 1; s <= 6; ++s) {
    const double scale = std::ldexp(1.0, s);
    for (int64_t v = -300; v <= 300; ++v) {
      const double q = v / scale;
      EXPECT_EQ(shift_right_round(v, s, Rounding::kFloor), static_cast<int64_t>(std::floor(q)));
      EXPECT_EQ(shift_right_round(v, s, Rounding::kTowardZero), static_cast<int64_t>(std::trunc(q)));
      EXPECT_EQ(shift_right_round(v, s, Rounding::kNearestHalfAway), static_cast<int64_t>(std::round(q)));
    }
  }
}

TEST(FixedRounding, ShiftRightRoundAtInt64Edges) {
  EXPECT_EQ(shift_right_round(kInt64Min, 1, Rounding::kNearestHalfAway), kInt64Min / 2);
  EXPECT_EQ(shift_right_round(kInt64Max, 1, Rounding::kNearestHalfAway), kInt64Max / 2 + 1);
  EXPECT_EQ(shift_right_round(kInt64Max, 1, Rounding::kFloor), kInt64Max / 2);
  EXPECT_EQ(shift_right_round(kInt64Min + 1, 1, Rounding::kTowardZero), (kInt64Min + 1) / 2);
  EXPECT_EQ(shift_right_round(kInt64Min, 62, Rounding::kNearestHalfAway), -2);
  EXPECT_EQ(shift_right_round(-1, 62, Rounding::kFloor), -1);
  EXPECT_EQ(shift_right_round(-1, 62, Rounding::kNearestHalfAway), 0);
}

TEST(FixedRounding, DivRoundAllModesAndSigns) {
  EXPECT_EQ(div_round(7, 2, Rounding::kTowardZero), 3);
  EXPECT_EQ(div_round(7, 2, Rounding::kNearestHalfAway), 4);
  EXPECT_EQ(div_round(7, 2, Rounding::kFloor), 3);
  EXPECT_EQ(div_round(-7, 2, Rounding::kTowardZero), -3);
  EXPECT_EQ(div_round(-7, 2, Rounding::kNearestHalfAway), -4);
  EXPECT_EQ(div_round(-7, 2, Rounding::kFloor), -4);
  EXPECT_EQ(div_round(7, -2, Rounding::kFloor), -4);
  EXPECT_EQ(div_round(-7, -2, Rounding::kFloor), 3);
  EXPECT_EQ(div_round(5, 3, Rounding::kNearestHalfAway), 2);
  EXPECT_EQ(div_round(4, 3, Rounding::kNearestHalfAway), 1);
  EXPECT_EQ(div_round(-5, 3, Rounding::kNearestHalfAway), -2);
  for (int64_t n = -50; n <= 50; ++n) {
    for (int64_t d : {-7, -3, -2, -1, 1, 2, 3, 7}) {
      const double q = static_cast<double>(n) / static_cast<double>(d);
      EXPECT_EQ(div_round(n, d, Rounding::kFloor), static_cast<int64_t>(std::floor(q))) << n << "/" << d;
      EXPECT_EQ(div_round(n, d, Rounding::kTowardZero), static_cast<int64_t>(std::trunc(q))) << n << "/" << d;
      EXPECT_EQ(div_round(n, d, Rounding::kNearestHalfAway), static_cast<int64_t>(std::round(q))) << n << "/" << d;
    }
  }
}

TEST(FixedRounding, DivRoundEdgesAndDivideByZero) {
  FxStatus st = FxStatus::kOk;
  EXPECT_EQ(div_round(kInt64Min, -1, Rounding::kFloor, &st), kInt64Max);
  EXPECT_EQ(st, FxStatus::kSaturated);
  st = FxStatus::kOk;
  EXPECT_EQ(div_round(5, 0, Rounding::kFloor, &st), kInt64Max);
  EXPECT_EQ(st, FxStatus::kDivideByZero);
  EXPECT_EQ(div_round(-5, 0, Rounding::kFloor), kInt64Min);
  EXPECT_EQ(div_round(0, 0, Rounding::kFloor), 0);
  EXPECT_EQ(div_round(kInt64Max, kInt64Max, Rounding::kNearestHalfAway), 1);
  EXPECT_EQ(div_round(kInt64Min, kInt64Min, Rounding::kNearestHalfAway), 1);
  EXPECT_EQ(div_round(kInt64Max, kInt64Min, Rounding::kNearestHalfAway), -1);
  EXPECT_EQ(div_round(kInt64Max, 2, Rounding::kNearestHalfAway), kInt64Max / 2 + 1);
}

TEST(FixedSaturate, Int32Edges) {
  FxStatus st = FxStatus::kOk;
  EXPECT_EQ(saturate<int32_t>(kI32Max, &st), kI32Max);
  EXPECT_EQ(saturate<int32_t>(kI32Min, &st), kI32Min);
  EXPECT_EQ(st, FxStatus::kOk);
  EXPECT_EQ(saturate<int32_t>(static_cast<int64_t>(kI32Max) + 1, &st), kI32Max);
  EXPECT_EQ(st, FxStatus::kSaturated);
  st = FxStatus::kOk;
  EXPECT_EQ(saturate<int32_t>(static_cast<int64_t>(kI32Min) - 1, &st), kI32Min);
  EXPECT_EQ(st, FxStatus::kSaturated);
  EXPECT_EQ(saturate<int16_t>(-32769), -32768);
  EXPECT_EQ(saturate<int8_t>(128), 127);
  EXPECT_EQ(saturate<int8_t>(-1), -1);
}

TEST(FixedStatus, IsStickyFirstErrorWins) {
  FxStatus st = FxStatus::kOk;
  div_round(1, 0, Rounding::kFloor, &st);
  saturate<int8_t>(1000, &st);
  EXPECT_EQ(st, FxStatus::kDivideByZero);
}

using Q16 = Q16_16;

TEST(FixedFormat, FromDoubleRoundsAsNamedAndSaturates) {
  const double lsb = 1.0 / 65536.0;
  EXPECT_EQ(Q16::from_double(2.5 * lsb, Rounding::kNearestHalfAway).raw(), 3);
  EXPECT_EQ(Q16::from_double(-2.5 * lsb, Rounding::kNearestHalfAway).raw(), -3);
  EXPECT_EQ(Q16::from_double(-2.5 * lsb, Rounding::kTowardZero).raw(), -2);
  EXPECT_EQ(Q16::from_double(-2.5 * lsb, Rounding::kFloor).raw(), -3);
  EXPECT_EQ(Q16::from_double(-0.25 * lsb, Rounding::kFloor).raw(), -1);  // -1 LSB
  EXPECT_EQ(Q16::from_double(-0.25 * lsb, Rounding::kNearestHalfAway).raw(), 0);
  FxStatus st = FxStatus::kOk;
  EXPECT_EQ(Q16::from_double(32767.99998, Rounding::kNearestHalfAway, &st).raw(), kI32Max);
  EXPECT_EQ(st, FxStatus::kOk);  // rounds to exactly raw max
  EXPECT_EQ(Q16::from_double(32768.0, Rounding::kFloor, &st).raw(), kI32Max);
  EXPECT_EQ(st, FxStatus::kSaturated);
  st = FxStatus::kOk;
  EXPECT_EQ(Q16::from_double(-32768.0, Rounding::kFloor, &st).raw(), kI32Min);
  EXPECT_EQ(st, FxStatus::kOk);
  EXPECT_EQ(Q16::from_double(-32768.00002, Rounding::kFloor, &st).raw(), kI32Min);
  EXPECT_EQ(st, FxStatus::kSaturated);
  st = FxStatus::kOk;
  EXPECT_EQ(Q16::from_double(NAN, Rounding::kFloor, &st).raw(), 0);
  EXPECT_EQ(st, FxStatus::kNotANumber);
  st = FxStatus::kOk;
  EXPECT_EQ(Q16::from_double(-INFINITY, Rounding::kFloor, &st).raw(), kI32Min);
  EXPECT_EQ(st, FxStatus::kSaturated);
}

TEST(FixedFormat, FromIntAndToInt) {
  FxStatus st = FxStatus::kOk;
  EXPECT_EQ(Q16::from_int(-3, &st).raw(), -3 * 65536);
  EXPECT_EQ(Q16::from_int(32767, &st).raw(), 32767 * 65536);
  EXPECT_EQ(st, FxStatus::kOk);
  EXPECT_EQ(Q16::from_int(32768, &st).raw(), kI32Max);
  EXPECT_EQ(st, FxStatus::kSaturated);
  EXPECT_EQ(Q16::from_raw(-98304).to_int(Rounding::kNearestHalfAway), -2);  // -1.5
  EXPECT_EQ(Q16::from_raw(-98304).to_int(Rounding::kTowardZero), -1);
  EXPECT_EQ(Q16::from_raw(-98304).to_int(Rounding::kFloor), -2);
  EXPECT_EQ(Q16::from_raw(kI32Min).to_int(Rounding::kFloor), -32768);
  EXPECT_EQ(Q16::from_raw(kI32Max).to_int(Rounding::kNearestHalfAway), 32768);
  EXPECT_DOUBLE_EQ(Q16::from_raw(-1).to_double(), -1.0 / 65536.0);
  EXPECT_FLOAT_EQ(Q15::from_raw(-32768).to_float(), -1.0f);
}

TEST(FixedArithmetic, MultiplyAtEdges) {
  FxStatus st = FxStatus::kOk;
  // Q31: (-1) * (-1) = +1 does not fit -> saturates to max.
  EXPECT_EQ(fx_mul<Q31>(Q31::min(), Q31::min(), Rounding::kNearestHalfAway, &st).raw(), kI32Max);
  EXPECT_EQ(st, FxStatus::kSaturated);
  st = FxStatus::kOk;
  // (-1) * max = -max exactly (no saturation)
  EXPECT_EQ(fx_mul<Q31>(Q31::min(), Q31::max(), Rounding::kNearestHalfAway, &st).raw(), -kI32Max);
  EXPECT_EQ(st, FxStatus::kOk);
  // Into a wider result format the square of -1 fits.
  EXPECT_EQ(fx_mul<Q1_30>(Q31::min(), Q31::min(), Rounding::kFloor, &st).raw(), 1 << 30);
  // -1 LSB * 0.5: the rounding mode decides.
  const Q16 m1 = Q16::from_raw(-1), half = Q16::from_raw(32768);
  EXPECT_EQ(fx_mul<Q16>(m1, half, Rounding::kTowardZero).raw(), 0);
  EXPECT_EQ(fx_mul<Q16>(m1, half, Rounding::kFloor).raw(), -1);
  EXPECT_EQ(fx_mul<Q16>(m1, half, Rounding::kNearestHalfAway).raw(), -1);
  // Large positive * large positive overflows Q16.16.
  st = FxStatus::kOk;
  EXPECT_EQ(fx_mul<Q16>(Q16::from_int(200), Q16::from_int(200), Rounding::kFloor, &st).raw(), kI32Max);
  EXPECT_EQ(st, FxStatus::kSaturated);
  EXPECT_EQ(fx_mul<Q16>(Q16::from_int(-200), Q16::from_int(200), Rounding::kFloor).raw(), kI32Min);
}

TEST(FixedArithmetic, MultiplyMatchesDoubleOnRandomValues) {
  std::mt19937 rng(1);
  std::uniform_int_distribution<int32_t> any(kI32Min, kI32Max);
  for (int i = 0; i < 20000; ++i) {
    const Q1_30 a = Q1_30::from_raw(any(rng));
    const Q16 b = Q16::from_raw(any(rng) >> 8);  // |b| < 128
    FxStatus st = FxStatus::kOk;
    const Q16 p = fx_mul<Q16>(a, b, Rounding::kNearestHalfAway, &st);
    ASSERT_EQ(st, FxStatus::kOk);
    EXPECT_NEAR(p.to_double(), a.to_double() * b.to_double(), 0.5 / 65536.0 + 1e-12);
  }
}

TEST(FixedArithmetic, DivideAtEdges) {
  FxStatus st = FxStatus::kOk;
  EXPECT_EQ(fx_div<Q16>(Q16::from_int(1), Q16::from_int(3), Rounding::kNearestHalfAway).raw(), 21845);
  EXPECT_EQ(fx_div<Q16>(Q16::from_int(2), Q16::from_int(3), Rounding::kNearestHalfAway).raw(), 43691);
  EXPECT_EQ(fx_div<Q16>(Q16::from_int(2), Q16::from_int(3), Rounding::kTowardZero).raw(), 43690);
  EXPECT_EQ(fx_div<Q16>(Q16::from_int(-2), Q16::from_int(3), Rounding::kFloor).raw(), -43691);
  EXPECT_EQ(fx_div<Q16>(Q16::max(), Q16::from_raw(1), Rounding::kFloor, &st).raw(), kI32Max);
  EXPECT_EQ(st, FxStatus::kSaturated);
  st = FxStatus::kOk;
  EXPECT_EQ(fx_div<Q16>(Q16::min(), Q16::from_int(-1), Rounding::kFloor, &st).raw(), kI32Max);
  EXPECT_EQ(st, FxStatus::kSaturated);
  st = FxStatus::kOk;
  EXPECT_EQ(fx_div<Q16>(Q16::min(), Q16::from_int(1), Rounding::kFloor, &st).raw(), kI32Min);
  EXPECT_EQ(st, FxStatus::kOk);
  EXPECT_EQ(fx_div<Q16>(Q16::from_int(1), Q16(), Rounding::kFloor, &st).raw(), kI32Max);
  EXPECT_EQ(st, FxStatus::kDivideByZero);
  EXPECT_EQ(fx_div<Q16>(Q16::from_int(-1), Q16(), Rounding::kFloor).raw(), kI32Min);
  // Different formats: Q31 / Q16 -> Q1.30
  EXPECT_EQ(fx_div<Q1_30>(Q31::from_raw(1 << 30), Q16::from_int(2), Rounding::kFloor).raw(), 1 << 28);
}

TEST(FixedArithmetic, ConvertNarrowsWithRoundingAndSaturation) {
  FxStatus st = FxStatus::kOk;
  EXPECT_EQ(fx_convert<Q15>(Q31::from_raw(kI32Max), Rounding::kFloor, &st).raw(), 32767);
  EXPECT_EQ(st, FxStatus::kOk);
  EXPECT_EQ(fx_convert<Q15>(Q31::from_raw(kI32Max), Rounding::kNearestHalfAway, &st).raw(), 32767);
  EXPECT_EQ(st, FxStatus::kSaturated);  // rounds up to +1.0, which Q15 cannot hold
  EXPECT_EQ(fx_convert<Q15>(Q31::from_raw(kI32Min), Rounding::kNearestHalfAway).raw(), -32768);
  EXPECT_EQ(fx_convert<Q15>(Q31::from_raw(-1), Rounding::kFloor).raw(), -1);
  EXPECT_EQ(fx_convert<Q15>(Q31::from_raw(-1), Rounding::kTowardZero).raw(), 0);
  EXPECT_EQ(fx_convert<Q15>(Q31::from_raw(-1), Rounding::kNearestHalfAway).raw(), 0);
  // Widening is exact; Q16.16 -> Q1.30 of a value >= 2 saturates.
  EXPECT_EQ(fx_convert<Q31>(Q15::from_raw(-32768), Rounding::kFloor).raw(), kI32Min);
  st = FxStatus::kOk;
  EXPECT_EQ(fx_convert<Q1_30>(Q16::from_int(2), Rounding::kFloor, &st).raw(), kI32Max);
  EXPECT_EQ(st, FxStatus::kSaturated);
  using Q8_4 = Fixed<int8_t, 4>;
  EXPECT_EQ(fx_convert<Q8_4>(Q16::from_double(-8.0, Rounding::kFloor), Rounding::kFloor).raw(), -128);
  EXPECT_EQ(fx_convert<Q8_4>(Q16::from_double(7.97, Rounding::kFloor), Rounding::kNearestHalfAway).raw(), 127);
}

TEST(FixedArithmetic, AddSubSaturate) {
  FxStatus st = FxStatus::kOk;
  EXPECT_EQ(fx_add(Q16::max(), Q16::from_raw(1), &st).raw(), kI32Max);
  EXPECT_EQ(st, FxStatus::kSaturated);
  st = FxStatus::kOk;
  EXPECT_EQ(fx_sub(Q16::min(), Q16::from_raw(1), &st).raw(), kI32Min);
  EXPECT_EQ(st, FxStatus::kSaturated);
  st = FxStatus::kOk;
  EXPECT_EQ(fx_sub(Q16::from_raw(0), Q16::min(), &st).raw(), kI32Max);  // -INT32_MIN
  EXPECT_EQ(st, FxStatus::kSaturated);
  st = FxStatus::kOk;
  EXPECT_EQ(fx_add(Q16::min(), Q16::max(), &st).raw(), -1);
  EXPECT_EQ(st, FxStatus::kOk);
  EXPECT_TRUE(Q16::from_raw(-1) < Q16());
}

// ---- The 32-bit kernels of the MCU's sample path, against exact 128-bit / long double results ----

TEST(FixedKernels, ProductHighWordRoundedToNearest) {
  std::mt19937 rng(1);
  for (int i = 0; i < 200000; ++i) {
    const uint32_t u = i < 4 ? (i & 1 ? 0xFFFFFFFFu : 0u) : rng(), f = i < 4 ? (i & 2 ? 0xFFFFFFFFu : 1u) : rng();
    const uint64_t p = static_cast<uint64_t>(u) * f;
    ASSERT_EQ(mul_hi_round(u, f), static_cast<uint32_t>((static_cast<unsigned __int128>(p) + 0x80000000u) >> 32));
  }
  EXPECT_EQ(mul_hi_round(0x80000000u, 1), 1u);           // 0.5: ties up
  EXPECT_EQ(mul_hi_round(0x80000000u, 2), 1u);           // 1.0
  EXPECT_EQ(mul_hi_round(0x80000000u, 3), 2u);           // 1.5 -> 2
  EXPECT_EQ(mul_hi_round(0x7FFFFFFFu, 1), 0u);           // just below 0.5
  EXPECT_EQ(mul_hi_round(0xFFFFFFFFu, 0xFFFFFFFFu), 0xFFFFFFFEu);  // 2^32 - 2 + 2^-32
}

TEST(FixedKernels, FractionIsTheRoundedQuotient) {
  std::mt19937 rng(2);
  for (int i = 0; i < 200000; ++i) {
    uint32_t b = rng() | 1u, a = rng();
    if (i % 3 == 0) b >>= rng() % 31;
    if (b == 0) b = 1;
    a %= b;
    const unsigned __int128 n = (static_cast<unsigned __int128>(a) << 32);
    uint64_t exact = static_cast<uint64_t>((n + b / 2) / b);  // ties up: (2r >= b)
    if ((n % b) * 2 == b) exact = static_cast<uint64_t>(n / b) + 1;
    if (exact > 0xFFFFFFFFu) exact = 0xFFFFFFFFu;
    ASSERT_EQ(frac_q32(a, b), exact) << a << " / " << b;
  }
  EXPECT_EQ(frac_q32(0, 7), 0u);
  EXPECT_EQ(frac_q32(1, 2), 0x80000000u);
  EXPECT_EQ(frac_q32(0xFFFFFFFEu, 0xFFFFFFFFu), 0xFFFFFFFFu);  // rounds to 1: saturated
}

TEST(FixedKernels, IntegerSquareRootsAndNormalisation) {
  std::mt19937 rng(3);
  for (int i = 0; i < 200000; ++i) {
    const uint32_t v = i < 3 ? (i == 0 ? 0u : i == 1 ? 0xFFFFFFFFu : 0xFFFE0001u) : rng() >> (rng() % 32);
    const uint32_t r = isqrt32(v);
    ASSERT_LE(static_cast<uint64_t>(r) * r, v);
    ASSERT_GT((static_cast<uint64_t>(r) + 1) * (r + 1), v);
    if (v == 0) continue;
    uint8_t k = 0, ke = 0;
    const uint32_t n = normalize(v, &k);
    ASSERT_EQ(n, v << k);
    ASSERT_GE(n, 0x80000000u);
    const uint32_t e = normalize_even(v, &ke);
    ASSERT_EQ(ke % 2, 0);
    ASSERT_EQ(e, v << ke);
    ASSERT_GE(e, 0x40000000u);
  }
  double worst = 0;
  for (int i = 0; i < 200000; ++i) {
    const uint32_t a = (rng() >> (rng() % 31)) | 1u, b = (rng() >> (rng() % 31)) | 1u;
    const double exact = std::sqrt(double(a) * double(b));
    const uint32_t s = sqrt_mul(a, b);
    if (exact >= 65536) worst = std::max(worst, std::fabs(s - exact) / exact);
    ASSERT_LE(std::fabs(s - exact), exact * 6.2e-5 + 1.0) << a << " " << b;
  }
  std::printf("[fixed] sqrt_mul (16-bit roots of the normalised operands): worst %.2e relative (results >= 2^16)\n", worst);
  EXPECT_LT(worst, 6.2e-5);
}

TEST(FixedKernels, ShiftRoundSaturate) {
  EXPECT_EQ(shift_round_sat(5, 0), 5u);
  EXPECT_EQ(shift_round_sat(5, 2), 20u);
  EXPECT_EQ(shift_round_sat(0x40000000u, 1), 0x80000000u);
  EXPECT_EQ(shift_round_sat(0x40000000u, 2), 0xFFFFFFFFu);  // saturated
  EXPECT_EQ(shift_round_sat(1, 40), 0xFFFFFFFFu);
  EXPECT_EQ(shift_round_sat(0, 40), 0u);
  EXPECT_EQ(shift_round_sat(6, -2), 2u);   // 1.5 -> 2 (ties up)
  EXPECT_EQ(shift_round_sat(5, -2), 1u);   // 1.25
  EXPECT_EQ(shift_round_sat(7, -2), 2u);   // 1.75
  EXPECT_EQ(shift_round_sat(0xFFFFFFFFu, -1), 0x80000000u);
  EXPECT_EQ(shift_round_sat(0xFFFFFFFFu, -31), 2u);
  EXPECT_EQ(shift_round_sat(0xFFFFFFFFu, -32), 1u);  // 0.99999... -> 1
  EXPECT_EQ(shift_round_sat(0xFFFFFFFFu, -33), 0u);  // 0.49999... -> 0
  EXPECT_EQ(shift_round_sat(0xFFFFFFFFu, -40), 0u);
}

}  // namespace
}  // namespace btsm::fx
