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

#include <chrono>
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
  }
}
