// Reduced-model blob: layout, codec round trip, fault injection at every byte, validation of every
// rule, quantisation errors, and the fixed-point evaluation against the double reference.
#include "common/reduced_model.hpp"

#include <gtest/gtest.h>

#include <random>

#include <cmath>
#include <cstdio>
#include <vector>

#include "spindle_model_fixture.hpp"

namespace btsm {
namespace {

using test::spindle_model;

ReducedModel quantized_spindle() {
  ReducedModel m;
  const ModelCheck c = quantize(spindle_model(), m);
  EXPECT_TRUE(c.ok()) << model_status_name(c.status);
  return m;
}

std::vector<uint8_t> blob_of(const ReducedModel& m) {
  std::vector<uint8_t> b(kReducedModelBlobSize);
  encode(m, b.data());
  return b;
}

// Re-seal a blob after editing it so the content checks (not the CRC) are what is tested.
void reseal(std::vector<uint8_t>& b) { put_le32(b.data() + kBlobOffCrc, crc32(b.data(), kBlobOffCrc)); }

TEST(ReducedModelBlob, SizeFitsTwoSlotsInEeprom) {
  EXPECT_EQ(kReducedModelBlobSize, 464u);
  EXPECT_LE(2 * kReducedModelBlobSize, 1024u - 96u);  // leaves >= 96 B for slot headers + config
}

TEST(ReducedModelBlob, LayoutIsLittleEndianWithMagicAndCrcLast) {
  const ReducedModel m = quantized_spindle();
  const std::vector<uint8_t> b = blob_of(m);
  EXPECT_EQ(b[0], 'B');
  EXPECT_EQ(b[1], 'T');
  EXPECT_EQ(b[2], 'R');
  EXPECT_EQ(b[3], 'M');
  EXPECT_EQ(b[kBlobOffVersion], 1);
  EXPECT_EQ(b[kBlobOffBreakpointCount], 5);
  EXPECT_EQ(b[kBlobOffAmbientChannel], 3);
  EXPECT_EQ(b[kBlobOffEnabledMask], 0x1F);
  EXPECT_EQ(get_le16(&b[kBlobOffDtMs]), 5000);
  EXPECT_EQ(get_le16(&b[kBlobOffSpeeds + 2 * 4]), 8000);
  // a of breakpoint 3 = exp(-3.67e-4 * 5) in Q1.30, little-endian.
  const int32_t a3 = static_cast<int32_t>(get_le32(&b[kBlobOffBreakpoints + 3 * kBlobBreakpointSize]));
  EXPECT_EQ(a3, static_cast<int32_t>(std::lround(std::exp(-3.67e-4 * 5.0) * (1 << 30))));
  EXPECT_EQ(get_le16(&b[kBlobOffWarnBands]), 1500);
  EXPECT_EQ(get_le16(&b[kBlobOffAlarmBands + 2]), 4000);
  EXPECT_EQ(static_cast<int32_t>(get_le32(&b[kBlobOffAbsLimits + 4 * 4])), 70000);
  EXPECT_EQ(get_le16(&b[kBlobOffMaxRise]), 3000);
  EXPECT_EQ(get_le32(&b[kBlobOffCrc]), crc32(b.data(), kBlobOffCrc));
  EXPECT_EQ(blob_stored_crc(b.data()), get_le32(&b[460]));
}

TEST(ReducedModelBlob, RoundTripIsExact) {
  const ReducedModel m = quantized_spindle();
  const std::vector<uint8_t> b = blob_of(m);
  ReducedModel back;
  const ModelCheck c = decode(b.data(), b.size(), back);
  ASSERT_TRUE(c.ok()) << model_status_name(c.status);
  EXPECT_EQ(blob_of(back), b);
  EXPECT_EQ(back.bp[2].b_q24, m.bp[2].b_q24);
  EXPECT_EQ(back.limits[2].abs_limit_mK, 70000);
}

TEST(ReducedModelBlob, EveryByteCorruptionIsRejectedByCrc) {
  const std::vector<uint8_t> good = blob_of(quantized_spindle());
  for (size_t i = 0; i < good.size(); ++i) {
    for (uint8_t flip : {0x01, 0x80, 0xFF}) {
      std::vector<uint8_t> b = good;
      b[i] ^= flip;
      ReducedModel out;
      const ModelCheck c = decode(b.data(), b.size(), out);
      EXPECT_EQ(c.status, ModelStatus::kBadCrc) << "byte " << i << " flip " << int(flip);
      EXPECT_EQ(model_status_class(c.status), ModelStatusClass::kCrc);
    }
  }
}

TEST(ReducedModelBlob, WrongLengthsAreRejected) {
  const std::vector<uint8_t> good = blob_of(quantized_spindle());
  ReducedModel out;
  for (size_t len = 0; len < good.size(); ++len)
    EXPECT_EQ(decode(good.data(), len, out).status, ModelStatus::kBadLength) << len;
  std::vector<uint8_t> longer = good;
  longer.push_back(0);
  EXPECT_EQ(decode(longer.data(), longer.size(), out).status, ModelStatus::kBadLength);
  EXPECT_EQ(decode(nullptr, kReducedModelBlobSize, out).status, ModelStatus::kBadLength);
}

TEST(ReducedModelBlob, DecodeLeavesOutputUntouchedOnError) {
  std::vector<uint8_t> b = blob_of(quantized_spindle());
  b[kBlobOffVersion] = 2;
  reseal(b);
  ReducedModel out;
  memset(&out, 0xA5, sizeof(out));
  EXPECT_EQ(decode(b.data(), b.size(), out).status, ModelStatus::kBadVersion);
  EXPECT_EQ(out.n_breakpoints, 0xA5);
}

struct Edit {
  const char* what;
  void (*apply)(std::vector<uint8_t>&);
  ModelStatus expected;
  uint8_t breakpoint;
  uint8_t channel;
};

void set32(std::vector<uint8_t>& b, size_t off, int32_t v) { put_le32(&b[off], static_cast<uint32_t>(v)); }
size_t bp_off(int i, int field) { return kBlobOffBreakpoints + kBlobBreakpointSize * i + 4 * field; }

TEST(ReducedModelBlob, EveryContentRuleIsEnforcedWithLocation) {
  const Edit edits[] = {
      {"magic", [](std::vector<uint8_t>& b) { b[0] = 'X'; }, ModelStatus::kBadMagic, 0xFF, 0xFF},
      {"version", [](std::vector<uint8_t>& b) { b[kBlobOffVersion] = 0; }, ModelStatus::kBadVersion, 0xFF, 0xFF},
      {"n=1", [](std::vector<uint8_t>& b) { b[kBlobOffBreakpointCount] = 1; }, ModelStatus::kBadBreakpointCount, 0xFF, 0xFF},
      {"n=9", [](std::vector<uint8_t>& b) { b[kBlobOffBreakpointCount] = 9; }, ModelStatus::kBadBreakpointCount, 0xFF, 0xFF},
      {"dt=99", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffDtMs], 99); }, ModelStatus::kBadDt, 0xFF, 0xFF},
      {"dt=60001", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffDtMs], 60001); }, ModelStatus::kBadDt, 0xFF, 0xFF},
      {"mask bit 5", [](std::vector<uint8_t>& b) { b[kBlobOffEnabledMask] = 0x3F; }, ModelStatus::kBadChannelMask, 0xFF, 0xFF},
      {"mask empty", [](std::vector<uint8_t>& b) { b[kBlobOffEnabledMask] = 0; }, ModelStatus::kBadChannelMask, 0xFF, 0xFF},
      {"ambient 5", [](std::vector<uint8_t>& b) { b[kBlobOffAmbientChannel] = 5; }, ModelStatus::kBadAmbientChannel, 0xFF, 0xFF},
      {"ambient disabled", [](std::vector<uint8_t>& b) { b[kBlobOffEnabledMask] = 0x17; }, ModelStatus::kBadAmbientChannel, 0xFF, 0xFF},
      {"speed0 != 0", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffSpeeds], 10); }, ModelStatus::kBadSpeeds, 0, 0xFF},
      {"speeds not ascending", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffSpeeds + 6], 4000); }, ModelStatus::kBadSpeeds, 3, 0xFF},
      {"unused speed", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffSpeeds + 12], 9000); }, ModelStatus::kBadSpeeds, 6, 0xFF},
      {"a = 1", [](std::vector<uint8_t>& b) { set32(b, bp_off(2, 0), 1 << 30); }, ModelStatus::kUnstablePole, 2, 0xFF},
      {"a = -1", [](std::vector<uint8_t>& b) { set32(b, bp_off(1, 0), -(1 << 30)); }, ModelStatus::kUnstablePole, 1, 0xFF},
      {"b at 0 rpm", [](std::vector<uint8_t>& b) { set32(b, bp_off(0, 1), 5); }, ModelStatus::kInputAtStandstill, 0, 0xFF},
      {"d at 0 rpm", [](std::vector<uint8_t>& b) { set32(b, bp_off(0, 7 + 4), 5); }, ModelStatus::kInputAtStandstill, 0, 0xFF},
      // b = 100 K/step with a = 0.998 -> x_ss = 50000 K
      {"x_ss huge", [](std::vector<uint8_t>& b) { set32(b, bp_off(4, 1), 100 << 24); }, ModelStatus::kSteadyStateOutOfRange, 4, 0xFF},
      // c = 127 with x_ss = 20 K -> 2540 K
      {"c huge", [](std::vector<uint8_t>& b) { set32(b, bp_off(4, 2 + 1), 127 << 24); }, ModelStatus::kGainOutOfRange, 4, 1},
      {"unused slot", [](std::vector<uint8_t>& b) { set32(b, bp_off(7, 3), 1); }, ModelStatus::kUnusedNotZero, 7, 0xFF},
      {"warn 0", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffWarnBands + 2], 0); }, ModelStatus::kBadBands, 0xFF, 1},
      {"alarm <= warn", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffAlarmBands + 8], 1500); }, ModelStatus::kBadBands, 0xFF, 4},
      {"limit 851 C", [](std::vector<uint8_t>& b) { set32(b, kBlobOffAbsLimits + 8, 851000); }, ModelStatus::kLimitOutOfRange, 0xFF, 2},
      {"limit -201 C", [](std::vector<uint8_t>& b) { set32(b, kBlobOffAbsLimits, -201000); }, ModelStatus::kLimitOutOfRange, 0xFF, 0},
  };
  const std::vector<uint8_t> good = blob_of(quantized_spindle());
  for (const Edit& e : edits) {
    std::vector<uint8_t> b = good;
    e.apply(b);
    reseal(b);
    ReducedModel out;
    const ModelCheck c = decode(b.data(), b.size(), out);
    EXPECT_EQ(c.status, e.expected) << e.what << ": got " << model_status_name(c.status);
    EXPECT_EQ(c.breakpoint, e.breakpoint) << e.what;
    EXPECT_EQ(c.channel, e.channel) << e.what;
    EXPECT_EQ(model_status_class(c.status),
              e.expected == ModelStatus::kBadVersion ? ModelStatusClass::kVersion : ModelStatusClass::kInvalid)
        << e.what;
  }
}

