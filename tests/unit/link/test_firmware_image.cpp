// Intel HEX parsing/writing and patching the per-device key record of common/device_key.hpp.
#include "common/device_key.hpp"
#include "host/link/firmware_image.hpp"

#include <gtest/gtest.h>

using namespace btsm;
using namespace btsm::link;

namespace {
HexImage test_image(bool with_erased_key) {
  HexImage img;
  for (uint32_t a = 0; a < 300; ++a) img.bytes[a] = static_cast<uint8_t>(a * 7);
  if (with_erased_key)
    for (uint32_t a = 0; a < device_key::kRecordSize; ++a) img.bytes[device_key::kFlashAddress + a] = 0xFF;
  return img;
}
}  // namespace

TEST(IntelHex, RoundTripAndChecksums) {
  const HexImage img = test_image(true);
  const std::string text = format_intel_hex(img);
  EXPECT_EQ(text.substr(text.size() - 12), ":00000001FF\n");
  const HexImage back = parse_intel_hex(text, "t.hex");
  EXPECT_EQ(back.bytes, img.bytes);
  // A known record from the Intel spec example.
  const HexImage one = parse_intel_hex(":0300300002337A1E\n:00000001FF\n", "spec");
  EXPECT_EQ(one.bytes.at(0x30), 0x02);
  EXPECT_EQ(one.bytes.at(0x32), 0x7A);
  // Each single-character corruption of a data record is caught with its line number.
  std::string bad = text;
  bad[9] = bad[9] == '0' ? '1' : '0';
  try {
    parse_intel_hex(bad, "bad.hex");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("bad.hex:1"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_intel_hex(":0300300002337A1E\n", "noeof"), std::invalid_argument);
  EXPECT_THROW(parse_intel_hex("0300300002337A1E\n:00000001FF\n", "nocolon"), std::invalid_argument);
  // Two records over one byte: the same value is a harmless repeat, another value makes the image
  // mean two things and is refused at the second record's line.
  EXPECT_EQ(parse_intel_hex(":0300300002337A1E\n:0100300002CD\n:00000001FF\n", "same").bytes.at(0x30), 0x02);
  try {
    parse_intel_hex(":0300300002337A1E\n:01003000557A\n:00000001FF\n", "clash.hex");
    FAIL() << "a byte written twice with different data was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("clash.hex:2"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("0x0030 written twice"), std::string::npos) << e.what();
  }
  // Above 64 KiB an extended linear address record appears.
  HexImage big;
  big.bytes[0x10005] = 0xAB;
  const HexImage big_back = parse_intel_hex(format_intel_hex(big), "big");
  EXPECT_EQ(big_back.bytes.at(0x10005), 0xAB);
}

TEST(KeyPatch, PatchesErasedRecordAndReadsItBack) {
  HexImage img = test_image(true);
  DeviceKey key{};
  for (size_t i = 0; i < key.size(); ++i) key[i] = static_cast<uint8_t>(0xA0 + i);
  const auto r = patch_device_key(img, 0xDE71, key);
  EXPECT_FALSE(r.had_key);
  const auto rec = read_device_key(parse_intel_hex(format_intel_hex(img), "patched"));
  ASSERT_TRUE(rec);
  EXPECT_EQ(rec->device_id, 0xDE71u);
  EXPECT_EQ(rec->key, key);
  // The firmware's own validity check accepts the bytes we wrote.
  uint8_t raw[device_key::kRecordSize];
  for (uint16_t i = 0; i < device_key::kRecordSize; ++i) raw[i] = img.bytes.at(device_key::kFlashAddress + i);
  EXPECT_TRUE(device_key::record_valid(raw));
  // Re-patching replaces a valid record and reports the previous id; code bytes are untouched.
  const auto again = patch_device_key(img, 0xDE72, key);
  EXPECT_TRUE(again.had_key);
  EXPECT_EQ(again.previous_device_id, 0xDE71u);
  EXPECT_EQ(img.bytes.at(10), static_cast<uint8_t>(70));
}

TEST(KeyPatch, RefusesImagesWithoutOrWithForeignRecord) {
  DeviceKey key{};
  HexImage none = test_image(false);
  EXPECT_THROW(patch_device_key(none, 1, key), std::invalid_argument);
  HexImage foreign = test_image(true);
  foreign.bytes[device_key::kFlashAddress + 3] = 0x12;
  EXPECT_THROW(patch_device_key(foreign, 1, key), std::invalid_argument);
}

TEST(Avrdude, CommandUsesTheBlunoUnoSettings) {
  const auto cmd = avrdude_command("/dev/ttyACM0", "/tmp/x.hex");
  const std::vector<std::string> want = {"avrdude", "-p", "atmega328p", "-c", "arduino", "-b", "115200",
                                         "-P", "/dev/ttyACM0", "-D", "-U", "flash:w:/tmp/x.hex:i"};
  EXPECT_EQ(cmd, want);
  EXPECT_EQ(run_command({"true"}), 0);
  EXPECT_EQ(run_command({"false"}), 1);
  EXPECT_THROW(run_command({"/nonexistent/btsm-tool"}), std::runtime_error);
}
