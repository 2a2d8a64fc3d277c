// Session against the in-process fake module on a pty: info, commands, NACK names, timeouts,
// sample tracking, and `record` to CSV read back with the sysid reader.
#include "fake_module.hpp"
#include "host/link/recorder.hpp"
#include "host/link/serial_transport.hpp"
#include "host/link/session.hpp"
#include "host/thermal/recording.hpp"
#include "link_test_support.hpp"
#include "module_on_pty.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

using namespace btsm;
using namespace btsm::link;
using btsm::test::FakeModule;
using btsm::test::FakeModuleOptions;

namespace {

using test::ModuleOnPty;

// A fake module streaming a sample every 2 ms, identified, and record options writing a CSV into
// a temporary folder (no reconnect).
struct RecordSetup {
  ModuleOnPty m;
  test::TempDir dir;
  std::string path;
  ModuleIdentity id;
  RecordOptions ro;
  explicit RecordSetup(FakeModuleOptions o = streaming()) : m(o), path(dir.path + "/rec.csv"), id(identify(m.session)) {
    ro.out_path = path;
    ro.reconnect_s = 0;
  }
  static FakeModuleOptions streaming() {
    FakeModuleOptions o;
    o.sample_period = Millis(2);
    return o;
  }
};

}  // namespace

TEST(SampleTracker, ReportsGapsRestartsAndDuplicates) {
  SampleTracker t;
  EXPECT_FALSE(t.observe(10).gap);  // the first sample defines the start
  EXPECT_FALSE(t.observe(11).gap);
  auto r = t.observe(15);
  ASSERT_TRUE(r.gap);
  EXPECT_EQ(r.gap->first, 12u);
  EXPECT_EQ(r.gap->last, 14u);
  EXPECT_FALSE(t.observe(15).accept);  // duplicate
  r = t.observe(2);                    // went back: module restarted, 0..1 of the new run lost
  EXPECT_TRUE(r.restarted);
  ASSERT_TRUE(r.gap);
  EXPECT_EQ(r.gap->first, 0u);
  EXPECT_EQ(r.gap->last, 1u);
  EXPECT_EQ(t.lost(), 5u);
  EXPECT_EQ(t.received(), 4u);
  EXPECT_EQ(t.restarts(), 1u);
  EXPECT_EQ(t.duplicates(), 1u);
}

TEST(Session, GetInfoSetSpeedAndConfigOverPty) {
  ModuleOnPty m;
  const auto info = m.session.get_info();
  EXPECT_EQ(info.device_id, 0x0000DE70u);
  EXPECT_EQ(info.protocol_version, wire::kProtocolVersion);
  m.session.set_speed(4200);
  EXPECT_EQ(m.module.speed(), 4200);
  m.session.set_config(static_cast<uint8_t>(wire::ConfigKey::SamplePeriodMs), 2000);
  EXPECT_EQ(m.session.get_config(static_cast<uint8_t>(wire::ConfigKey::SamplePeriodMs)).value, 2000);
  m.session.ack_alarm();
  // Samples kept flowing while we talked; none was mistaken for a reply, none lost.
  auto ev = m.session.next_sample(Millis(500));
  ASSERT_TRUE(ev);
  EXPECT_EQ(m.session.tracker().lost(), 0u);
}

