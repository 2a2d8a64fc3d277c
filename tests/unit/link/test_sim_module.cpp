// The link against the real simulated module (native firmware core + AD7794 model + spindle
// plant behind a pty): record, and a model upload with the development key and read-back.
#include "host/sim/runner/sim_module.hpp"
#include "fake_module.hpp"
#include "host/link/model_flash.hpp"
#include "host/link/recorder.hpp"
#include "host/link/serial_transport.hpp"
#include "host/thermal/recording.hpp"
#include "link_test_support.hpp"

#include <gtest/gtest.h>

#include <iostream>

#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

using namespace btsm;
using namespace btsm::link;

namespace {
std::unique_ptr<sim::SimModule> start_sim(const std::string& pty) {
  sim::SimModuleOptions o;
  o.board = sim::BoardKind::Native;
  o.pty_path = pty;
  o.plant.speed = sim::SpeedProfile::parse("2h@6000");
  auto m = std::make_unique<sim::SimModule>(o);
  m->start();
  return m;
}
}  // namespace

TEST(SimModuleLink, RecordsSamplesFromTheSimulatedFirmware) {
  test::TempDir dir;
  auto sim = start_sim(dir.path + "/btsm-sim");
  SerialTransport t(dir.path + "/btsm-sim");
  Session s(t);
  const ModuleIdentity id = identify(s);
  EXPECT_EQ(id.info.device_id, 0x0000DE70u);
  RecordOptions ro;
  ro.out_path = dir.path + "/rec.csv";
  ro.max_samples = 12;
  ro.reconnect_s = 0;
  const auto sum = record(s, id, ro);
  EXPECT_EQ(sum.rows, 12u);
  EXPECT_EQ(sum.lost, 0u);
  const auto rec = thermal::read_recording_csv(ro.out_path);
  ASSERT_EQ(rec.rows(), 12u);
  for (size_t r = 0; r < rec.rows(); ++r) {
    EXPECT_GT(rec.ambient_c[r], 0.0);
    EXPECT_LT(rec.ambient_c[r], 60.0);
  }
  EXPECT_TRUE(sim->error().empty()) << sim->error();
}

TEST(SimModuleLink, FlashesAModelWithTheDevelopmentKey) {
  test::TempDir dir;
  auto sim = start_sim(dir.path + "/btsm-sim");
  SerialTransport t(dir.path + "/btsm-sim");
  Session s(t);
  DeviceKey key{};
  for (uint8_t i = 0; i < 32; ++i) key[i] = i;  // device_key::dev_key_byte
  const auto blob = test::make_test_blob(2);
  const auto sum = flash_model(s, blob, key);
  EXPECT_TRUE(sum.verified);
  EXPECT_LE(sum.max_chunk_frame, 20u);
  DeviceKey wrong = key;
  wrong[0] ^= 1;
  try {
    flash_model(s, test::make_test_blob(3), wrong);
    FAIL();
  } catch (const NackError& e) {
    EXPECT_EQ(e.code(), static_cast<uint8_t>(wire::Nack::AuthFailed));
  }
  EXPECT_EQ(read_model(s, blob.size()), blob);
}

namespace {
bool ends_within(sim::SimModule& m, double seconds) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < until) {
    if (!m.running()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return !m.running();
}
}  // namespace

TEST(SimModuleLink, EndsWhenItsHostClosedThePortAndNoneCameBack) {
  test::TempDir dir;
  sim::SimModuleOptions o;
  o.pty_path = dir.path + "/btsm-sim";
  o.plant.speed = sim::SpeedProfile::parse("10h@6000");
  o.time_scale = 600;  // 10 h would take a minute: the end must come from the rule, not the duration
  o.host_gone_exit_s = 0.5;
  sim::SimModule m(o);
  m.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  EXPECT_TRUE(m.running()) << "before any host opened the port it waits";
  {
    SerialTransport t(o.pty_path);
    Session s(t);
    identify(s);
  }  // the host (a record stopped early) goes away
  ASSERT_TRUE(ends_within(m, 5.0));
  EXPECT_TRUE(m.stats().ended_host_gone);
  EXPECT_LT(m.sim_time_s(), 3600.0);
  EXPECT_TRUE(m.error().empty()) << m.error();

  // Without the rule it keeps waiting for a host.
  sim::SimModuleOptions forever = o;
  forever.pty_path = dir.path + "/btsm-sim2";
  forever.host_gone_exit_s = std::numeric_limits<double>::infinity();
  sim::SimModule m2(forever);
  m2.start();
  {
    SerialTransport t(forever.pty_path);
    Session s(t);
    identify(s);
  }
  EXPECT_FALSE(ends_within(m2, 1.5));
  m2.stop();
  EXPECT_FALSE(m2.stats().ended_host_gone);
}