TEST(ReducedModelBlob, AmbientChannelNeedsNoBandsAndDisabledChannelsNoLimits) {
  ReducedModelF64 f = spindle_model();
  f.warn_band_k[3] = 0.0;   // ambient: no residual, bands unused
  f.alarm_band_k[3] = 0.0;
  f.enabled_mask = 0x0F;    // spare channel disabled: its limits are not checked
  f.abs_limit_c[4] = 5000.0;
  ReducedModel m;
  EXPECT_TRUE(quantize(f, m).ok());
  f.ambient_channel = kModelAmbientNone;
  EXPECT_EQ(quantize(f, m).status, ModelStatus::kBadBands);  // channel 3 is now a probe
}

TEST(ReducedModelBlob, DetailPacksStatusAndLocation) {
  const ModelCheck c = model_check(ModelStatus::kUnstablePole, 2);
  EXPECT_EQ(c.detail(), 0x0209);
  EXPECT_EQ(model_check(ModelStatus::kBadBands, 0xFF, 4).detail(), 0x040F);
}

TEST(ReducedModelQuantize, RejectsValuesThatDoNotFitWithLocation) {
  struct Case {
    const char* what;
    void (*apply)(ReducedModelF64&);
    ModelStatus expected;
    uint8_t bp, ch;
  };
  const Case cases[] = {
      {"NaN a", [](ReducedModelF64& f) { f.a[2] = NAN; }, ModelStatus::kNotFinite, 2, 0xFF},
      {"inf c", [](ReducedModelF64& f) { f.c[1][4] = INFINITY; }, ModelStatus::kNotFinite, 1, 4},
      {"a = 1", [](ReducedModelF64& f) { f.a[3] = 1.0; }, ModelStatus::kUnstablePole, 3, 0xFF},
      {"a = 1 - 1e-12 rounds to 1", [](ReducedModelF64& f) { f.a[3] = 1.0 - 1e-12; }, ModelStatus::kUnstablePole, 3, 0xFF},
      {"b = 128", [](ReducedModelF64& f) { f.b[1] = 128.0; }, ModelStatus::kGainOutOfRange, 1, 0xFF},
      {"d = -200", [](ReducedModelF64& f) { f.d[2][0] = -200.0; }, ModelStatus::kGainOutOfRange, 2, 0},
      {"n = 9", [](ReducedModelF64& f) { f.n_breakpoints = 9; }, ModelStatus::kBadBreakpointCount, 0xFF, 0xFF},
      {"warn 70 K", [](ReducedModelF64& f) { f.warn_band_k[0] = 70.0; }, ModelStatus::kLimitOutOfRange, 0xFF, 0},
      {"rise NaN", [](ReducedModelF64& f) { f.max_rise_k_per_min[2] = NAN; }, ModelStatus::kLimitOutOfRange, 0xFF, 2},
      {"limit 900 C", [](ReducedModelF64& f) { f.abs_limit_c[1] = 900.0; }, ModelStatus::kLimitOutOfRange, 0xFF, 1},
  };
  for (const Case& k : cases) {
    ReducedModelF64 f = spindle_model();
    k.apply(f);
    ReducedModel m;
    const ModelCheck c = quantize(f, m);
    EXPECT_EQ(c.status, k.expected) << k.what << ": got " << model_status_name(c.status);
    EXPECT_EQ(c.breakpoint, k.bp) << k.what;
    EXPECT_EQ(c.channel, k.ch) << k.what;
  }
}

