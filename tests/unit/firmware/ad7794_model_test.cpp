// AD7794 register map, driver transactions and the register-level model.
#include <gtest/gtest.h>

#include "boards/sim/ad7794_model.hpp"
#include "firmware/ad7794.hpp"
#include "test_support.hpp"

namespace btsm {
namespace {

struct ModelSpi {
  sim::Ad7794Model& m;
  void select() { m.set_cs(true); }
  void deselect() { m.set_cs(false); }
  uint8_t transfer(uint8_t b) { return m.transfer(b); }
  bool miso_high() { return m.miso_high(); }
};

struct Fixture : ::testing::Test {
  sim::Ad7794ModelOptions opt() {
    sim::Ad7794ModelOptions o;
    o.noise_scale = 0.0;
    return o;
  }
  sim::Ad7794Model model{opt()};
  ModelSpi spi{model};
  Ad7794<ModelSpi> adc{spi};

  // Runs a single conversion on `ch` with the given config bits; returns the data code.
  uint32_t convert(uint16_t config, uint8_t fs = 10) {
    adc.write(ad7794::kRegConfig, config, 2);
    adc.start(ad7794::kModeSingle, fs);
    model.advance(ad7794::settle_ms(fs) / 1000.0 + 1.5e-3);  // + oscillator start from power-down
    EXPECT_TRUE(adc.ready());
    uint8_t status = 0;
    uint32_t code = 0;
    adc.finish_conversion(status, code, 3);
    last_status = status;
    return code;
  }
  uint8_t last_status = 0;
};

TEST(Ad7794Regs, CommandBytesMatchTheDatasheetLayout) {
  EXPECT_EQ(ad7794::comm_write(ad7794::kRegMode), 0x08);
  EXPECT_EQ(ad7794::comm_write(ad7794::kRegConfig), 0x10);
  EXPECT_EQ(ad7794::comm_write(ad7794::kRegIo), 0x28);
  EXPECT_EQ(ad7794::comm_read(ad7794::kRegStatus), 0x40);
  EXPECT_EQ(ad7794::comm_read(ad7794::kRegData), 0x58);
  EXPECT_EQ(ad7794::comm_read(ad7794::kRegId), 0x60);
  EXPECT_EQ(ad7794::comm_read(ad7794::kRegOffset), 0x70);
  EXPECT_EQ(ad7794::comm_read(ad7794::kRegFullScale), 0x78);
  EXPECT_EQ(ad7794::comm_read(ad7794::kRegData) | ad7794::kCommCread, 0x5C);
  const uint8_t widths[8] = {1, 2, 2, 3, 1, 1, 3, 3};
  for (uint8_t r = 0; r < 8; ++r) EXPECT_EQ(ad7794::width(r), widths[r]) << "register " << int(r);
  EXPECT_EQ(ad7794::cal_pair(ad7794::kAin4), ad7794::cal_pair(ad7794::kAin6));
  EXPECT_EQ(ad7794::cal_pair(ad7794::kAin5), 3);
  EXPECT_NE(ad7794::cal_pair(ad7794::kAin3), ad7794::cal_pair(ad7794::kAin4));
  EXPECT_EQ(ad7794::settle_ms(10), 120);
  EXPECT_EQ(ad7794::rate_mhz(15), 4170u);
}

TEST_F(Fixture, PowerOnValuesAndWidths) {
  EXPECT_EQ(adc.read16(ad7794::kRegMode), 0x000A);
  EXPECT_EQ(adc.read16(ad7794::kRegConfig), 0x0710);
  EXPECT_EQ(adc.read8(ad7794::kRegIo), 0x00);
  EXPECT_EQ(adc.read24(ad7794::kRegOffset), 0x800000u);
  EXPECT_EQ(adc.read8(ad7794::kRegId) & 0x0F, 0x0F);
  EXPECT_EQ(adc.read8(ad7794::kRegStatus) & 0x7F, 0x08);  // RDY may be either: continuous mode runs
  EXPECT_EQ(adc.read24(ad7794::kRegFullScale) >> 20, 0x5u);
}

TEST_F(Fixture, ThirtyTwoOnesResetTheChipAndAccessIsIgnoredFor500us) {
  adc.write(ad7794::kRegIo, 0x0E, 1);
  adc.write(ad7794::kRegConfig, 0x1234, 2);
  ASSERT_EQ(adc.read8(ad7794::kRegIo), 0x0E);
  adc.reset();
  EXPECT_EQ(model.counters().resets, 2u);  // power-on + ours
  // Within the 500 us guard time the interface ignores us (reads all ones).
  EXPECT_EQ(adc.read8(ad7794::kRegIo), 0xFF);
  EXPECT_GT(model.counters().access_during_reset, 0u);
  model.advance(600e-6);
  EXPECT_EQ(adc.read8(ad7794::kRegIo), 0x00);
  EXPECT_EQ(adc.read16(ad7794::kRegConfig), 0x0710);
  // 24 ones are not a reset.
  adc.write(ad7794::kRegIo, 0x02, 1);
  spi.select();
  for (int i = 0; i < 3; ++i) spi.transfer(0xFF);
  spi.deselect();
  EXPECT_EQ(adc.read8(ad7794::kRegIo), 0x02);
}

TEST_F(Fixture, IdentifyTellsAd7794FromAd7795AndMissingChip) {
  EXPECT_EQ(adc.identify(), AdcChip::kAd7794);
  sim::Ad7794ModelOptions o = opt();
  o.ad7795 = true;
  sim::Ad7794Model m5(o);
  ModelSpi s5{m5};
  Ad7794<ModelSpi> a5(s5);
  EXPECT_EQ(a5.identify(), AdcChip::kAd7795);
  model.front_end().chip_missing = true;  // MISO stuck high: ID reads 0xFF, whose low nibble is 0xF
  EXPECT_EQ(adc.read8(ad7794::kRegId), 0xFF);
  EXPECT_EQ(adc.identify(), AdcChip::kNone);
  EXPECT_FALSE(adc.ready());
}

TEST_F(Fixture, ConversionTimingFollowsFsAndRdyNeedsChipSelect) {
  adc.write(ad7794::kRegIo, ad7794::io_word(0, ad7794::kIexc210uA), 1);
  adc.write(ad7794::kRegConfig, 0x1230, 2);  // unipolar, gain 4, REF_DET, BUF, AIN1
  adc.start(ad7794::kModeSingle, 10);
  model.advance(0.119);
  EXPECT_FALSE(adc.ready());
  model.advance(0.002);
  EXPECT_TRUE(adc.ready());
  spi.deselect();
  EXPECT_FALSE(model.rdy_low()) << "DOUT/RDY is only driven while CS is low";
  spi.select();
  uint8_t status;
  uint32_t code;
  adc.finish_conversion(status, code, 3);
  EXPECT_EQ(status & 0x80, 0);
  // Single conversion returns the chip to power-down.
  EXPECT_EQ(ad7794::mode_of(adc.read16(ad7794::kRegMode)), ad7794::kModePowerDown);
  // Faster rate: FS 1 settles in 4 ms.
  adc.start(ad7794::kModeSingle, 1);
  model.advance(0.0035);
  EXPECT_FALSE(adc.ready());
  model.advance(0.002);  // + 1 ms oscillator start after power-down
  EXPECT_TRUE(adc.ready());
  adc.finish();
}

TEST_F(Fixture, UnipolarAndBipolarCodingOfTheRatio) {
  model.front_end().probe_ohm[0] = 1200.0;
  adc.write(ad7794::kRegIo, ad7794::io_word(0, ad7794::kIexc210uA), 1);
  // Calibrate gain 4 so the factory gain-1 trim does not distort the check.
  adc.write(ad7794::kRegConfig, 0x1230, 2);
  adc.start(ad7794::kModeInternalZeroCal, 10);
  model.advance(0.2);
  adc.finish();
  adc.start(ad7794::kModeInternalFullCal, 10);
  model.advance(0.3);
  adc.finish();
  const double ratio = 4.0 * 1200.0 / 6800.0;
  const uint32_t uni = convert(0x1230);
  EXPECT_NEAR(uni / 16777216.0, ratio, 2e-6);
  EXPECT_EQ(last_status & ad7794::kStatusErr, 0);
  const uint32_t bip = convert(0x0230);  // same channel, bipolar (offset binary)
  EXPECT_NEAR((static_cast<double>(bip) - 8388608.0) / 8388608.0, ratio, 1e-3);
  // Over range at gain 8: ratio 1.41 -> clamps to all ones with ERR.
  const uint32_t over = convert(0x1330);
  EXPECT_EQ(over, 0xFFFFFFu);
  EXPECT_NE(last_status & ad7794::kStatusErr, 0);
}

TEST_F(Fixture, CalibrationRegistersAreWritableOnlyInIdleAndAin4To6ShareAPair) {
  adc.write(ad7794::kRegConfig, 0x1233, 2);  // AIN4
  adc.write(ad7794::kRegMode, ad7794::mode_word(ad7794::kModeContinuous, 10), 2);
  adc.write(ad7794::kRegOffset, 0x812345, 3);
  EXPECT_EQ(adc.read24(ad7794::kRegOffset), 0x800000u);
  EXPECT_EQ(model.counters().ignored_cal_writes, 1u);
  adc.write(ad7794::kRegMode, ad7794::mode_word(ad7794::kModeIdle, 10), 2);
  adc.write(ad7794::kRegOffset, 0x812345, 3);
  EXPECT_EQ(adc.read24(ad7794::kRegOffset), 0x812345u);
  adc.write(ad7794::kRegConfig, 0x1234, 2);  // AIN5: same pair
  EXPECT_EQ(adc.read24(ad7794::kRegOffset), 0x812345u);
  adc.write(ad7794::kRegConfig, 0x1235, 2);  // AIN6: same pair
  EXPECT_EQ(adc.read24(ad7794::kRegOffset), 0x812345u);
  adc.write(ad7794::kRegConfig, 0x1232, 2);  // AIN3: its own pair
  EXPECT_EQ(adc.read24(ad7794::kRegOffset), 0x800000u);
}

TEST_F(Fixture, InternalFullScaleCalibrationIsRefusedAtGain128) {
  adc.write(ad7794::kRegIo, ad7794::io_word(0, ad7794::kIexc210uA), 1);
  adc.write(ad7794::kRegConfig, 0x1730, 2);
  const uint32_t before = adc.read24(ad7794::kRegFullScale);
  adc.start(ad7794::kModeInternalFullCal, 10);
  model.advance(0.5);
  adc.finish();
  EXPECT_EQ(adc.read24(ad7794::kRegFullScale), before);
  EXPECT_EQ(model.counters().invalid_calibrations, 1u);
}

TEST_F(Fixture, ReferenceDetectAndExcitationRouting) {
  // Excitation routed away from the chain (IEXC1 -> IOUT2, IEXC2 off? both on IOUT2): no reference.
  adc.write(ad7794::kRegIo, ad7794::io_word(ad7794::kIexcBothIout2, ad7794::kIexc210uA), 1);
  EXPECT_DOUBLE_EQ(model.chain_current_a(), 0.0);
  adc.write(ad7794::kRegMode, ad7794::mode_word(ad7794::kModeIdle, 10), 2);
  EXPECT_DOUBLE_EQ(model.chain_current_a(), 0.0);
  convert(0x1230);
  EXPECT_NE(last_status & ad7794::kStatusNoXref, 0);
  EXPECT_NE(last_status & ad7794::kStatusErr, 0);
  adc.write(ad7794::kRegIo, ad7794::io_word(ad7794::kIexcBothIout1, ad7794::kIexc10uA), 1);
  adc.write(ad7794::kRegMode, ad7794::mode_word(ad7794::kModeIdle, 10), 2);
  EXPECT_NEAR(model.chain_current_a(), 20e-6, 1e-12);  // both 10 uA sources on IOUT1
  adc.write(ad7794::kRegIo, ad7794::io_word(0, ad7794::kIexc1mA), 1);
  // 1 mA through the 11.8 kOhm chain would need 11.8 V: the source saturates at AVDD - 0.65 V.
  EXPECT_NEAR(model.chain_current_a(), 4.35 / (6800.0 + 5 * 1000.0 + 10 * 0.5), 1e-12);
  adc.write(ad7794::kRegIo, ad7794::io_word(0, ad7794::kIexc210uA), 1);
  model.front_end().reference_lost = true;
  convert(0x1230);
  EXPECT_NE(last_status & ad7794::kStatusNoXref, 0);
  convert(0x1210);  // REF_DET off: no NOXREF flag, but the result is still unusable (ERR)
  EXPECT_EQ(last_status & ad7794::kStatusNoXref, 0);
  EXPECT_NE(last_status & ad7794::kStatusErr, 0);
}

TEST_F(Fixture, BurnoutCurrentsDriveAnOpenInputToFullScale) {
  adc.write(ad7794::kRegIo, ad7794::io_word(0, ad7794::kIexc210uA), 1);
  model.front_end().probe_fault[1] = sim::ProbeFault::kOpenSense;
  const uint32_t stale = convert(0x1231);  // without burnout: a plausible stale value
  EXPECT_EQ(last_status & ad7794::kStatusErr, 0);
  EXPECT_GT(stale, 0x100000u);
  const uint32_t bo = convert(0x3231);
  EXPECT_EQ(bo, 0xFFFFFFu);
  EXPECT_NE(last_status & ad7794::kStatusErr, 0);
  // A healthy input moves only by 100 nA x R.
  const uint32_t a = convert(0x1230);
  const uint32_t b = convert(0x3230);
  EXPECT_NEAR((static_cast<double>(b) - a) / a, 100e-9 / 210e-6, 2e-5);
}

TEST_F(Fixture, ContinuousReadModeAndSilentReset) {
  adc.write(ad7794::kRegIo, ad7794::io_word(0, ad7794::kIexc210uA), 1);
  adc.write(ad7794::kRegConfig, 0x1230, 2);
  adc.write(ad7794::kRegMode, ad7794::mode_word(ad7794::kModeContinuous, 1), 2);
  spi.select();
  spi.transfer(0x5C);
  int words = 0;
  for (int i = 0; i < 5; ++i) {
    model.advance(0.0045);
    if (!model.rdy_low()) continue;
    uint32_t v = 0;
    for (int k = 0; k < 3; ++k) v = (v << 8) | spi.transfer(0x00);
    EXPECT_GT(v, 0u);
    ++words;
  }
  EXPECT_GE(words, 3);
  spi.deselect();
  model.inject_silent_reset();
  model.advance(0.001);
  EXPECT_EQ(adc.read16(ad7794::kRegConfig), 0x0710);
  EXPECT_EQ(adc.read8(ad7794::kRegIo), 0);
}

TEST(Ad7794Noise, RmsNoiseFollowsTheModelAndIsSeeded) {
  sim::Ad7794ModelOptions o;
  o.seed = 42;
  EXPECT_NEAR(sim::Ad7794Model::rms_noise_v(7, 10), 85e-9, 1e-12);
  EXPECT_NEAR(sim::Ad7794Model::rms_noise_v(7, 15), 85e-9 * std::sqrt(4.17 / 16.7), 1e-12);
  auto run = [&](uint64_t seed) {
    o.seed = seed;
    sim::Ad7794Model m(o);
    ModelSpi s{m};
    Ad7794<ModelSpi> a(s);
    a.write(ad7794::kRegIo, ad7794::io_word(0, ad7794::kIexc210uA), 1);
    a.write(ad7794::kRegConfig, 0x1230, 2);
    std::vector<double> v;
    for (int i = 0; i < 200; ++i) {
      a.start(ad7794::kModeSingle, 10);
      m.advance(0.125);
      uint8_t st;
      uint32_t code;
      a.finish_conversion(st, code, 3);
      v.push_back(code);
    }
    return v;
  };
  const auto v1 = run(42), v2 = run(42), v3 = run(43);
  EXPECT_EQ(v1, v2);
  EXPECT_NE(v1, v3);
  double mean = 0, var = 0;
  for (double x : v1) mean += x;
  mean /= v1.size();
  for (double x : v1) var += (x - mean) * (x - mean);
  const double rms_codes = std::sqrt(var / (v1.size() - 1));
  // Expected: noise at gain 4 (0.34 uV) over the full-scale input 1.428 V / 4 -> codes.
  const double expected = sim::Ad7794Model::rms_noise_v(2, 10) / (210e-6 * 6800.0 / 4.0) * 16777216.0;
  EXPECT_NEAR(rms_codes, expected, 0.2 * expected);
}

}  // namespace
}  // namespace btsm
