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
