// Diagnosis state machine: one test per transition of the diagram in common/diagnosis.hpp, plus
// persistence, hysteresis, the overall ranking, the residual evidence and the rise-rate helper.
#include "common/diagnosis.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

namespace btsm {
namespace {

// Limits: warn 1500, alarm 4000 mK samples of upper evidence, warn 1500 of lower evidence; exit at
// 80 %: 1200 / 3200; absolute 80 degC (exit 79); rise 3 K/min (exit 2.4). N = 3, Mw = 3, Ma = 5,
// Mf = 2. residual(e) feeds evidence e: upper for e > 0, lower for e < 0.
struct DiagTransition : ::testing::Test {
  DiagChannelLimits lim;
  DiagTiming t;
  DiagChannel ch;
  DiagTransition() {
    lim.warn_evidence = 1500;
    lim.alarm_evidence = 4000;
    lim.low_warn_evidence = 1500;
    lim.abs_limit_mK = 80000;
    lim.max_rise_mK_per_min = 3000;
    t.enter_samples = 3;
    t.warn_clear_samples = 3;
    t.alarm_clear_samples = 5;
    t.fault_clear_samples = 2;
    t.hysteresis_permille = 200;
    t.abs_hysteresis_mK = 1000;
  }
  static DiagInput residual(int32_t e, int32_t measured = 40000) {
    DiagInput in;
    in.measured_mK = measured;
    in.evidence_high = e > 0 ? e : 0;
    in.evidence_low = e < 0 ? -e : 0;
    in.rise_mK_per_min = 0;
    return in;
  }
  static DiagInput fault() {
    DiagInput in;
    in.fault = true;
    return in;
  }
  DiagState feed(const DiagInput& in, int n = 1) {
    DiagState s = ch.state();
    for (int i = 0; i < n; ++i) s = ch.update(in, lim, t);
    return s;
  }
  void drive_to_alarm() {
    feed(residual(5000), 3);
    ASSERT_EQ(ch.state(), DiagState::kAlarm);
  }
};

TEST_F(DiagTransition, NormalToWarnNeedsNConsecutiveSamples) {
  EXPECT_EQ(feed(residual(2000), 2), DiagState::kNormal);
  EXPECT_EQ(feed(residual(0)), DiagState::kNormal);  // run broken: persistence restarts
  EXPECT_EQ(feed(residual(-2000), 2), DiagState::kNormal);
  EXPECT_EQ(feed(residual(-2000)), DiagState::kWarn);  // the lower evidence warns too
  EXPECT_TRUE(ch.reasons() & kReasonResidualWarn);
}

TEST_F(DiagTransition, NormalToAlarmOnResidual) {
  EXPECT_EQ(feed(residual(4500), 2), DiagState::kNormal);  // alarm and warn runs both at 2 < N
  EXPECT_EQ(feed(residual(4500)), DiagState::kAlarm);
  EXPECT_TRUE(ch.alarm_latched());
  EXPECT_TRUE(ch.reasons() & kReasonResidualAlarm);
}

TEST_F(DiagTransition, NormalToAlarmOnAbsoluteLimitEvenWithoutModel) {
  DiagInput in;
  in.measured_mK = 80001;  // no prediction: residual checks skipped, the limit still applies
  EXPECT_EQ(feed(in, 2), DiagState::kNormal);
  EXPECT_EQ(feed(in), DiagState::kAlarm);
  EXPECT_TRUE(ch.reasons() & kReasonAbsLimit);
  EXPECT_TRUE(ch.reasons() & kReasonNoPrediction);
}

TEST_F(DiagTransition, NormalToAlarmOnRateOfRise) {
  DiagInput in = residual(0);
  in.rise_mK_per_min = 3001;
  EXPECT_EQ(feed(in, 3), DiagState::kAlarm);
  EXPECT_TRUE(ch.reasons() & kReasonRise);
  DiagChannel other;
  lim.max_rise_mK_per_min = 0;  // disabled
  for (int i = 0; i < 10; ++i) EXPECT_EQ(other.update(in, lim, t), DiagState::kNormal);
}

TEST_F(DiagTransition, WarnToNormalOnlyBelowTheExitThresholdForMwSamples) {
  feed(residual(2000), 3);
  ASSERT_EQ(ch.state(), DiagState::kWarn);
  EXPECT_EQ(feed(residual(1300), 10), DiagState::kWarn);  // below entry, above exit (1.2 K)
  EXPECT_EQ(feed(residual(1100), 2), DiagState::kWarn);
  EXPECT_EQ(feed(residual(1300)), DiagState::kWarn);  // run broken
  EXPECT_EQ(feed(residual(1200), 2), DiagState::kWarn);
  EXPECT_EQ(feed(residual(1200)), DiagState::kNormal);
}

TEST_F(DiagTransition, WarnToAlarm) {
  feed(residual(2000), 3);
  ASSERT_EQ(ch.state(), DiagState::kWarn);
  EXPECT_EQ(feed(residual(4100), 2), DiagState::kWarn);
  EXPECT_EQ(feed(residual(4100)), DiagState::kAlarm);
}

TEST_F(DiagTransition, AlarmIsLatchedThenAutoClearsAfterMaNormalSamples) {
  drive_to_alarm();
  EXPECT_EQ(feed(residual(0), 4), DiagState::kAlarm);  // latched
  EXPECT_EQ(feed(residual(2000)), DiagState::kAlarm);  // not normal: counter restarts
  EXPECT_EQ(feed(residual(0), 4), DiagState::kAlarm);
  EXPECT_EQ(feed(residual(0)), DiagState::kNormal);
  EXPECT_FALSE(ch.alarm_latched());
}

// Ma = 0: a latched alarm in the strict sense -- however long the channel reads normal, only an
// acknowledgement ends it (the module's alarm_latch 1).
TEST_F(DiagTransition, AlarmWithoutAutoClearIsHeldUntilAcknowledged) {
  t.alarm_clear_samples = 0;
  drive_to_alarm();
  EXPECT_EQ(feed(residual(0), 5000), DiagState::kAlarm);  // 7 h at 5 s: still there
  EXPECT_TRUE(ch.alarm_latched());
  ch.acknowledge();
  EXPECT_EQ(feed(residual(0)), DiagState::kNormal);
  EXPECT_FALSE(ch.alarm_latched());
  // A new alarm is held again.
  drive_to_alarm();
  EXPECT_EQ(feed(residual(0), 300), DiagState::kAlarm);
}

TEST_F(DiagTransition, AlarmToNormalOnAcknowledgeWhenClear) {
  drive_to_alarm();
  feed(residual(0));
  ch.acknowledge();
  EXPECT_EQ(feed(residual(0)), DiagState::kNormal);
}

TEST_F(DiagTransition, AlarmToWarnOnAcknowledgeWithWarnConditionLeft) {
  drive_to_alarm();
  ch.acknowledge();
  EXPECT_EQ(feed(residual(5000), 5), DiagState::kAlarm);  // still active: stays, acknowledged
  EXPECT_TRUE(ch.reasons() & kReasonAcknowledged);
  EXPECT_EQ(feed(residual(3300)), DiagState::kAlarm);  // above the alarm exit threshold 3.2 K
  EXPECT_EQ(feed(residual(3100)), DiagState::kWarn);   // alarm clear, warn still present
  EXPECT_FALSE(ch.alarm_latched());
  // Re-entering ALARM needs N samples again.
  EXPECT_EQ(feed(residual(5000), 2), DiagState::kWarn);
  EXPECT_EQ(feed(residual(5000)), DiagState::kAlarm);
}

TEST_F(DiagTransition, AbsoluteLimitAlarmClearsOnlyBelowLimitMinusHysteresis) {
  DiagInput in;
  in.measured_mK = 81000;
  feed(in, 3);
  ASSERT_EQ(ch.state(), DiagState::kAlarm);
  ch.acknowledge();
  in.measured_mK = 79500;  // below the limit but inside the 1 K hysteresis
  EXPECT_EQ(feed(in), DiagState::kAlarm);
  in.measured_mK = 79000;
  EXPECT_EQ(feed(in), DiagState::kNormal);
}

TEST_F(DiagTransition, AcknowledgeOutsideAlarmHasNoEffect) {
  feed(residual(2000), 3);
  ch.acknowledge();
  EXPECT_EQ(feed(residual(5000), 3), DiagState::kAlarm);
  EXPECT_FALSE(ch.reasons() & kReasonAcknowledged);
  EXPECT_EQ(feed(residual(0)), DiagState::kAlarm);  // latched: the early ack did not pre-clear it
}

TEST_F(DiagTransition, AnyStateToSensorFaultAtOnce) {
  EXPECT_EQ(feed(fault()), DiagState::kSensorFault);  // from NORMAL
  ch.reset();
  feed(residual(2000), 3);
  EXPECT_EQ(feed(fault()), DiagState::kSensorFault);  // from WARN
  ch.reset();
  drive_to_alarm();
  EXPECT_EQ(feed(fault()), DiagState::kSensorFault);  // from ALARM
  EXPECT_TRUE(ch.reasons() & kReasonFault);
  DiagInput missing = residual(0);
  missing.measured_mK = kDiagNoValue;  // no reading at all counts as a fault
  ch.reset();
  EXPECT_EQ(feed(missing), DiagState::kSensorFault);
}

TEST_F(DiagTransition, SensorFaultToNormalAfterMfGoodSamples) {
  feed(fault(), 4);
  EXPECT_EQ(feed(residual(0)), DiagState::kSensorFault);
  EXPECT_EQ(feed(fault()), DiagState::kSensorFault);  // run broken
  EXPECT_EQ(feed(residual(0)), DiagState::kSensorFault);
  EXPECT_EQ(feed(residual(0)), DiagState::kNormal);
}

TEST_F(DiagTransition, SensorFaultReturnsToALatchedAlarm) {
  drive_to_alarm();
  feed(fault(), 3);
  EXPECT_EQ(feed(residual(0), 2), DiagState::kAlarm);  // the alarm was not acknowledged
  EXPECT_TRUE(ch.alarm_latched());
}

TEST_F(DiagTransition, AlarmAcknowledgedDuringFaultClearsWithTheFault) {
  drive_to_alarm();
  feed(fault());
  ch.acknowledge();
  EXPECT_EQ(feed(residual(0), 2), DiagState::kNormal);
}

TEST(DiagnosisOverall, WorstStateRanksAlarmAboveFault) {
  EXPECT_EQ(diag_worst(DiagState::kSensorFault, DiagState::kAlarm), DiagState::kAlarm);
  EXPECT_EQ(diag_worst(DiagState::kAlarm, DiagState::kSensorFault), DiagState::kAlarm);
  EXPECT_EQ(diag_worst(DiagState::kWarn, DiagState::kSensorFault), DiagState::kSensorFault);
  EXPECT_EQ(diag_worst(DiagState::kNormal, DiagState::kWarn), DiagState::kWarn);
  Diagnosis<5> d;
  d.timing.enter_samples = 1;
  d.enabled_mask = 0x0F;  // channel 4 disabled: its fault does not count
  DiagInput in[5];
  for (auto& i : in) i.measured_mK = 30000, i.evidence_high = 0, i.evidence_low = 0, i.rise_mK_per_min = 0;
  in[4].fault = true;
  EXPECT_EQ(d.update(in), DiagState::kNormal);
  in[1].fault = true;
  EXPECT_EQ(d.update(in), DiagState::kSensorFault);
  in[2].evidence_high = 600000;  // -> ALARM outranks the fault
  EXPECT_EQ(d.update(in), DiagState::kAlarm);
  EXPECT_EQ(d.channel(2).state(), DiagState::kAlarm);
  in[2].evidence_high = 0;
  in[1].fault = false;
  d.acknowledge_all();
  d.update(in);
  EXPECT_EQ(d.channel(2).state(), DiagState::kNormal);
  EXPECT_EQ(d.overall(), DiagState::kSensorFault);  // channel 1 still clearing (Mf = 3)
  d.update(in);
  EXPECT_EQ(d.update(in), DiagState::kNormal);
}

// The lower evidence only warns: a probe colder than its model is no overheating.
TEST_F(DiagTransition, LowerEvidenceNeverAlarms) {
  EXPECT_EQ(feed(residual(-900000), 100), DiagState::kWarn);
  lim.low_warn_evidence = 0;  // off
  DiagChannel other;
  for (int i = 0; i < 10; ++i) EXPECT_EQ(other.update(residual(-900000), lim, t), DiagState::kNormal);
}

// The CUSUM statistics: drained by the drift, piled up by the excess, never below 0 nor above the
// cap, and the residual clamped so no sum leaves int32.
TEST(ResidualEvidence, AccumulatesTheExcessOverTheDriftBothWays) {
  ResidualEvidence e;
  for (int i = 0; i < 100; ++i) e.add(300, 500, 500, 100000);
  EXPECT_EQ(e.high(), 0);
  EXPECT_EQ(e.low(), 0);
  e.add(1700, 500, 500, 100000);
  EXPECT_EQ(e.high(), 1200);
  e.add(1700, 500, 500, 100000);
  EXPECT_EQ(e.high(), 2400);
  e.add(-100, 500, 500, 100000);
  EXPECT_EQ(e.high(), 1800);
  EXPECT_EQ(e.low(), 0);
  for (int i = 0; i < 1000; ++i) e.add(8000000, 500, 500, 100000);
  EXPECT_EQ(e.high(), 100000) << "capped";
  e.add(-2147483647, 0, 0, 100000);
  EXPECT_EQ(e.high(), 0);
  for (int i = 0; i < 10; ++i) e.add(4194304, 0, 0, 2000000000);
  EXPECT_EQ(e.high(), ResidualEvidence::kMax) << "24 bits, whatever the cap";
  e.add(-2147483647, 0, 0, 100000);
  EXPECT_EQ(e.low(), 100000);
  e.reset();
  EXPECT_EQ(e.high() + e.low(), 0);
  // Each side forgives its own drift.
  e.add(-800, 500, 1000, 100000);
  EXPECT_EQ(e.low(), 0);
  e.add(800, 1000, 500, 100000);
  EXPECT_EQ(e.high(), 0);
  e.add(-1800, 500, 1000, 100000);
  EXPECT_EQ(e.low(), 800);
  // A constant excess r above the drift k reaches a threshold h after ceil(h / (r - k)) samples.
  ResidualEvidence f;
  int n = 0;
  while (f.high() <= 24000) f.add(1500, 500, 500, 48000), ++n;
  EXPECT_EQ(n, 25);
}

// push_scaled (the firmware's: the scale computed once per sample period, integer clamp and
// rounding, no float) against the exact rational rate diff x 60000 / (dt (W - 1)) rounded half away
// from zero and clamped, computed in int64: equal, except within the documented bound of a rounding
// tie (2^-8 mK/min for the firmware's window of 4, 2^-6 for 13) where 1 mK/min is allowed (and
// counted in the test's properties). Every window difference class:
// small, near the rounding ties, near and beyond the clamp, the int32 extremes, odd periods, and
// the window of the firmware (4) and longer ones.
template <uint8_t kWindow>
void check_scaled_rates_are_exactly_rounded(std::mt19937& rng) {
  struct Exact {
    int64_t rate;
    bool near_tie;  // within the bound of a tie
  };
  const int64_t tie_window_inv = kWindow <= 4 ? 256 : 64;  // 1 / the bound
  const auto exact = [tie_window_inv](int32_t diff, uint16_t dt) {
    const int64_t span = static_cast<int64_t>(dt) * (kWindow - 1);
    const int64_t mag = diff < 0 ? -static_cast<int64_t>(diff) : diff;
    const int64_t num = mag * 60000;
    const int64_t twice_rem = 2 * (num % span);
    int64_t r = (2 * num + span) / (2 * span);  // half up on the magnitude
    if (r > kDiagMaxRate) r = kDiagMaxRate;
    const int64_t from_tie = twice_rem > span ? twice_rem - span : span - twice_rem;  // x 1/(2 span)
    return Exact{diff < 0 ? -r : r, from_tie * tie_window_inv <= 2 * span};
  };
  long near_tie_off = 0, cases = 0;
  for (uint16_t dt : {1u, 7u, 100u, 1000u, 3333u, 5000u, 5001u, 12345u, 20000u, 60000u, 65535u}) {
    const auto scale = RiseRate<kWindow>::scale_for(dt);
    const double per_min = 60000.0 / (static_cast<double>(dt) * (kWindow - 1));
    for (int i = 0; i < 100000; ++i) {
      int32_t diff;
      switch (i % 5) {
        case 0: diff = static_cast<int32_t>(rng() % 20001) - 10000; break;
        case 1: diff = static_cast<int32_t>(rng() % 16777215) - 8388607; break;
        case 2: diff = static_cast<int32_t>(std::lround((static_cast<int32_t>(rng() % 2000001) - 1000000 + 0.5) / per_min)) +
                       static_cast<int32_t>(rng() % 3) - 1; break;  // rates near k + 1/2
        case 3: diff = static_cast<int32_t>(std::lround(8388607.0 / per_min)) * (rng() % 2 ? 1 : -1) +
                       static_cast<int32_t>(rng() % 41) - 20; break;  // near the clamp
        default: diff = static_cast<int32_t>(rng()); break;  // anywhere in int32
      }
      if (i == 0) diff = -2147483647 - 1;
      if (i == 5) diff = 2147483647;
      RiseRate<kWindow> r(dt);
      for (int k = 0; k + 1 < kWindow; ++k) ASSERT_EQ(r.push_scaled(0, scale), kDiagNoValue);
      const int32_t got = r.push_scaled(diff, scale);
      const Exact want = exact(diff, dt);
      ++cases;
      if (want.near_tie) {
        ASSERT_LE(std::llabs(got - want.rate), 1) << "W " << int(kWindow) << " dt " << dt << " diff " << diff;
        near_tie_off += got != want.rate;
      } else {
        ASSERT_EQ(got, want.rate) << "W " << int(kWindow) << " dt " << dt << " diff " << diff;
      }
      ASSERT_EQ(RiseRate<kWindow>::scaled_rate(diff, scale), got);
    }
  }
  ::testing::Test::RecordProperty("off_by_one_near_a_tie_W" + std::to_string(kWindow), std::to_string(near_tie_off) + " of " + std::to_string(cases));
}

TEST(RiseRate, ScaledPushIsTheExactlyRoundedRate) {
  std::mt19937 rng(9);
  check_scaled_rates_are_exactly_rounded<4>(rng);
  check_scaled_rates_are_exactly_rounded<2>(rng);
  check_scaled_rates_are_exactly_rounded<13>(rng);
}

// A period of 0 yields no rate (store() reports none due); its Scale clamps every non-zero
// difference rather than dividing by zero.
TEST(RiseRate, ZeroPeriodGivesNoRateAndAClampingScale) {
  RiseRate<4> r(0);
  for (int k = 0; k < 6; ++k) EXPECT_EQ(r.push(1000 * k), kDiagNoValue);
  const auto s = RiseRate<4>::scale_for(0);
  EXPECT_EQ(RiseRate<4>::scaled_rate(0, s), 0);
  EXPECT_EQ(RiseRate<4>::scaled_rate(1, s), kDiagMaxRate);
  EXPECT_EQ(RiseRate<4>::scaled_rate(-1, s), -kDiagMaxRate);
}

TEST(RiseRate, MeasuresMilliKelvinPerMinuteOverTheWindow) {
  RiseRate<13> r(5000);  // 12 intervals of 5 s = 1 min
  int32_t out = 0;
  for (int i = 0; i < 12; ++i) EXPECT_EQ(r.push(20000 + 250 * i), kDiagNoValue) << i;
  out = r.push(20000 + 250 * 12);
  EXPECT_EQ(out, 3000);  // 250 mK per 5 s
  out = r.push(20000 + 250 * 13);
  EXPECT_EQ(out, 3000);
  r.reset();
  EXPECT_EQ(r.push(0), kDiagNoValue);
  RiseRate<2> fast(100);
  fast.push(0);
  EXPECT_EQ(fast.push(-10), -6000);
}

}  // namespace
}  // namespace btsm
