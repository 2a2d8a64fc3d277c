// AD7794 ratiometric conversion: unipolar/bipolar coding, gains, calibration, and every error path
// (ERR flag, rails, negative ratio, beyond the gain range, bad config), plus code -> RTD -> degC.
#include "common/ratiometric.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "common/rtd.hpp"

namespace btsm {
namespace {

RatiometricConfig<double> btsm_config() {
  RatiometricConfig<double> c;  // defaults: 6.8 kOhm, gain 4, unipolar
  return c;
}

TEST(Ratiometric, UnipolarFormulaAtKnownCodes) {
  const auto cfg = btsm_config();
  const ChannelCalibration<double> cal;
  // Half scale at gain 4: ratio = 0.5 / 4 = 0.125 -> 850 ohm.
  auto r = code_to_resistance(0x800000, false, cfg, cal);
  ASSERT_TRUE(r.ok());
  EXPECT_DOUBLE_EQ(r.ratio, 0.125);
  EXPECT_DOUBLE_EQ(r.r_ohm, 850.0);
  r = code_to_resistance(1, false, RatiometricConfig<double>{6800.0, 1, false, 0}, cal);
  ASSERT_TRUE(r.ok());
  EXPECT_DOUBLE_EQ(r.ratio, 1.0 / 16777216.0);
}

TEST(Ratiometric, BipolarOffsetBinary) {
  RatiometricConfig<double> cfg = btsm_config();
  cfg.bipolar = true;
  const ChannelCalibration<double> cal;
  auto r = code_to_resistance(0xC00000, false, cfg, cal);  // +half of +FS
  ASSERT_TRUE(r.ok());
  EXPECT_DOUBLE_EQ(r.ratio, 0.5 / 4);
  r = code_to_resistance(0x800000, false, cfg, cal);  // zero volts
  ASSERT_TRUE(r.ok());
  EXPECT_DOUBLE_EQ(r.r_ohm, 0.0);
  r = code_to_resistance(0x7FFFFF, false, cfg, cal);  // just below zero: reversed wiring
  EXPECT_EQ(r.status, RatioStatus::kNegative);
  EXPECT_EQ(r.r_ohm, 0.0);
}

TEST(Ratiometric, Pt1000ThroughTheWholeChainRoundTrips) {
  const auto cfg = btsm_config();
  const ChannelCalibration<double> cal;
  const auto k = iec60751<double>(1000.0);
  for (double t = -40.0; t <= 150.0; t += 0.5) {
    const double r_true = rtd_resistance(k, t).value;
    const uint32_t code = ideal_code(r_true, cfg.r_ref_ohm, cfg.gain, cfg.bipolar);
    const auto r = code_to_resistance(code, false, cfg, cal);
    ASSERT_TRUE(r.ok()) << t;
    // One code = 6800 / 4 / 2^24 = 1.0e-4 ohm = 2.6e-5 degC: quantisation is negligible.
    EXPECT_NEAR(r.r_ohm, r_true, 0.5 * 6800.0 / 4 / 16777216.0 + 1e-9);
    EXPECT_NEAR(rtd_temperature(k, r.r_ohm).value, t, 3e-5);
  }
}

TEST(Ratiometric, FloatPathMatchesDouble) {
  RatiometricConfig<float> cf;
  const ChannelCalibration<float> calf;
  const auto cd = btsm_config();
  const ChannelCalibration<double> cald;
  double worst = 0;
  for (uint32_t code = 0x100000; code < 0xF00000; code += 997) {
    const auto f = code_to_resistance(code, false, cf, calf);
    const auto d = code_to_resistance(code, false, cd, cald);
    ASSERT_EQ(f.ok(), d.ok());
    if (f.ok()) worst = std::max(worst, std::fabs(double(f.r_ohm) - d.r_ohm));
  }
  EXPECT_LT(worst, 2e-4);  // float ulp of R near 1700 ohm is 1.2e-4
}

// The MCU's fixed-point path: R_ref from milliohms to ohm x 2^16 rounded to nearest, and
// R = R_ref code / (2^24 G) as one 32x32 product, exactly round(R_ref_q16 code / 2^(24 + log2 G))
// for every gain, whole-range codes and R_ref over the configuration range.
TEST(RatiometricFixed, ReferenceFromMilliohmIsRoundedToNearest) {
  for (uint32_t mohm : {1000000u, 1000001u, 4999999u, 6800000u, 6800062u, 12345678u, 20000000u, 65535999u})
    EXPECT_EQ(ohm_q16_from_milliohm(mohm), static_cast<uint32_t>(std::llround(mohm * 65536.0 / 1000.0))) << mohm;
  std::mt19937 rng(5);
  for (int i = 0; i < 100000; ++i) {
    const uint32_t mohm = 1000000u + rng() % 19000001u;
    ASSERT_EQ(ohm_q16_from_milliohm(mohm), static_cast<uint32_t>(std::llround(mohm * 65536.0 / 1000.0))) << mohm;
  }
}

TEST(RatiometricFixed, ResistanceIsTheExactQuotientRoundedOnce) {
  std::mt19937 rng(9);
  for (uint8_t g = 0; g <= 7; ++g) {
    for (int i = 0; i < 20000; ++i) {
      const uint32_t code = i == 0 ? 0xFFFFFFu : i == 1 ? 1u : rng() & 0xFFFFFFu;
      const uint32_t r_ref_q16 = ohm_q16_from_milliohm(1000000u + rng() % 19000001u);
      const unsigned __int128 p = static_cast<unsigned __int128>(code) * r_ref_q16;
      const int shift = 24 + g;
      const uint64_t exact = static_cast<uint64_t>((p + (static_cast<unsigned __int128>(1) << (shift - 1))) >> shift);
      ASSERT_EQ(code_to_ohm_q16(code, g, r_ref_q16), exact) << "gain 2^" << int(g) << " code " << code;
    }
  }
  // Against the double path at the module's settings: half an LSB of 2^-16 ohm plus R_ref's rounding.
  const auto cd = btsm_config();
  const ChannelCalibration<double> cald;
  const uint32_t rq = ohm_q16_from_milliohm(6800000u);
  double worst = 0;
  for (uint32_t code = 0x100000; code < 0xF00000; code += 997) {
    const auto d = code_to_resistance(code, false, cd, cald);
    ASSERT_TRUE(d.ok());
    worst = std::max(worst, std::fabs(code_to_ohm_q16(code, 2, rq) / 65536.0 - d.r_ohm));
  }
  std::printf("[ratiometric] fixed point (ohm x 2^16) vs double: worst %.2e ohm\n", worst);
  EXPECT_LT(worst, 1.0 / 65536);  // float path: 2e-4 ohm
}

TEST(Ratiometric, CalibrationCorrectsOffsetAndGain) {
  const auto cfg = btsm_config();
  // A channel that reads 200 codes high at zero and 0.3 % low in span.
  auto read = [&](double r_ohm) {
    const double ratio = r_ohm / cfg.r_ref_ohm * cfg.gain * 0.997;
    return static_cast<uint32_t>(std::lround(ratio * 16777216.0 + 200.0));
  };
  ChannelCalibration<double> cal;
  const double raw_zero = raw_ratio<double>(read(0.0), cfg.gain, false);
  const double raw_known = raw_ratio<double>(read(1000.0), cfg.gain, false);
  ASSERT_TRUE(make_calibration(raw_zero, raw_known, 1000.0, cfg.r_ref_ohm, cal));
  for (double r_ohm : {800.0, 1000.0, 1385.055, 1573.0}) {
    const auto r = code_to_resistance(read(r_ohm), false, cfg, cal);
    ASSERT_TRUE(r.ok());
    EXPECT_NEAR(r.r_ohm, r_ohm, 2e-3) << r_ohm;
  }
  ChannelCalibration<double> untouched;
  EXPECT_FALSE(make_calibration(raw_known, raw_zero, 1000.0, 6800.0, untouched));  // span <= 0
  EXPECT_FALSE(make_calibration(raw_zero, raw_known, 0.0, 6800.0, untouched));
  EXPECT_DOUBLE_EQ(untouched.gain_correction, 1.0);
}

TEST(Ratiometric, ErrorFlagAndRailsAreErrors) {
  const auto cfg = btsm_config();
  const ChannelCalibration<double> cal;
  EXPECT_EQ(code_to_resistance(0x400000, true, cfg, cal).status, RatioStatus::kAdcError);
  EXPECT_EQ(code_to_resistance(0, false, cfg, cal).status, RatioStatus::kRailLow);
  EXPECT_EQ(code_to_resistance(0xFFFFFF, false, cfg, cal).status, RatioStatus::kRailHigh);
  EXPECT_TRUE(code_to_resistance(0xFFFFFE, false, cfg, cal).ok());  // one code below the rail: valid
  EXPECT_TRUE(code_to_resistance(1, false, cfg, cal).ok());
  RatiometricConfig<double> margin = cfg;
  margin.rail_margin_codes = 16;
  EXPECT_EQ(code_to_resistance(16, false, margin, cal).status, RatioStatus::kRailLow);
  EXPECT_EQ(code_to_resistance(0xFFFFEF, false, margin, cal).status, RatioStatus::kRailHigh);
  EXPECT_EQ(code_to_resistance(0x1000000, false, cfg, cal).status, RatioStatus::kBadCode);
  const auto r = code_to_resistance(0xFFFFFF, false, cfg, cal);
  EXPECT_EQ(r.r_ohm, 0.0);  // never a plausible number
}

TEST(Ratiometric, RatioBeyondTheGainRangeIsAnError) {
  const auto cfg = btsm_config();
  ChannelCalibration<double> cal;
  cal.gain_correction = 1.5;  // a calibration that pushes a high reading past full scale
  EXPECT_EQ(code_to_resistance(0xE00000, false, cfg, cal).status, RatioStatus::kBeyondGainRange);
  cal.gain_correction = 1.0;
  cal.offset_ratio = 0.01;  // reading below the calibrated zero
  EXPECT_EQ(code_to_resistance(0x020000, false, cfg, cal).status, RatioStatus::kBeyondGainRange);
}

TEST(Ratiometric, BadConfigurationIsAnError) {
  const ChannelCalibration<double> cal;
  for (uint8_t g : {0, 3, 5, 6, 7, 9, 255})
    EXPECT_EQ(code_to_resistance(0x400000, false, RatiometricConfig<double>{6800.0, g, false, 0}, cal).status,
              RatioStatus::kBadConfig)
        << int(g);
  for (uint8_t g : {1, 2, 4, 8, 16, 32, 64, 128}) EXPECT_TRUE(valid_adc_gain(g)) << int(g);
  EXPECT_EQ(code_to_resistance(0x400000, false, RatiometricConfig<double>{0.0, 4, false, 0}, cal).status,
            RatioStatus::kBadConfig);
  ChannelCalibration<double> bad;
  bad.gain_correction = NAN;
  EXPECT_EQ(code_to_resistance(0x400000, false, btsm_config(), bad).status, RatioStatus::kBadConfig);
}

TEST(Ratiometric, IdealCodeClampsLikeTheAdc) {
  EXPECT_EQ(ideal_code(1e9, 6800.0, 4, false), kAdcFullScaleCode);  // open probe
  EXPECT_EQ(ideal_code(-5.0, 6800.0, 4, false), 0u);
  EXPECT_EQ(ideal_code(0.0, 6800.0, 4, true), kAdcMidScaleCode);
  EXPECT_EQ(ideal_code(850.0, 6800.0, 4, false), 0x800000u);
}

}  // namespace
}  // namespace btsm
