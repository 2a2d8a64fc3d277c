// The BLE serial transport end to end: fake peripheral (Bluno / NUS / HM-10 database) bridged to
// the fake module, the protocol session on top. Frames arrive split into 20-byte notifications
// and leave in writes of at most MTU-3 bytes.
#include "common/wire_frame.hpp"
#include "fake_module.hpp"
#include "fake_peripheral.hpp"
#include "host/link/ble_transport.hpp"
#include "host/link/model_flash.hpp"
#include "host/link/session.hpp"

#include <gtest/gtest.h>

#include <sys/socket.h>
#include <unistd.h>

using namespace btsm;
using namespace btsm::link;
using btsm::test::FakeModule;
using btsm::test::FakeModuleOptions;
using btsm::test::FakePeripheral;

namespace {

enum class Db { kBluno, kNus, kHm10 };

// Peripheral with database `db`, its serial characteristic bridged to a fake module.
struct BleRig {
  FakePeripheral peripheral;
  std::unique_ptr<FakeModule> module;
  uint16_t tx = 0, rx = 0, command = 0;
  int client_fd = -1;
  explicit BleRig(Db db, FakeModuleOptions o = {}, const std::string& model = "DF Bluno") {
    switch (db) {
      case Db::kBluno: FakePeripheral::make_bluno(peripheral, tx, command, model); rx = tx; break;
      case Db::kNus: FakePeripheral::make_nus(peripheral, tx, rx); break;
      case Db::kHm10: FakePeripheral::make_hm10(peripheral, tx); rx = tx; break;
    }
    int stream[2];
    if (::socketpair(AF_UNIX, SOCK_STREAM, 0, stream) != 0) throw std::runtime_error("socketpair");
    module = std::make_unique<FakeModule>(stream[1], o);
    // Bridge: writes to tx go to the module; module bytes come back as notifications of rx.
    peripheral.bridge(tx, rx, stream[0]);
    int att[2];
    if (::socketpair(AF_UNIX, SOCK_SEQPACKET, 0, att) != 0) throw std::runtime_error("socketpair");
    client_fd = att[0];
    peripheral.start(att[1]);
    module->start();
  }
  ~BleRig() {
    module->stop();
    peripheral.stop();
  }
  std::function<int()> connector() {
    return [this] {
      const int fd = client_fd;
      client_fd = -1;
      if (fd < 0) throw LinkError(LinkErrorKind::kNoDevice, "fake: already connected once");
      return fd;
    };
  }
};

SessionOptions fast() {
  SessionOptions so;
  so.reply_timeout = Millis(500);
  so.retries = 2;
  return so;
}

}  // namespace

TEST(GattSerial, BlunoSetupSequenceAndProtocolOverNotifications) {
  FakeModuleOptions o;
  o.sample_period = Millis(5);
  BleRig rig(Db::kBluno, o);
  GattSerialTransport t(rig.connector(), "BLE fake");
  EXPECT_EQ(t.profile().kind, BleProfileKind::kBluno);
  EXPECT_EQ(t.max_write_size(), 20u);
  // The DFRobot connect sequence reached the command characteristic, in order.
  std::string at;
  for (const auto& w : rig.peripheral.writes())
    if (w.handle == rig.command) at.append(w.value.begin(), w.value.end());
  EXPECT_EQ(at, "AT+PASSWOR=DFRobot\r\nAT+CURRUART=115200\r\n");
  EXPECT_TRUE(rig.peripheral.notifications_enabled(rig.tx));

  Session s(t, fast());
  const auto info = s.get_info();
  EXPECT_EQ(info.device_id, 0x0000DE70u);
  // SAMPLE frames (~60 bytes on the wire) arrive as three or four notifications each.
  for (int i = 0; i < 10; ++i) {
    auto ev = s.next_sample(Millis(1000));
    ASSERT_TRUE(ev);
  }
  EXPECT_EQ(s.tracker().lost(), 0u);
  EXPECT_EQ(s.frame_counters().frame_errors(), 0u);
}