// The evaluation primitives (32-bit interpolation, one-add rounding shift) are bit-identical to
// forming the products in int64 and rounding with fx::shift_right_round.
TEST(ReducedModelEval, FastPrimitivesMatchTheInt64Reference) {
  std::mt19937_64 g(5);
  for (int i = 0; i < 2000000; ++i) {
    int32_t p0 = static_cast<int32_t>(g()), p1 = static_cast<int32_t>(g());
    uint16_t f = static_cast<uint16_t>(g());
    if (i % 4 == 0) p1 = static_cast<int32_t>(static_cast<int64_t>(p0) + static_cast<int64_t>(g() % 2001) - 1000);
    if (i % 8 == 1) f = (g() % 2) ? 0x8000 : 1;
    if (i % 16 == 3) {  // exact ties (odd difference, f = 1/2), both signs
      p0 /= 2;
      p1 = p0 + 2 * static_cast<int32_t>(g() % 5) - 5;
      f = 0x8000;
    }
    const int64_t d = static_cast<int64_t>(p1) - p0;
    const int32_t ref = static_cast<int32_t>(p0 + fx::shift_right_round(d * f, kSpeedFracBits, fx::Rounding::kNearestHalfAway));
    ASSERT_EQ(detail_rm::lerp_q(p0, p1, f), ref) << p0 << " " << p1 << " " << f;
  }
  for (int i = 0; i < 2000000; ++i) {
    int s = 1 + static_cast<int>(g() % 61);
    int64_t v = static_cast<int64_t>(g()) / (static_cast<int64_t>(2) << (g() % 40));
    if (i % 3 == 0) {  // ties and near-ties
      s = 1 + static_cast<int>(g() % 50);
      v = (static_cast<int64_t>(g() % 1000) - 500) * fx::pow2(s - 1) + static_cast<int64_t>(g() % 3) - 1;
    }
    ASSERT_EQ(detail_rm::round_shift(v, s), fx::shift_right_round(v, s, fx::Rounding::kNearestHalfAway))
        << v << " >> " << s;
  }
}

