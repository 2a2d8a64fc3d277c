// ATT PDU codecs and the GATT client against the in-process fake peripheral.
#include "fake_peripheral.hpp"
#include "host/link/gatt_client.hpp"

#include <gtest/gtest.h>

#include <sys/socket.h>
#include <unistd.h>

using namespace btsm::link;
using namespace btsm::link::att;
using btsm::test::FakePeripheral;

namespace {
std::pair<int, int> seqpacket_pair() {
  int sv[2];
  if (::socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv) != 0) throw std::runtime_error("socketpair");
  return {sv[0], sv[1]};
}
}  // namespace

TEST(AttPdu, UuidParsingAndPrinting) {
  EXPECT_EQ(Uuid::parse("2a24")->str(), "0x2a24");
  EXPECT_EQ(Uuid::parse("0x180A")->short16(), 0x180A);
  const auto nus = Uuid::parse("6E400001-B5A3-F393-E0A9-E50E24DCCA9E");
  ASSERT_TRUE(nus);
  EXPECT_FALSE(nus->is16());
  EXPECT_EQ(nus->str(), "6e400001-b5a3-f393-e0a9-e50e24dcca9e");
  EXPECT_EQ(nus->to_le().size(), 16u);
  EXPECT_EQ(nus->to_le()[0], 0x9E);  // little-endian on the wire
  EXPECT_EQ(Uuid::parse("0000180a-0000-1000-8000-00805f9b34fb"), Uuid::from16(0x180A));
  EXPECT_FALSE(Uuid::parse("12345"));
  EXPECT_FALSE(Uuid::parse("6e400001-b5a3-f393-e0a9-e50e24dcca9"));
  EXPECT_FALSE(Uuid::parse("zz24"));
}

TEST(AttPdu, CodecPairsRoundTripAndRejectMalformed) {
  TypedRangeReq r{{5, 0x20}, Uuid::from16(0x2803)};
  TypedRangeReq back;
  ASSERT_TRUE(decode_typed_range(encode_typed_range(kReadByTypeReq, r), kReadByTypeReq, back));
  EXPECT_EQ(back.range.start, 5);
  EXPECT_EQ(back.range.end, 0x20);
  EXPECT_EQ(back.type, r.type);
  EXPECT_FALSE(decode_typed_range(encode_typed_range(kReadByTypeReq, r), kReadByGroupTypeReq, back));

  std::vector<GroupRecord> svcs = {{1, 5, Uuid::from16(0x1800)}, {6, 9, Uuid::from16(0x180A)},
                                   {10, 20, *Uuid::parse("6e400001-b5a3-f393-e0a9-e50e24dcca9e")}};
  size_t taken = 0;
  const Pdu rsp = encode_read_by_group_rsp(svcs, 23, taken);
  EXPECT_EQ(taken, 2u);  // the 128-bit one needs its own response
  std::vector<GroupRecord> got;
  ASSERT_TRUE(decode_read_by_group_rsp(rsp, got));
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[1].end, 9);
  // Every truncation is rejected unless it ends on a record boundary (then it is a shorter
  // valid response); nothing is read past the end.
  for (size_t n = 0; n < rsp.size(); ++n) {
    Pdu cut(rsp.begin(), rsp.begin() + static_cast<long>(n));
    const bool whole_records = n > 2 && (n - 2) % 6 == 0;
    EXPECT_EQ(decode_read_by_group_rsp(cut, got), whole_records) << n;
  }
  ErrorRsp e{kReadByTypeReq, 0x0010, kAttributeNotFound}, e2;
  ASSERT_TRUE(decode_error_rsp(encode_error_rsp(e), e2));
  EXPECT_EQ(e2.handle, 0x0010);
  EXPECT_EQ(e2.code, kAttributeNotFound);
  CharDeclaration d{kPropNotify | kPropWrite, 0x0025, Uuid::from16(0xDFB1)}, d2;
  ASSERT_TRUE(decode_char_declaration(encode_char_declaration(d), d2));
  EXPECT_EQ(d2.value_handle, 0x0025);
  EXPECT_EQ(d2.uuid, Uuid::from16(0xDFB1));
}

