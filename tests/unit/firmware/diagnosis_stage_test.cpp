// The firmware's diagnosis stage and the channel roles: which channels get the model's thermal
// limits (bearings, housing, motor, coolant, shaft) and which are only watched for sensor faults
// (ambient, spare) or not at all (disabled).
#include <gtest/gtest.h>

#include "common/wire_messages.hpp"
#include "firmware/diagnosis_stage.hpp"

namespace btsm {
namespace {

using wire::ChannelRole;

struct Sweeps {
  ChannelLimits limits[5];
  int32_t temp_mK[5] = {30000, 30000, 30000, 20000, 30000};
  int32_t predicted_mK[5] = {30000, 30000, 30000, 20000, 20000};  // channel 5 reads 10 K above its prediction
  uint8_t faults[5] = {0, 0, 0, 0, 0};
  uint8_t roles[5];

  Sweeps() {
    for (int j = 0; j < 5; ++j) {
      limits[j].drift_mK = 500;
      limits[j].low_drift_mK = 500;
      limits[j].warn_evidence = 10;  // 1280 mK samples
      limits[j].alarm_evidence = 20;
      limits[j].low_warn_evidence = 10;
      limits[j].abs_limit_mK = 90000;
      limits[j].max_rise_mK_per_min = 0;
      roles[j] = static_cast<uint8_t>(wire::default_channel_role(static_cast<uint8_t>(j)));
    }
  }
  // One model step's evidence and the sweep's evaluation, as the App runs them.
  void sweep(DiagnosisStage& d) {
    d.accumulate(limits, temp_mK, predicted_mK);
    d.evaluate(limits, temp_mK, predicted_mK, faults, roles, 5000);
  }
  // The state of channel 5 after ten sweeps with its role set to `role`.
  uint8_t state_of_channel5(ChannelRole role) {
    roles[4] = static_cast<uint8_t>(role);
    DiagnosisStage d;
    d.configure(true);
    for (int k = 0; k < 10; ++k) sweep(d);
    return d.state(4);
  }
};

TEST(DiagnosisStage, ThermalRolesGetTheModelsLimitsOthersOnlySensorFaults) {
  Sweeps s;
  const uint8_t alarm = static_cast<uint8_t>(DiagState::kAlarm);
  const uint8_t normal = static_cast<uint8_t>(DiagState::kNormal);
  for (ChannelRole r : {ChannelRole::FrontBearing, ChannelRole::RearBearing, ChannelRole::Housing, ChannelRole::Motor,
                        ChannelRole::Coolant, ChannelRole::Shaft})
    EXPECT_EQ(s.state_of_channel5(r), alarm) << wire::channel_role_name(static_cast<uint8_t>(r));
  for (ChannelRole r : {ChannelRole::Spare, ChannelRole::Ambient, ChannelRole::Disabled})
    EXPECT_EQ(s.state_of_channel5(r), normal) << wire::channel_role_name(static_cast<uint8_t>(r));
  // A sensor fault is reported on a spare channel, not on a disabled one.
  s.faults[4] = wire::kFaultOpen;
  EXPECT_EQ(s.state_of_channel5(ChannelRole::Spare), static_cast<uint8_t>(DiagState::kSensorFault));
  EXPECT_EQ(s.state_of_channel5(ChannelRole::Disabled), normal);
}

// alarm_latch 1 holds an ALARM until ACK_ALARM however long the cause is gone (the counter used to
// let it go after 255 samples, 21 min); alarm_latch 0 lets it go after 60 normal samples.
TEST(DiagnosisStage, LatchedAlarmIsHeldUntilAcknowledged) {
  for (bool latch : {true, false}) {
    Sweeps s;
    s.roles[4] = static_cast<uint8_t>(ChannelRole::Shaft);
    DiagnosisStage d;
    d.configure(latch);
    for (int k = 0; k < 5; ++k) s.sweep(d);
    ASSERT_EQ(d.state(4), static_cast<uint8_t>(DiagState::kAlarm));
    s.temp_mK[4] = s.predicted_mK[4];  // the cause is gone
    for (int k = 0; k < 1000; ++k) s.sweep(d);
    if (latch) {
      EXPECT_EQ(d.state(4), static_cast<uint8_t>(DiagState::kAlarm));
      EXPECT_TRUE(d.alarm_latched());
      d.acknowledge();
      s.sweep(d);
    }
    EXPECT_EQ(d.state(4), static_cast<uint8_t>(DiagState::kNormal)) << "latch " << latch;
    EXPECT_FALSE(d.alarm_latched());
  }
}

// The evidence: a residual within the drift never accumulates; a small lasting excess does, and
// reaches WARN and then ALARM after the time its thresholds say (CUSUM: threshold / (r - drift)
// samples, plus the persistence of 3 samples); a probe colder than its model only warns.
TEST(DiagnosisStage, EvidenceAccumulatesALastingExcessAndForgivesTheDrift) {
  Sweeps s;
  s.roles[4] = static_cast<uint8_t>(ChannelRole::Shaft);
  s.limits[4].warn_evidence = 94;   // 12,032 mK samples
  s.limits[4].alarm_evidence = 188;  // 24,064
  s.limits[4].low_warn_evidence = 94;
  DiagnosisStage d;
  d.configure(true);
  s.temp_mK[4] = s.predicted_mK[4] + 499;  // just within the drift: for a day
  for (int k = 0; k < 17280; ++k) s.sweep(d);
  EXPECT_EQ(d.state(4), static_cast<uint8_t>(DiagState::kNormal));
  EXPECT_EQ(d.evidence(4).high(), 0);
  s.temp_mK[4] = s.predicted_mK[4] + 1500;  // 1000 mK above the drift per sample
  int warn_at = -1, alarm_at = -1;
  for (int k = 1; k <= 60 && alarm_at < 0; ++k) {
    s.sweep(d);
    if (warn_at < 0 && d.state(4) == static_cast<uint8_t>(DiagState::kWarn)) warn_at = k;
    if (d.state(4) == static_cast<uint8_t>(DiagState::kAlarm)) alarm_at = k;
  }
  EXPECT_EQ(warn_at, 13 + 2);   // evidence 13,000 > 12,032 after 13 samples, held 3 samples
  EXPECT_EQ(alarm_at, 25 + 2);  // 25,000 > 24,064
  // Colder than the model: WARN, never ALARM.
  Sweeps c;
  c.roles[4] = static_cast<uint8_t>(ChannelRole::Shaft);
  c.temp_mK[4] = c.predicted_mK[4] - 5000;
  DiagnosisStage dc;
  dc.configure(true);
  for (int k = 0; k < 1000; ++k) c.sweep(dc);
  EXPECT_EQ(dc.state(4), static_cast<uint8_t>(DiagState::kWarn));
  EXPECT_GT(dc.evidence(4).low(), 0);
  EXPECT_EQ(dc.evidence(4).high(), 0);
  // Without a prediction the evidence starts afresh.
  c.predicted_mK[4] = wire::kMissing;
  c.sweep(dc);
  EXPECT_EQ(dc.evidence(4).low(), 0);
}

}  // namespace
}  // namespace btsm