TEST(SimModuleLink, TruthFileNamesWhereTheFifthProbeIs) {
  test::TempDir dir;
  for (auto [mode, expected] : {std::pair{sim::Ch5Mode::ShaftEnd, "T5 shaft end"},
                                std::pair{sim::Ch5Mode::HousingSurface, "T5 housing surface"}}) {
    sim::SimModuleOptions o;
    o.truth_csv = dir.path + "/truth.csv";
    o.plant.ch5 = mode;
    o.plant.speed = sim::SpeedProfile::parse("1h@6000");
    {
      sim::SimModule m(o);
      m.run_for(5);
    }
    const auto truth = thermal::read_recording_csv(o.truth_csv);
    const std::string channels = truth.meta_value("channels");
    EXPECT_NE(channels.find(expected), std::string::npos) << channels;
    if (mode == sim::Ch5Mode::ShaftEnd) {
      EXPECT_EQ(channels.find("housing surface"), std::string::npos) << channels;
    }
    // The roles line a recording carries: `fit --preset spindle4` on a truth file took T4 (the
    // ambient probe) for the shaft without it (probe 5).
    EXPECT_EQ(truth.meta_value("channel_roles"), std::string("T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=") +
                                                     (mode == sim::Ch5Mode::ShaftEnd ? "shaft" : "spare"));
  }
}

// A second module on the link path of a running one takes the link, and says that hosts which
// opened the old one still talk to it (a pasted README block's set-config reached the old module).
TEST(SimModuleLink, ASecondModuleOnALiveLinkSaysSo) {
  test::TempDir dir;
  auto first = start_sim(dir.path + "/btsm-sim");
  std::vector<std::string> said;
  sim::SimModuleOptions o;
  o.pty_path = dir.path + "/btsm-sim";
  o.plant.speed = sim::SpeedProfile::parse("1h@0");
  o.log = [&](const std::string& s) { said.push_back(s); };
  sim::SimModule second(o);
  ASSERT_FALSE(said.empty());
  EXPECT_NE(said[0].find("WARNING: " + o.pty_path + " led to /dev/pts/"), std::string::npos) << said[0];
  EXPECT_NE(said[0].find("another sim-module still running?"), std::string::npos) << said[0];
  // ... and the old module, which no host can open any more, ends by itself (its 2 h profile had
  // hardly begun): a block run again no longer finds the previous module behind the link.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (first->running() && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_FALSE(first->running()) << "the module behind the old link kept running";
}

TEST(SimModuleLink, RecordingSaysWhichFaultEmptiedACell) {
  test::TempDir dir;
  sim::SimModuleOptions o;
  o.pty_path = dir.path + "/btsm-sim";
  o.plant.speed = sim::SpeedProfile::parse("2h@6000");
  o.plant.faults.push_back(sim::parse_fault("open:ch2@100-200"));
  sim::SimModule m(o);
  m.start();
  SerialTransport t(o.pty_path);
  Session s(t);
  const ModuleIdentity id = identify(s);
  RecordOptions ro;
  ro.out_path = dir.path + "/rec.csv";
  ro.max_samples = 70;  // 350 s at 5 s
  ro.reconnect_s = 0;
  const auto sum = record(s, id, ro);
  const auto rec = thermal::read_recording_csv(ro.out_path);  // an older reader: the file reads as before
  const auto faults = thermal::sensor_faults(rec);
  ASSERT_EQ(faults.size(), sum.sensor_faults.size());
  ASSERT_GE(faults.size(), 1u);
  // The open wire is found within the rotating open-wire check (three sweeps) of its start; once
  // it is mended the channel may report SENSOR_FAULT without a fault bit ("fault") until the
  // next check of that channel clears it.
  EXPECT_EQ(faults[0].code, "open");
  EXPECT_GE(faults[0].from_s, 100.0 - 5.0);
  EXPECT_LE(faults[0].from_s, 100.0 + 3 * 5.0);
  EXPECT_GE(faults.back().to_s, 195.0);
  EXPECT_LE(faults.back().to_s, 200.0 + 3 * 5.0);
  for (const auto& f : faults) {
    EXPECT_EQ(f.channel, "T2") << thermal::format_sensor_fault(f);
    EXPECT_TRUE(f.code == "open" || f.code == "fault") << thermal::format_sensor_fault(f);
  }
  // Every empty T2 cell is explained by an episode, and every row of the open episode is empty
  // (the lingering "fault" rows carry a reading again).
  const int t2 = rec.channel_index("T2");
  ASSERT_GE(t2, 0);
  for (size_t k = 0; k < rec.rows(); ++k) {
    bool in_any = false, in_open = false;
    for (const auto& f : faults) {
      const bool in = rec.time_s[k] >= f.from_s && rec.time_s[k] <= f.to_s;
      in_any |= in;
      in_open |= in && f.code == "open";
    }
    const bool empty = std::isnan(rec.temp_c(static_cast<Eigen::Index>(k), t2));
    EXPECT_TRUE(!empty || in_any) << "empty cell without a fault line at " << rec.time_s[k];
    EXPECT_TRUE(!in_open || empty) << rec.time_s[k];
  }
}

// At --time-scale 0.001 one 0.25 s plant step is 250 s of wall time, slept in one piece: Ctrl-C
// and SIGTERM said "stopping" and the run went on for minutes. stop() is heard within a slice.
TEST(SimModuleLink, StopsPromptlyWhenRunningFarSlowerThanRealTime) {
  sim::SimModuleOptions o;
  o.board = sim::BoardKind::Native;
  o.plant.speed = sim::SpeedProfile::parse("1h@6000");
  o.time_scale = 0.001;
  o.wait_for_host = false;
  sim::SimModule m(o);
  m.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ASSERT_TRUE(m.running());
  const auto t0 = std::chrono::steady_clock::now();
  m.stop();
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(waited, 2.0);
  EXPECT_FALSE(m.running());
}
