// Host-in-the-loop, native board: every injected fault gives SENSOR_FAULT on the right
// channel(s), the healthy channels keep measuring, and no ALARM is raised.
#include "sim_link.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace btsm::test {
namespace {

struct FaultCase {
  const char* spec;     // --fault syntax, starting at 120 s
  uint8_t faulted;      // bit i = channel i+1 expected in SENSOR_FAULT
  uint8_t fault_bits;   // status bits expected on the faulted channels (any of them)
};

inline void PrintTo(const FaultCase& f, std::ostream* os) { *os << f.spec; }

class HilFault : public ::testing::TestWithParam<FaultCase> {};

TEST_P(HilFault, SensorFaultOnTheRightChannelsAndNoFalseAlarm) {
  const FaultCase fc = GetParam();
  sim::SimModuleOptions o;
  o.plant.speed = sim::SpeedProfile::parse("1h@6000");
  o.plant.start_steady = true;
  o.plant.start_steady_rpm = 6000;
  o.plant.faults.push_back(sim::parse_fault(fc.spec));
  SimLink l(o);
  for (int i = 0; i < 360; ++i) l.step(1.0);
  ASSERT_GE(l.cap.samples.size(), 70u);
  int faulted_samples = 0;
  for (const auto& s : l.cap.samples) {
    const double t = s.time_ms * 1e-3;
    SCOPED_TRACE(std::string(fc.spec) + " at t = " + std::to_string(t));
    EXPECT_NE(s.overall & wire::kStatusStateMask, uint8_t(wire::DiagState::Alarm)) << "false ALARM";
    EXPECT_EQ(s.overall & wire::kOverallAlarmLatched, 0);
    for (int ch = 0; ch < 5; ++ch) {
      const uint8_t state = s.channel_status[ch] & wire::kStatusStateMask;
      EXPECT_NE(state, uint8_t(wire::DiagState::Alarm)) << "ch" << ch + 1;
      const bool expect_fault = (fc.faulted >> ch) & 1;
      if (t < 119.0) {
        EXPECT_NE(state, uint8_t(wire::DiagState::SensorFault)) << "ch" << ch + 1 << " before the fault";
      } else if (t > 140.0) {
        if (expect_fault) {
          EXPECT_EQ(state, uint8_t(wire::DiagState::SensorFault)) << "ch" << ch + 1;
          EXPECT_EQ(s.temp_mK[ch], wire::kMissing) << "ch" << ch + 1;
          EXPECT_NE(s.channel_status[ch] & fc.fault_bits, 0) << "ch" << ch + 1 << " status "
                                                            << int(s.channel_status[ch]);
        } else {
          EXPECT_NE(state, uint8_t(wire::DiagState::SensorFault)) << "healthy ch" << ch + 1;
          EXPECT_NEAR(s.temp_mK[ch] * 1e-3, l.truth_at(t, ch), 0.010) << "healthy ch" << ch + 1;
        }
      }
    }
    if (t > 140.0) ++faulted_samples;
  }
  EXPECT_GE(faulted_samples, 40);
}

constexpr uint8_t kAll = 0x1F;
INSTANTIATE_TEST_SUITE_P(
    Faults, HilFault,
    ::testing::Values(FaultCase{"open:ch2@120", 0x02, wire::kFaultOpen | wire::kFaultAdc},
                      FaultCase{"short:ch1@120", 0x01, wire::kFaultShort},
                      FaultCase{"open:ch5@120", 0x10, wire::kFaultOpen | wire::kFaultAdc},
                      FaultCase{"openchain:ch3@120", kAll, wire::kFaultOpen | wire::kFaultAdc | wire::kFaultReference},
                      FaultCase{"noadc@120", kAll, wire::kFaultAdc},
                      FaultCase{"noref@120", kAll, wire::kFaultReference | wire::kFaultAdc}),
    [](const ::testing::TestParamInfo<FaultCase>& i) { return fault_case_name(i.param.spec); });

}  // namespace
}  // namespace btsm::test