// The int64 form of step_with (every product formed exactly in int64 and rounded once with
// fx::shift_right_round), which the firmware used before the 32-bit-word evaluation.
void step_with_int64(const ModelBreakpoint& p, bool running, uint8_t ambient_channel, uint8_t enabled_mask,
                     ReducedModelState& st, int32_t ambient_mK, int32_t predicted_mK[kModelChannels]) {
  const auto rs = [](int64_t v, int s) { return fx::shift_right_round(v, s, fx::Rounding::kNearestHalfAway); };
  const int32_t x = st.x_q20;
  for (uint8_t j = 0; j < kModelChannels; ++j) {
    // Which channels are predicted is not what this reference checks: the arithmetic below is.
    if (detail_rm::unmodelled_channel(j, static_cast<uint8_t>(1U << j), enabled_mask, ambient_channel, ambient_mK,
                                      predicted_mK[j]))
      continue;
    int64_t theta_q44 = static_cast<int64_t>(p.c_q24[j]) * x;
    if (running) theta_q44 += static_cast<int64_t>(p.d_q24[j]) * fx::pow2(kStateFracBits);
    const int64_t theta_mK = rs(rs(theta_q44, kGainFracBits) * 1000, kStateFracBits);
    int64_t v = static_cast<int64_t>(ambient_mK) + theta_mK;
    if (v > kInt24Max) v = kInt24Max;
    if (v <= kModelNoPrediction) v = kModelNoPrediction + 1;
    predicted_mK[j] = static_cast<int32_t>(v);
  }
  int64_t acc_q50 = static_cast<int64_t>(p.a_q30) * x;
  if (running) acc_q50 += static_cast<int64_t>(p.b_q24) * fx::pow2(kPoleFracBits + kStateFracBits - kGainFracBits);
  st.x_q20 = fx::saturate<int32_t>(rs(acc_q50, kPoleFracBits));
}