TEST(GattSerial, FlashModelOverBleUsesTwentyByteWrites) {
  FakeModuleOptions o;
  o.sample_period = Millis(50);
  BleRig rig(Db::kBluno, o);
  GattSerialTransport t(rig.connector(), "BLE fake");
  Session s(t, fast());
  const auto blob = test::make_test_blob(4);
  const auto sum = flash_model(s, blob, test::fake_module_key());
  EXPECT_TRUE(sum.verified);
  EXPECT_EQ(rig.module->active_model(), blob);
  size_t writes = 0;
  for (const auto& w : rig.peripheral.writes()) {
    if (w.handle != rig.tx) continue;
    ++writes;
    EXPECT_LE(w.value.size(), 20u);
    EXPECT_EQ(w.opcode, link::att::kWriteCmd);  // Bluno serial supports write without response
  }
  EXPECT_GE(writes, sum.chunks);
}

TEST(GattSerial, NordicUartPicksCharacteristicsByProperties) {
  BleRig rig(Db::kNus);
  GattSerialTransport t(rig.connector(), "BLE fake");
  EXPECT_EQ(t.profile().kind, BleProfileKind::kNordicUart);
  EXPECT_EQ(t.profile().tx_handle, rig.tx);
  EXPECT_EQ(t.profile().rx_handle, rig.rx);
  EXPECT_TRUE(rig.peripheral.notifications_enabled(rig.rx));
  // Bytes notified on the RX characteristic come out of read().
  ASSERT_TRUE(rig.peripheral.notify(rig.rx, {0x7E, 0x01, 0x02}));
  uint8_t buf[8];
  size_t n = 0;
  for (int i = 0; i < 20 && n == 0; ++i) n = t.read(buf, Millis(50));
  ASSERT_EQ(n, 3u);
  EXPECT_EQ(buf[0], 0x7E);
}

TEST(GattSerial, Hm10WritesWithResponseWhenNoWriteCommand) {
  BleRig rig(Db::kHm10);
  GattSerialTransport t(rig.connector(), "BLE fake");
  EXPECT_EQ(t.profile().kind, BleProfileKind::kHm10);
  EXPECT_TRUE(t.profile().tx_with_response);
  Session s(t, fast());
  EXPECT_EQ(s.get_info().device_id, 0x0000DE70u);
}

TEST(GattSerial, UnknownDatabaseAndFakeBlunoAreRefusedWithReasons) {
  {
    FakePeripheral p;
    p.add_service(link::att::Uuid::from16(0x1800));
    p.add_characteristic(link::att::Uuid::from16(0x2A00), link::att::kPropRead, {'x'});
    int att[2];
    ASSERT_EQ(::socketpair(AF_UNIX, SOCK_SEQPACKET, 0, att), 0);
    p.start(att[1]);
    try {
      GattSerialTransport t([&] { return att[0]; }, "BLE fake");
      FAIL();
    } catch (const LinkError& e) {
      EXPECT_EQ(e.kind(), LinkErrorKind::kUnsupported);
      EXPECT_NE(std::string(e.what()).find("0x1800"), std::string::npos) << e.what();
    }
    p.stop();
  }
  {
    BleRig rig(Db::kBluno, {}, "HMSoft");
    try {
      GattSerialTransport t(rig.connector(), "BLE fake");
      FAIL();
    } catch (const LinkError& e) {
      EXPECT_EQ(e.kind(), LinkErrorKind::kUnsupported);
      EXPECT_NE(std::string(e.what()).find("HMSoft"), std::string::npos) << e.what();
    }
  }
}

TEST(BleAddress, ParsesTypeSuffixAndRejectsGarbage) {
  EXPECT_EQ(parse_ble_address("C8:A0:30:F1:02:03").type, BleAddressType::kPublic);
  EXPECT_EQ(parse_ble_address("C8:A0:30:F1:02:03/random").type, BleAddressType::kRandom);
  EXPECT_THROW(parse_ble_address("C8:A0:30:F1:02"), LinkError);
  EXPECT_THROW(parse_ble_address("C8:A0:30:F1:02:0G"), LinkError);
  EXPECT_THROW(parse_ble_address("C8:A0:30:F1:02:03/foo"), LinkError);
}
