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
      limits[j].warn_band_mK = 1000;
      limits[j].alarm_band_mK = 2000;
      limits[j].abs_limit_mK = 90000;
      limits[j].max_rise_mK_per_min = 0;
      roles[j] = static_cast<uint8_t>(wire::default_channel_role(static_cast<uint8_t>(j)));
    }
  }
  // The state of channel 5 after ten sweeps with its role set to `role`.
  uint8_t state_of_channel5(ChannelRole role) {
    roles[4] = static_cast<uint8_t>(role);
    DiagnosisStage d;
    d.configure(true);
    for (int k = 0; k < 10; ++k) d.evaluate(limits, temp_mK, predicted_mK, faults, roles, 5000);
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
    for (int k = 0; k < 5; ++k) d.evaluate(s.limits, s.temp_mK, s.predicted_mK, s.faults, s.roles, 5000);
    ASSERT_EQ(d.state(4), static_cast<uint8_t>(DiagState::kAlarm));
    s.temp_mK[4] = s.predicted_mK[4];  // the cause is gone
    for (int k = 0; k < 1000; ++k) d.evaluate(s.limits, s.temp_mK, s.predicted_mK, s.faults, s.roles, 5000);
    if (latch) {
      EXPECT_EQ(d.state(4), static_cast<uint8_t>(DiagState::kAlarm));
      EXPECT_TRUE(d.alarm_latched());
      d.acknowledge();
      d.evaluate(s.limits, s.temp_mK, s.predicted_mK, s.faults, s.roles, 5000);
    }
    EXPECT_EQ(d.state(4), static_cast<uint8_t>(DiagState::kNormal)) << "latch " << latch;
    EXPECT_FALSE(d.alarm_latched());
  }
}

}  // namespace
}  // namespace btsm