// The 32-bit-word evaluation (detail_rm::Wide, byte-move shifts) is bit-identical to the int64
// form: random coefficients and states over the whole int32 range (including saturation of the
// state), plus values near the rounding ties -- except that a channel with |c x| >= 1024 K
// saturates at the end of the wire's range instead.
TEST(ReducedModelEval, StepWithMatchesTheInt64Form) {
  std::mt19937_64 g(17);
  const auto any32 = [&] { return static_cast<int32_t>(g()); };
  const auto scaled = [&] { return static_cast<int32_t>(static_cast<int64_t>(any32()) >> (g() % 31)); };
  int saturated = 0;
  for (int i = 0; i < 300000; ++i) {
    ModelBreakpoint p;
    p.a_q30 = (i % 2) ? scaled() : static_cast<int32_t>((1 << 30) - 1 - static_cast<int32_t>(g() % 5000000));
    p.b_q24 = scaled();
    for (int j = 0; j < kModelChannels; ++j) {
      p.c_q24[j] = (i % 3 == 0) ? any32() : scaled();
      p.d_q24[j] = scaled();
    }
    ReducedModelState a, b;
    a.x_q20 = b.x_q20 = (i % 5 == 0) ? any32() : scaled();
    if (i % 7 == 0) {  // products on (or next to) a rounding tie of the 2^24 and 2^30 shifts
      p.c_q24[1] = 1 << (g() % 8);
      a.x_q20 = b.x_q20 = static_cast<int32_t>((static_cast<int64_t>(g() % 2001) - 1000) * (1 << 16) + (g() % 3) - 1);
      p.a_q30 = 1 << 14;
    }
    const bool running = (g() & 1) != 0;
    const uint8_t ambient_ch = static_cast<uint8_t>(g() % 6);
    const uint8_t mask = static_cast<uint8_t>(g() % 32 | (i % 4 ? 0x1F : 0));
    const int32_t ambient = (i % 11 == 0) ? kModelNoPrediction : static_cast<int32_t>(static_cast<int64_t>(any32()) >> 9);
    int32_t pa[kModelChannels], pb[kModelChannels];
    const int32_t x0 = a.x_q20;
    step_with(p, running, ambient_ch, mask, a, ambient, pa);
    step_with_int64(p, running, ambient_ch, mask, b, ambient, pb);
    ASSERT_EQ(a.x_q20, b.x_q20) << i;
    for (int j = 0; j < kModelChannels; ++j) {
      const int64_t cx = static_cast<int64_t>(p.c_q24[j]) * x0;
      const bool beyond = cx >= (static_cast<int64_t>(1) << 54) || cx < -(static_cast<int64_t>(1) << 54);
      if (beyond && pb[j] != kModelNoPrediction && j != ambient_ch) {
        ASSERT_EQ(pa[j], cx < 0 ? kModelNoPrediction + 1 : kInt24Max) << i << " ch " << j;
        ++saturated;
      } else {
        ASSERT_EQ(pa[j], pb[j]) << i << " ch " << j;
      }
    }
  }
  EXPECT_GT(saturated, 1000);
}

