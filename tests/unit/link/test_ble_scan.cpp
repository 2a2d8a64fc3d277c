// Parsing of HCI LE advertising reports (the scan itself needs an adapter and privileges).
#include "host/link/ble_scan.hpp"

#include <gtest/gtest.h>

using namespace btsm::link;

TEST(BleScan, ParsesAdvertisingReportsNamesAndUuids) {
  // subevent 0x02, 1 report: ADV_IND, public, addr C8:A0:30:F1:02:03 (LE on the wire), data, rssi -60
  std::vector<uint8_t> ev = {0x02, 0x01, 0x00, 0x00, 0x03, 0x02, 0xF1, 0x30, 0xA0, 0xC8};
  const std::vector<uint8_t> data = {0x02, 0x01, 0x06,                          // flags
                                     0x03, 0x03, 0xB0, 0xDF,                    // 16-bit UUID 0xDFB0
                                     0x06, 0x09, 'B', 'l', 'u', 'n', 'o'};      // complete name
  ev.push_back(static_cast<uint8_t>(data.size()));
  ev.insert(ev.end(), data.begin(), data.end());
  ev.push_back(static_cast<uint8_t>(-60));
  std::map<std::string, BleAdvertiser> found;
  ASSERT_TRUE(parse_le_advertising_event(ev, found));
  ASSERT_EQ(found.size(), 1u);
  const auto& a = found.begin()->second;
  EXPECT_EQ(a.address, "C8:A0:30:F1:02:03");
  EXPECT_EQ(a.name, "Bluno");
  EXPECT_EQ(a.rssi_dbm, -60);
  ASSERT_EQ(a.services.size(), 1u);
  EXPECT_EQ(a.services[0], btsm::link::att::Uuid::from16(0xDFB0));
  EXPECT_TRUE(a.looks_like_module());
  // Every truncation is rejected or parsed without reading past the end (ASan would tell).
  for (size_t n = 0; n < ev.size(); ++n) {
    std::map<std::string, BleAdvertiser> f;
    EXPECT_FALSE(parse_le_advertising_event(std::span<const uint8_t>(ev.data(), n), f)) << n;
  }
  // A malformed AD structure length stops parsing of that payload only.
  BleAdvertiser adv;
  const std::vector<uint8_t> broken = {0x05, 0x09, 'a'};
  parse_advertising_data(broken, adv);
  EXPECT_TRUE(adv.name.empty());
}