TEST(Session, NackCarriesTheCodeNameInTheError) {
  ModuleOnPty m;
  // Bypass the host-side range check to see the module's refusal: SET_CONFIG with a bad value.
  const uint8_t payload[5] = {0x01, 0x01, 0x00, 0x00, 0x00};  // sample_period_ms = 1 ms
  try {
    m.session.request(wire::MsgType::SetConfig, payload, std::nullopt);
    FAIL() << "expected a NACK";
  } catch (const NackError& e) {
    EXPECT_EQ(e.code(), static_cast<uint8_t>(wire::Nack::BadValue));
    EXPECT_NE(std::string(e.what()).find("BAD_VALUE"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("SET_CONFIG"), std::string::npos) << e.what();
  }
  // Host-side checks refuse before sending.
  EXPECT_THROW(m.session.set_config(0x01, 1), LinkError);
  EXPECT_THROW(m.session.set_speed(60001), LinkError);
}

TEST(Session, SilentModuleTimesOutAfterRetries) {
  test::PtyPair pty;  // nobody on the master side
  SerialTransport t(pty.path);
  SessionOptions so;
  so.reply_timeout = Millis(50);
  so.retries = 2;
  Session s(t, so);
  try {
    s.get_info();
    FAIL() << "expected a timeout";
  } catch (const LinkError& e) {
    EXPECT_EQ(e.kind(), LinkErrorKind::kTimeout);
    EXPECT_NE(std::string(e.what()).find("3 attempts"), std::string::npos) << e.what();
  }
}

TEST(SerialTransport, MissingDeviceAndHangUpAreClearErrors) {
  try {
    SerialTransport t("/dev/does-not-exist-btsm");
    FAIL();
  } catch (const LinkError& e) {
    EXPECT_EQ(e.kind(), LinkErrorKind::kNoDevice);
    EXPECT_NE(std::string(e.what()).find("/dev/does-not-exist-btsm"), std::string::npos);
  }
  auto pty = std::make_unique<test::PtyPair>();
  SerialTransport t(pty->path);
  ::close(pty->slave);
  pty->slave = -1;
  pty->close_master();  // the simulator (or USB adapter) went away
  uint8_t buf[8];
  try {
    for (int i = 0; i < 10; ++i) t.read(buf, Millis(100));
    FAIL() << "expected device gone";
  } catch (const LinkError& e) {
    EXPECT_EQ(e.kind(), LinkErrorKind::kDeviceGone) << e.what();
  }
}

TEST(Record, WritesCsvThatReadsBackSampleForSample) {
  FakeModuleOptions o = RecordSetup::streaming();
  o.first_sample_index = 100;
  RecordSetup r(o);
  auto& m = r.m;
  const std::string& path = r.path;
  EXPECT_TRUE(r.id.roles.from_module);
  r.ro.max_samples = 40;
  const RecordSummary sum = record(m.session, r.id, r.ro);
  EXPECT_EQ(sum.rows, 40u);
  EXPECT_EQ(sum.lost, 0u);

  const thermal::Recording rec = thermal::read_recording_csv(path);
  ASSERT_EQ(rec.rows(), 40u);
  EXPECT_EQ(rec.channels, (std::vector<std::string>{"T1", "T2", "T3", "T5"}));
  EXPECT_EQ(rec.meta_value("module_id"), "0000de70");
  EXPECT_EQ(rec.meta_value("firmware_version"), "0.9.1");
  EXPECT_EQ(rec.meta_value("lost_samples"), "0");
  EXPECT_NE(rec.meta_value("channel_roles").find("T4=ambient"), std::string::npos);
  // Rows are consecutive samples, 5 s of module time apart (no gap, nothing invented).
  for (size_t r = 1; r < rec.rows(); ++r) EXPECT_DOUBLE_EQ(rec.time_s[r] - rec.time_s[r - 1], 5.0);
  // Every row equals the module's sample: recover its index from T1 (pattern in sample_for).
  for (size_t r = 0; r < rec.rows(); ++r) {
    bool matched = false;
    for (uint32_t idx = 100; idx < 100 + m.module.samples_sent() + 5 && !matched; ++idx) {
      const auto s = FakeModule::sample_for(idx, 0, 5000);
      if (std::abs(rec.temp_c(static_cast<long>(r), 0) - s.temp_mK[0] / 1000.0) > 1e-9) continue;
      if (std::abs(rec.ambient_c[r] - s.temp_mK[3] / 1000.0) > 1e-9) continue;
      if (std::abs(rec.temp_c(static_cast<long>(r), 1) - s.temp_mK[1] / 1000.0) > 1e-9) continue;
      matched = true;
      if (s.temp_mK[4] == wire::kMissing) EXPECT_TRUE(std::isnan(rec.temp_c(static_cast<long>(r), 3)));
      else EXPECT_NEAR(rec.temp_c(static_cast<long>(r), 3), s.temp_mK[4] / 1000.0, 1e-9);
    }
    EXPECT_TRUE(matched) << "row " << r;
  }
}

// A module that falls silent ends the recording with an error, but the rows already written stay,
// and the summary lines say why it ended.
TEST(Record, LostLinkKeepsTheRowsAndWritesTheReason) {
  RecordSetup r;
  r.ro.sample_timeout_s = 0.5;
  r.ro.progress = [&](const RecordProgress& p) {
    if (p.rows == 15) r.m.module.set_streaming(false);
  };
  EXPECT_THROW(record(r.m.session, r.id, r.ro), LinkError);
  const thermal::Recording rec = thermal::read_recording_csv(r.path);
  EXPECT_GE(rec.rows(), 15u);
  EXPECT_EQ(rec.meta_value("stop_reason").rfind("link lost: ", 0), 0u) << rec.meta_value("stop_reason");
  EXPECT_EQ(rec.meta_value("samples"), std::to_string(rec.rows()));
}

TEST(Record, GapsBecomeDroppedLinesAndNeverRows) {
  RecordSetup r;
  // Lose samples on purpose: read a few, stop reading while the module streams on, then record.
  // The pty buffer keeps everything, so instead simulate loss with a module restart: the tracker
  // sees the index go back and reports the restart; time stays increasing.
  r.ro.max_samples = 30;
  std::atomic<bool> restarted{false};
  r.ro.progress = [&](const RecordProgress& p) {
    if (p.rows == 10 && !restarted) {
      r.m.module.restart();
      restarted = true;
    }
  };
  const RecordSummary sum = record(r.m.session, r.id, r.ro);
  EXPECT_EQ(sum.rows, 30u);
  EXPECT_EQ(sum.restarts, 1u);
  const thermal::Recording rec = thermal::read_recording_csv(r.path);  // throws on non-increasing time
  EXPECT_EQ(rec.rows(), 30u);
  EXPECT_EQ(rec.meta_value("module_restarts"), "1");
}

TEST(Monitor, LineShowsTemperaturesPredictionsAndFaults) {
  ChannelRoles roles;
  for (uint8_t i = 0; i < wire::kChannels; ++i) roles.role[i] = static_cast<uint8_t>(wire::default_channel_role(i));
  auto s = FakeModule::sample_for(3, 6000, 5000);  // index 3: channel 5 open
  s.predicted_mK[0] = 21500;
  s.overall |= wire::kOverallModelActive;
  const std::string line = format_sample_line(s, roles);
  EXPECT_NE(line.find("6000 rpm"), std::string::npos) << line;
  EXPECT_NE(line.find("(pred  21.500)"), std::string::npos) << line;
  EXPECT_NE(line.find("SENSOR_FAULT/open"), std::string::npos) << line;
  EXPECT_NE(line.find("model"), std::string::npos) << line;
  s.channel_status[1] = wire::kFaultKalmanReject;  // state NORMAL, reading rejected as an outlier
  EXPECT_NE(format_sample_line(s, roles).find("| T2 "), std::string::npos);
  EXPECT_NE(format_sample_line(s, roles).find("NORMAL/outlier"), std::string::npos) << format_sample_line(s, roles);
  roles.role[4] = static_cast<uint8_t>(wire::ChannelRole::Disabled);
  EXPECT_EQ(format_sample_line(s, roles).find("T5"), std::string::npos);
}