TEST(ReducedModelEval, InterpolationFractionAndSegments) {
  const ReducedModel m = quantized_spindle();
  SpeedSegment s = find_segment(m.speed_rpm, m.n_breakpoints, 0);
  EXPECT_FALSE(s.running);
  EXPECT_EQ(s.lo, 0);
  s = find_segment(m.speed_rpm, m.n_breakpoints, 5000);
  EXPECT_TRUE(s.running);
  EXPECT_EQ(s.lo, 2);
  EXPECT_EQ(s.hi, 3);
  EXPECT_EQ(s.frac_q16, 32768);
  s = find_segment(m.speed_rpm, m.n_breakpoints, 6000);  // exactly on a breakpoint
  EXPECT_EQ(s.lo, 3);
  EXPECT_EQ(s.frac_q16, 0);
  s = find_segment(m.speed_rpm, m.n_breakpoints, 12000);  // above the last: held
  EXPECT_EQ(s.lo, 4);
  EXPECT_EQ(s.hi, 4);
  s = find_segment(m.speed_rpm, m.n_breakpoints, 1);  // between standstill and the first speed
  EXPECT_TRUE(s.running);
  EXPECT_EQ(s.lo, 0);
  EXPECT_EQ(s.frac_q16, 32);  // floor(65536 / 2000)
  ModelBreakpoint p;
  interpolate(m.bp[2], m.bp[3], 32768, p);
  EXPECT_NEAR(p.a_q30, (static_cast<int64_t>(m.bp[2].a_q30) + m.bp[3].a_q30) / 2, 1);
}

// The 16-step division of the interpolation fraction is the exact floor(n 2^16 / d) for n < d.
TEST(ReducedModelEval, FractionDivisionIsExact) {
  std::mt19937_64 g(11);
  for (int i = 0; i < 1000000; ++i) {
    const uint16_t d = static_cast<uint16_t>(1 + g() % 65535);
    uint16_t n = static_cast<uint16_t>(g() % d);
    if (i % 4 == 0) n = static_cast<uint16_t>(d - 1 - g() % 3 % d);  // fractions close to 1
    ASSERT_EQ(detail_rm::fraction_q16(n, d), (static_cast<uint32_t>(n) << 16) / d) << n << " / " << d;
  }
}

TEST(ReducedModelEval, SettlesToSteadyStateAtABreakpoint) {
  const ReducedModel m = quantized_spindle();
  ReducedModelState st;
  reset(st);
  int32_t pred[kModelChannels];
  for (int k = 0; k < 17280; ++k) step(m, st, 8000, 20000, pred);  // 24 h, 40 time constants
  // front bearing: ambient + c x_ss + d = 20 + 20 + 0.8 K
  EXPECT_NEAR(pred[2], 20000 + 20000 + 800, 1);
  EXPECT_EQ(pred[3], 20000);  // ambient channel predicts ambient
  // Rounding dead band of x' = a x + b: the update stops once (1-a)|x_ss - x| < 0.5 LSB, i.e.
  // |x_ss - x| < 0.5 * 2^-20 / (1 - a) = 2.4e-4 K at a = exp(-4.05e-4 * 5).
  const double dead_band = 0.5 / (1 << 20) / (1.0 - std::exp(-4.05e-4 * 5.0));
  EXPECT_NEAR(static_cast<double>(st.x_q20) / (1 << 20), 20.0, dead_band + 1e-6);
}

