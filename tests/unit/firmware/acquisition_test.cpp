// Acquisition state machine (calibration, sweeps, every fault) against the AD7794 model on the
// native board.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "firmware/acquisition.hpp"
#include "test_support.hpp"

namespace btsm {
namespace {

using Spi = sim::NativeBoard::Spi;

struct AcqFixture : ::testing::Test {
  sim::NativeBoard board;
  Acquisition<Spi> acq{board.spi};

  void SetUp() override {
    const double temps[5] = {20.0, 35.5, 42.0, 22.0, 60.0};
    for (int j = 0; j < 5; ++j) board.front_end().probe_ohm[j] = test::pt1000_ohm(temps[j]);
    acq.configure(AcquisitionSetup());
  }

  // Polls and advances simulated time until a sweep is ready (or the limit passes).
  bool sweep(double limit_s = 10.0) {
    acq.request_sweep();
    const uint64_t end = board.now_us() + static_cast<uint64_t>(limit_s * 1e6);
    while (board.now_us() < end) {
      const uint32_t budget = acq.poll(board.clock.millis());
      if (acq.sweep_ready()) {
        acq.take_sweep();
        return true;
      }
      if (budget == 0) continue;
      board.advance_to_next_event(std::min<uint64_t>(budget, 1000) * 1000);
    }
    return false;
  }
};

TEST_F(AcqFixture, CalibratesEveryChannelAndMeasuresTheResistances) {
  ASSERT_TRUE(sweep());
  EXPECT_TRUE(acq.calibrated());
  EXPECT_EQ(acq.chip(), AdcChip::kAd7794);
  for (uint8_t j = 0; j < 5; ++j) {
    const ChannelReading& r = acq.reading(j);
    EXPECT_EQ(r.faults, 0) << "channel " << int(j);
    EXPECT_NEAR(r.r_q16 / 65536.0, board.front_end().probe_ohm[j], 0.01) << "channel " << int(j);
  }
  // AIN4 and AIN5 share one pair on the chip but keep their own coefficients in RAM.
  EXPECT_NE(acq.calibration(3).offset, acq.calibration(4).offset);
  EXPECT_EQ(board.adc().counters().ignored_cal_writes, 0u);
  EXPECT_EQ(acq.counters().inits, 1u);
}

// evaluate() is code_to_resistance() (identity software calibration, unipolar) in fixed point:
// the resistance is code_to_ohm_q16 bit for bit, and that is the exact R_ref code / (2^24 G) to
// within half an LSB (2^-17 ohm) plus the rounding of R_ref to 2^-16 ohm scaled by the ratio, over
// the whole probe range; the statuses are the same.
TEST_F(AcqFixture, ResistanceIsCodeToResistanceInFixedPoint) {
  RatiometricConfig<double> cfg;
  cfg.r_ref_ohm = AcquisitionSetup().r_ref_milliohm * 1e-3;
  cfg.gain = ad7794::gain_of_code(AcquisitionSetup().gain_code);
  cfg.bipolar = false;
  cfg.rail_margin_codes = 16;
  const uint32_t r_ref_q16 = ohm_q16_from_milliohm(AcquisitionSetup().r_ref_milliohm);
  double worst = 0;
  for (double t = -60.0; t <= 165.0; t += 22.7) {  // up to ~1.66 kOhm: gain 4 reaches 1.7 kOhm
    for (int j = 0; j < 5; ++j) board.front_end().probe_ohm[j] = test::pt1000_ohm(t + j);
    ASSERT_TRUE(sweep());
    for (uint8_t j = 0; j < 5; ++j) {
      const ChannelReading& r = acq.reading(j);
      ASSERT_EQ(r.faults, 0) << t;
      EXPECT_EQ(r.r_q16, code_to_ohm_q16(r.code, AcquisitionSetup().gain_code, r_ref_q16));
      const RatioResult<double> ref = code_to_resistance<double>(r.code, false, cfg, ChannelCalibration<double>());
      ASSERT_TRUE(ref.ok());
      const double err = std::fabs(r.r_q16 / 65536.0 - ref.r_ohm);
      worst = std::max(worst, err);
      EXPECT_LE(err, 0.5 / 65536 + 0.5 / 65536 * ref.ratio + 1e-12) << "t " << t << " channel " << int(j);
    }
  }
  std::printf("[acquisition] fixed-point resistance vs code_to_resistance (double): worst %.2e ohm\n", worst);
}

TEST_F(AcqFixture, SharedCalibrationPairIsRestoredOnChannelSwitch) {
  ASSERT_TRUE(sweep());
  // The last channel converted was AIN5: its pair is loaded. The next sweep converts AIN4 with
  // its own coefficients again, so both stay accurate sweep after sweep.
  for (int k = 0; k < 3; ++k) {
    ASSERT_TRUE(sweep());
    EXPECT_NEAR(acq.reading(3).r_q16 / 65536.0, board.front_end().probe_ohm[3], 0.01);
    EXPECT_NEAR(acq.reading(4).r_q16 / 65536.0, board.front_end().probe_ohm[4], 0.01);
  }
  // Control: converting AIN4 with AIN5's coefficients would be visibly wrong (offset errors
  // -5 uV vs +1.5 uV in the model = 0.03 ohm).
  const double wrong = (static_cast<double>(acq.calibration(4).offset) - acq.calibration(3).offset) /
                       16777216.0 * 6800.0 / 4.0;
  EXPECT_GT(std::abs(wrong), 0.02);
}

TEST_F(AcqFixture, SweepTakesTheConversionAndBurnoutTimes) {
  ASSERT_TRUE(sweep());  // includes calibration
  const uint64_t t0 = board.now_us();
  ASSERT_TRUE(sweep());
  const double dt = (board.now_us() - t0) * 1e-6;
  // 5 x (120 ms conversion + 4 ms burnout + oscillator starts); never more than 1 s.
  EXPECT_GT(dt, 0.6);
  EXPECT_LT(dt, 1.0);
}

TEST_F(AcqFixture, OpenSenseLeadIsFoundByTheBurnoutCheckOnly) {
  AcquisitionSetup every;
  every.burnout_checks_per_sweep = 5;  // every channel every sweep: found in the next sweep
  acq.configure(every);
  ASSERT_TRUE(sweep());
  board.front_end().probe_fault[1] = sim::ProbeFault::kOpenSense;
  ASSERT_TRUE(sweep());
  EXPECT_EQ(acq.reading(1).faults, wire::kFaultOpen);
  for (uint8_t j : {0, 2, 3, 4}) EXPECT_EQ(acq.reading(j).faults, 0) << int(j);
  board.front_end().probe_fault[1] = sim::ProbeFault::kNone;
  ASSERT_TRUE(sweep());
  EXPECT_EQ(acq.reading(1).faults, 0);
}

// Default: two open-wire checks per sweep, rotating. Whichever channel breaks at whichever point
// of the rotation, it is reported open within three sweeps and in every sweep after that (never
// again as a temperature), and reported good within three sweeps of the repair. Only the
// checks tell a broken sense lead from a good probe: the measurement itself reads plausibly.
TEST_F(AcqFixture, RotatingOpenWireChecksFindEveryChannelWithinThreeSweeps) {
  ASSERT_EQ(AcquisitionSetup().burnout_checks_per_sweep, 2);
  for (uint8_t broken = 0; broken < 5; ++broken) {
    for (int phase = 0; phase < 5; ++phase) {
      for (int k = 0; k < phase; ++k) ASSERT_TRUE(sweep());
      board.front_end().probe_fault[broken] = sim::ProbeFault::kOpenSense;
      int found_after = 0;
      for (int k = 1; k <= 3 && found_after == 0; ++k) {
        ASSERT_TRUE(sweep());
        if (acq.reading(broken).faults == wire::kFaultOpen) found_after = k;
        for (uint8_t j = 0; j < 5; ++j) {
          if (j == broken) continue;
          ASSERT_EQ(acq.reading(j).faults, 0) << int(j);
        }
      }
      ASSERT_NE(found_after, 0) << "channel " << int(broken) << " phase " << phase;
      for (int k = 0; k < 6; ++k) {  // the verdict holds between the channel's checks
        ASSERT_TRUE(sweep());
        ASSERT_EQ(acq.reading(broken).faults, wire::kFaultOpen) << "channel " << int(broken) << " sweep " << k;
      }
      board.front_end().probe_fault[broken] = sim::ProbeFault::kNone;
      int cleared_after = 0;
      for (int k = 1; k <= 3 && cleared_after == 0; ++k) {
        ASSERT_TRUE(sweep());
        if (acq.reading(broken).faults == 0) cleared_after = k;
      }
      ASSERT_NE(cleared_after, 0) << "channel " << int(broken) << " phase " << phase;
      EXPECT_NEAR(acq.reading(broken).r_q16 / 65536.0, board.front_end().probe_ohm[broken], 0.01);
    }
  }
}

// Two checks per sweep -- 5 measurements + 2 burnout conversions -- except the first sweep after
// configure(), which checks every channel: an input with nothing connected (a spare channel left
// open) is reported open from the first sample, never as a temperature.
TEST_F(AcqFixture, FirstSweepChecksEveryChannelThenTwoPerSweep) {
  board.front_end().probe_fault[4] = sim::ProbeFault::kOpenSense;
  ASSERT_TRUE(sweep());  // calibration + the first sweep
  EXPECT_EQ(acq.reading(4).faults, wire::kFaultOpen);
  for (int k = 0; k < 6; ++k) {
    const uint64_t before = board.adc().counters().conversions;
    ASSERT_TRUE(sweep());
    EXPECT_EQ(board.adc().counters().conversions - before, 7u) << k;
    EXPECT_EQ(acq.reading(4).faults, wire::kFaultOpen) << k;
  }
  board.front_end().probe_fault[4] = sim::ProbeFault::kNone;
  acq.configure(AcquisitionSetup());  // re-initialisation: calibration, then every channel checked
  ASSERT_TRUE(sweep());
  EXPECT_EQ(acq.reading(4).faults, 0);
}

TEST_F(AcqFixture, ShortedProbe) {
  ASSERT_TRUE(sweep());
  board.front_end().probe_fault[2] = sim::ProbeFault::kShort;
  ASSERT_TRUE(sweep());
  EXPECT_EQ(acq.reading(2).faults, wire::kFaultShort);
  for (uint8_t j : {0, 1, 3, 4}) EXPECT_EQ(acq.reading(j).faults, 0) << int(j);
}

TEST_F(AcqFixture, BrokenElementBreaksTheChainAndEveryChannelLosesItsReference) {
  ASSERT_TRUE(sweep());
  board.front_end().probe_fault[0] = sim::ProbeFault::kOpenElement;
  ASSERT_TRUE(sweep());
  for (uint8_t j = 0; j < 5; ++j) EXPECT_EQ(acq.reading(j).faults & wire::kFaultReference, wire::kFaultReference);
}

TEST_F(AcqFixture, LostReference) {
  ASSERT_TRUE(sweep());
  board.front_end().reference_lost = true;
  ASSERT_TRUE(sweep());
  for (uint8_t j = 0; j < 5; ++j) EXPECT_EQ(acq.reading(j).faults, wire::kFaultReference) << int(j);
  board.front_end().reference_lost = false;
  ASSERT_TRUE(sweep());
  for (uint8_t j = 0; j < 5; ++j) EXPECT_EQ(acq.reading(j).faults, 0) << int(j);
}

TEST_F(AcqFixture, MissingAdcAtStartAndDuringOperation) {
  board.front_end().chip_missing = true;
  ASSERT_TRUE(sweep());
  for (uint8_t j = 0; j < 5; ++j) EXPECT_EQ(acq.reading(j).faults, wire::kFaultAdc);
  EXPECT_EQ(acq.chip(), AdcChip::kNone);
  EXPECT_GE(acq.counters().missing, 1u);
  // While it is missing every requested sweep is answered at once with ADC faults; the chip is
  // looked for again once a second.
  board.front_end().chip_missing = false;
  board.advance_us(1'100'000);
  ASSERT_TRUE(sweep());
  ASSERT_TRUE(sweep());
  for (uint8_t j = 0; j < 5; ++j) EXPECT_EQ(acq.reading(j).faults, 0);
  // Vanishes while a conversion runs: RDY never comes, the conversion times out.
  acq.request_sweep();
  for (int i = 0; i < 3; ++i) acq.poll(board.clock.millis());
  board.front_end().chip_missing = true;
  ASSERT_TRUE(sweep());
  for (uint8_t j = 0; j < 5; ++j) EXPECT_EQ(acq.reading(j).faults, wire::kFaultAdc);
  EXPECT_EQ(acq.counters().adc_timeouts, 1u);
  // Vanishes between sweeps: the register read-back sees all ones.
  board.front_end().chip_missing = false;
  board.advance_us(1'100'000);
  ASSERT_TRUE(sweep());
  ASSERT_TRUE(sweep());
  const uint16_t missing_before = acq.counters().missing;
  board.front_end().chip_missing = true;
  ASSERT_TRUE(sweep());
  for (uint8_t j = 0; j < 5; ++j) EXPECT_EQ(acq.reading(j).faults, wire::kFaultAdc);
  EXPECT_GT(acq.counters().missing, missing_before);
}

TEST_F(AcqFixture, SilentResetIsDetectedByReadBackCountedAndRepaired) {
  ASSERT_TRUE(sweep());
  board.adc().inject_silent_reset();
  ASSERT_TRUE(sweep());
  EXPECT_EQ(acq.counters().silent_resets, 1u);
  EXPECT_EQ(acq.counters().inits, 2u);
  for (uint8_t j = 0; j < 5; ++j) {
    EXPECT_EQ(acq.reading(j).faults, 0);
    EXPECT_NEAR(acq.reading(j).r_q16 / 65536.0, board.front_end().probe_ohm[j], 0.01);
  }
}

TEST_F(AcqFixture, DisabledChannelsAreNotConverted) {
  AcquisitionSetup s;
  s.enabled_mask = 0x0B;  // ch1, ch2, ch4
  acq.configure(s);
  const uint64_t before = board.adc().counters().conversions;
  ASSERT_TRUE(sweep());
  ASSERT_TRUE(sweep());
  // 3 channels x measurement x 2 sweeps, burnout checks: all 3 in the first sweep, then 2.
  EXPECT_EQ(board.adc().counters().conversions - before, 11u);
  EXPECT_NEAR(acq.reading(3).r_q16 / 65536.0, board.front_end().probe_ohm[3], 0.01);
}

}  // namespace
}  // namespace btsm