TEST(GattClient, DiscoversTheWholeBlunoDatabase) {
  FakePeripheral p;
  uint16_t serial = 0, command = 0;
  FakePeripheral::make_bluno(p, serial, command);
  auto [client_fd, server_fd] = seqpacket_pair();
  p.start(server_fd);
  GattClient c(client_fd, "fake", Millis(1000));
  EXPECT_EQ(c.exchange_mtu(247), 23);  // the CC2540 keeps the default
  const GattDatabase db = c.discover_all();
  ASSERT_EQ(db.services.size(), 3u);
  EXPECT_EQ(db.services[2].uuid, Uuid::from16(0xDFB0));
  const auto* ch = db.find(Uuid::from16(0xDFB1));
  ASSERT_NE(ch, nullptr);
  EXPECT_EQ(ch->value_handle, serial);
  EXPECT_NE(ch->cccd_handle(), 0);
  EXPECT_EQ(ch->descriptors.size(), 2u);  // user description + CCCD
  EXPECT_TRUE(ch->can(kPropNotify));
  const auto* cmd = db.find(Uuid::from16(0xDFB2));
  ASSERT_NE(cmd, nullptr);
  EXPECT_EQ(cmd->value_handle, command);
  EXPECT_EQ(cmd->end_handle, db.services[2].end);
  const auto model = c.read(db.find(Uuid::from16(0x2A24))->value_handle);
  EXPECT_EQ(std::string(model.begin(), model.end()), "DF Bluno");
  ::close(client_fd);
  p.stop();
}

TEST(GattClient, CccdEnableNotificationsAndChunkedWrites) {
  FakePeripheral p;
  uint16_t serial = 0;
  FakePeripheral::make_hm10(p, serial);
  p.set_server_mtu(100);
  auto [client_fd, server_fd] = seqpacket_pair();
  p.start(server_fd);
  GattClient c(client_fd, "fake", Millis(1000));
  EXPECT_EQ(c.exchange_mtu(64), 64);
  const auto db = c.discover_all();
  const auto* ch = db.find(Uuid::from16(0xFFE1));
  ASSERT_NE(ch, nullptr);
  EXPECT_FALSE(p.notifications_enabled(serial));
  EXPECT_FALSE(p.notify(serial, {1, 2, 3}));  // not yet enabled: nothing sent
  c.enable_notifications(ch->cccd_handle());
  EXPECT_TRUE(p.notifications_enabled(serial));

  std::vector<uint8_t> got;
  c.on_notification([&](uint16_t h, std::span<const uint8_t> v) {
    EXPECT_EQ(h, serial);
    got.insert(got.end(), v.begin(), v.end());
  });
  ASSERT_TRUE(p.notify(serial, {1, 2, 3}));
  ASSERT_TRUE(p.notify(serial, {4, 5}));
  for (int i = 0; i < 20 && got.size() < 5; ++i) c.poll(Millis(50));
  EXPECT_EQ(got, (std::vector<uint8_t>{1, 2, 3, 4, 5}));

  std::vector<uint8_t> data(150);
  for (size_t i = 0; i < data.size(); ++i) data[i] = static_cast<uint8_t>(i);
  c.write_chunked(serial, data, true);
  std::vector<uint8_t> joined;
  size_t pieces = 0;
  for (const auto& w : p.writes()) {
    if (w.handle != serial) continue;
    EXPECT_LE(w.value.size(), 61u);  // MTU 64 - 3
    EXPECT_EQ(w.opcode, kWriteReq);
    joined.insert(joined.end(), w.value.begin(), w.value.end());
    ++pieces;
  }
  EXPECT_EQ(pieces, 3u);
  EXPECT_EQ(joined, data);
  ::close(client_fd);
  p.stop();
}

TEST(GattClient, ErrorsNameTheHandleAndDeadPeerIsDeviceGone) {
  FakePeripheral p;
  uint16_t serial = 0;
  FakePeripheral::make_hm10(p, serial);
  auto [client_fd, server_fd] = seqpacket_pair();
  p.start(server_fd);
  GattClient c(client_fd, "fake", Millis(500));
  try {
    c.read(0x0777);
    FAIL();
  } catch (const AttError& e) {
    EXPECT_EQ(e.code(), kInvalidHandle);
    EXPECT_NE(std::string(e.what()).find("0x0777"), std::string::npos);
  }
  p.disconnect();  // the module went out of range
  try {
    c.read(serial);
    FAIL();
  } catch (const LinkError& e) {
    EXPECT_EQ(e.kind(), LinkErrorKind::kDeviceGone) << e.what();
  }
  ::close(client_fd);
}