TEST(ReducedModelEval, DisabledChannelAndMissingAmbientGiveNoPrediction) {
  ReducedModelF64 f = spindle_model();
  f.enabled_mask = 0x0F;
  ReducedModel m;
  ASSERT_TRUE(quantize(f, m).ok());
  ReducedModelState st;
  reset(st);
  int32_t pred[kModelChannels];
  step(m, st, 6000, 21000, pred);
  EXPECT_EQ(pred[4], kModelNoPrediction);
  EXPECT_NE(pred[0], kModelNoPrediction);
  const int32_t x_before = st.x_q20;
  step(m, st, 6000, kModelNoPrediction, pred);
  for (int j = 0; j < 5; ++j) EXPECT_EQ(pred[j], kModelNoPrediction) << j;
  EXPECT_GT(st.x_q20, x_before);  // the state keeps integrating: it is relative to ambient
}

TEST(ReducedModelEval, InitFromMeasurementRecoversTheState) {
  const ReducedModel m = quantized_spindle();
  ReducedModelState truth;
  reset(truth);
  int32_t pred[kModelChannels];
  for (int k = 0; k < 700; ++k) step(m, truth, 6000, 22000, pred);
  // pred now holds the prediction for x before the last update; rebuild it for the current state.
  ReducedModelState probe = truth;
  step(m, probe, 6000, 22000, pred);
  ReducedModelState st;
  reset(st);
  ASSERT_TRUE(init_from_measurement(m, st, 6000, 22000, pred));
  EXPECT_NEAR(static_cast<double>(st.x_q20 - truth.x_q20) / (1 << 20), 0.0, 2e-3);
  const int32_t none[kModelChannels] = {kModelNoPrediction, kModelNoPrediction, kModelNoPrediction,
                                        kModelNoPrediction, kModelNoPrediction};
  EXPECT_FALSE(init_from_measurement(m, st, 6000, 22000, none));
}

// 24 h at dt = 5 s (17280 steps) with speed steps across and between breakpoints, stops and a
// slowly varying ambient: the fixed-point prediction must stay within 0.01 K of the double model.
TEST(ReducedModelEval, FixedPointTracksDoubleReferenceOver24Hours) {
  const ReducedModelF64 f = spindle_model();
  ReducedModel m;
  ASSERT_TRUE(quantize(f, m).ok());
  ReducedModelState st;
  reset(st);
  ReducedModelF64State ref;
  const uint16_t profile[] = {6000, 8000, 0, 3000, 10000, 4500, 0, 7999, 1, 2000, 5000, 6543, 0, 8000};
  const int steps = 17280;
  const int segment = steps / static_cast<int>(sizeof(profile) / sizeof(profile[0])) + 1;
  double worst_mk = 0.0, worst_state_k = 0.0, hottest_k = 0.0;
  for (int k = 0; k < steps; ++k) {
    const uint16_t rpm = profile[k / segment];
    const double ambient_c = 20.0 + 3.0 * std::sin(2.0 * M_PI * k / steps);
    const int32_t ambient_mk = static_cast<int32_t>(std::lround(ambient_c * 1000.0));
    int32_t pred[kModelChannels];
    double pred_ref[kModelChannels];
    step(m, st, rpm, ambient_mk, pred);
    step(f, ref, rpm, ambient_mk / 1000.0, pred_ref);
    for (int j = 0; j < kModelChannels; ++j) {
      worst_mk = std::max(worst_mk, std::fabs(pred[j] - pred_ref[j] * 1000.0));
      hottest_k = std::max(hottest_k, pred_ref[j] - ambient_mk / 1000.0);
    }
    worst_state_k = std::max(worst_state_k, std::fabs(st.x_q20 / double(1 << 20) - ref.x));
  }
  std::printf("[reduced model] 24 h, 17280 steps: worst |fixed - double| prediction %.4f mK, "
              "state %.3g K, hottest rise %.2f K\n",
              worst_mk, worst_state_k, hottest_k);
  EXPECT_GT(hottest_k, 15.0);  // the run really heats up
  EXPECT_LE(worst_mk, 10.0);   // contract: <= 0.01 K
  // Honest tighter bound actually met: output rounding to 1 mK (0.5) plus state/coefficient error.
  EXPECT_LE(worst_mk, 1.0);
  EXPECT_LE(worst_state_k, 5e-4);
}

}  // namespace
}  // namespace btsm
