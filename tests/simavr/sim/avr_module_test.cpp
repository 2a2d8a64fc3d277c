// The real AVR image in simavr inside the complete simulated module (plant, probes, AD7794
// model, tach, UART): the host-in-the-loop checks of tests/hil/sim on shorter runs.
#include "avr_link.hpp"
#include "tests/hil/sim/sim_link.hpp"
#include "tests/hil/sim/model_upload.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace btsm::test {
namespace {

sim::SimModuleOptions avr_options(const std::string& profile) {
  sim::SimModuleOptions o;
  o.board = sim::BoardKind::Avr;
  o.elf_path = firmware_elf();
  o.plant.speed = sim::SpeedProfile::parse(profile);
  o.plant.start_steady = true;
  o.plant.start_steady_rpm = o.plant.speed.rpm_at(0);
  return o;
}

class AvrModule : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(firmware_elf())) GTEST_SKIP() << "firmware image missing: " << firmware_elf();
  }
};

TEST_F(AvrModule, SamplesMatchTruthWithin10mKAndNoiseBelow2mK) {
  SimLink l(avr_options("1h@6000"));
  for (int i = 0; i < 240; ++i) l.step(1.0);
  ASSERT_GE(l.cap.samples.size(), 46u);
  EXPECT_EQ(l.cap.undecodable, 0u);
  for (int ch = 0; ch < 5; ++ch) {
    double s1 = 0, s2 = 0, mx = 0;
    int n = 0;
    for (const auto& s : l.cap.samples) {
      const double t = s.time_ms * 1e-3;
      if (t < 30.0) continue;
      ASSERT_NE(s.temp_mK[ch], wire::kMissing);
      const double e = s.temp_mK[ch] * 1e-3 - l.truth_at(t, ch);
      mx = std::max(mx, std::fabs(e));
      s1 += e;
      s2 += e * e;
      ++n;
    }
    const double sd = std::sqrt(std::max(0.0, s2 / n - (s1 / n) * (s1 / n)));
    std::printf("avr ch%d: max |err| %.5f K, std %.5f K over %d samples\n", ch + 1, mx, sd, n);
    EXPECT_LE(mx, 0.010);
    EXPECT_LE(sd, 0.002);
  }
}

TEST_F(AvrModule, TachSpeedReachesTheFirmware) {
  SimLink l(avr_options("40s@3000,40s@7500"));
  for (int i = 0; i < 80; ++i) l.step(1.0);
  int checked = 0;
  for (const auto& s : l.cap.samples) {
    const double t = s.time_ms * 1e-3;
    EXPECT_NE(s.overall & wire::kOverallSpeedFromTach, 0);
    if (t > 10 && t < 38) {
      EXPECT_NEAR(s.speed_rpm, 3000, 30) << "t = " << t;
      ++checked;
    }
    if (t > 50 && t < 78) {
      EXPECT_NEAR(s.speed_rpm, 7500, 75) << "t = " << t;
      ++checked;
    }
  }
  EXPECT_GE(checked, 8);
}

// The tach's dead-band: a constant pulse rate reads as one constant speed although interrupt
// latency moves the edges' timestamps by a tick (6000 rpm alternated with 5998 before), also at a
// rate between two tick counts (110 Hz = 2272.7 ticks: 6602 or 6599 rpm, whichever comes first).
TEST_F(AvrModule, ConstantTachRateReadsAsOneSpeed) {
  AvrLink l;
  l.h->set_tach_hz(100.0);
  l.step(40.0);
  l.h->set_tach_hz(110.0);
  l.step(40.0);
  std::vector<uint16_t> at100, at110;
  for (const auto& s : l.capture().samples) {
    const double t = s.time_ms * 1e-3;
    if (t > 2 && t < 39) at100.push_back(s.speed_rpm);
    if (t > 42 && t < 79) at110.push_back(s.speed_rpm);
  }
  ASSERT_GE(at100.size(), 6u);
  ASSERT_GE(at110.size(), 6u);
  for (uint16_t v : at100) EXPECT_EQ(v, 6000);
  EXPECT_GE(at110.front(), 6599);
  EXPECT_LE(at110.front(), 6602);
  for (uint16_t v : at110) EXPECT_EQ(v, at110.front());
}

TEST_F(AvrModule, AnswersGetInfoOverTheUart) {
  SimLink l(avr_options("1h@0"));
  l.step(1.0);
  uint8_t seq = 7;
  const wire::Info info = get_info(l, seq);
  EXPECT_EQ(info.device_id, 0x0000DE70u);
  EXPECT_EQ(info.protocol_version, wire::kProtocolVersion);
  const auto st = l.m.stats();
  EXPECT_GT(st.board.spi_bytes, 0u);
  EXPECT_LT(double(st.board.active_cycles) / double(st.board.cycles), 0.5) << "the firmware must sleep";
}

struct AvrFault {
  const char* spec;
  uint8_t faulted;
};
inline void PrintTo(const AvrFault& f, std::ostream* os) { *os << f.spec; }

class AvrModuleFault : public AvrModule, public ::testing::WithParamInterface<AvrFault> {};

TEST_P(AvrModuleFault, SensorFaultOnTheRightChannelsAndNoAlarm) {
  auto o = avr_options("1h@6000");
  o.plant.faults.push_back(sim::parse_fault(GetParam().spec));
  SimLink l(o);
  for (int i = 0; i < 90; ++i) l.step(1.0);
  int after = 0;
  for (const auto& s : l.cap.samples) {
    const double t = s.time_ms * 1e-3;
    EXPECT_NE(s.overall & wire::kStatusStateMask, uint8_t(wire::DiagState::Alarm));
    for (int ch = 0; ch < 5; ++ch) {
      const uint8_t st = s.channel_status[ch] & wire::kStatusStateMask;
      const bool f = (GetParam().faulted >> ch) & 1;
      if (t < 29.0) {
        EXPECT_NE(st, uint8_t(wire::DiagState::SensorFault)) << "ch" << ch + 1;
      }
      if (t > 50.0) {
        if (f) {
          EXPECT_EQ(st, uint8_t(wire::DiagState::SensorFault)) << "ch" << ch + 1 << " t " << t;
        } else {
          EXPECT_NE(st, uint8_t(wire::DiagState::SensorFault)) << "ch" << ch + 1 << " t " << t;
        }
      }
    }
    if (t > 50.0) ++after;
  }
  EXPECT_GE(after, 6);
}

INSTANTIATE_TEST_SUITE_P(Faults, AvrModuleFault,
                         ::testing::Values(AvrFault{"open:ch2@30", 0x02}, AvrFault{"short:ch1@30", 0x01},
                                           AvrFault{"noadc@30", 0x1F}, AvrFault{"noref@30", 0x1F}),
                         [](const ::testing::TestParamInfo<AvrFault>& i) { return fault_case_name(i.param.spec); });

}  // namespace
}  // namespace btsm::test
