// Byte-order helpers and CRC check values.
#include <gtest/gtest.h>

#include <cstring>

#include "common/byte_order.hpp"
#include "common/crc.hpp"

namespace btsm {
namespace {

const uint8_t kCheckInput[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};

TEST(ByteOrder, Le16IsLittleEndianAndRoundTrips) {
  uint8_t b[2];
  put_le16(b, 0xA1B2);
  EXPECT_EQ(b[0], 0xB2);
  EXPECT_EQ(b[1], 0xA1);
  for (uint32_t v = 0; v <= 0xFFFF; v += 257) {
    put_le16(b, static_cast<uint16_t>(v));
    EXPECT_EQ(get_le16(b), v);
  }
}

TEST(ByteOrder, Le24SignedExtremesAndSignExtension) {
  uint8_t b[3];
  const int32_t values[] = {0, 1, -1, kInt24Min, kInt24Max, 123456, -123456, -8388607};
  for (int32_t v : values) {
    put_le24(b, v);
    EXPECT_EQ(get_le24s(b), v) << v;
  }
  put_le24(b, -2);
  EXPECT_EQ(b[0], 0xFE);
  EXPECT_EQ(b[1], 0xFF);
  EXPECT_EQ(b[2], 0xFF);
  const uint8_t min_bytes[] = {0x00, 0x00, 0x80};
  EXPECT_EQ(get_le24s(min_bytes), -8388608);
  EXPECT_EQ(get_le24u(min_bytes), 0x800000u);
}

TEST(ByteOrder, Le32AndFloat) {
  uint8_t b[4];
  put_le32(b, 0x01020304u);
  EXPECT_EQ(b[0], 0x04);
  EXPECT_EQ(b[3], 0x01);
  EXPECT_EQ(get_le32(b), 0x01020304u);
  put_le_f32(b, 1.0f);  // 0x3F800000
  EXPECT_EQ(b[0], 0x00);
  EXPECT_EQ(b[2], 0x80);
  EXPECT_EQ(b[3], 0x3F);
  const float values[] = {0.0f, -0.0f, 1.5f, -273.15f, 3.4e38f, 1e-40f};
  for (float v : values) {
    put_le_f32(b, v);
    const float back = get_le_f32(b);
    EXPECT_EQ(std::memcmp(&back, &v, 4), 0) << v;
  }
}

TEST(Crc16, CcittFalseCheckValue) {
  EXPECT_EQ(crc16_ccitt(kCheckInput, sizeof kCheckInput), 0x29B1);
  EXPECT_EQ(crc16_ccitt(nullptr, 0), 0xFFFF);
}

TEST(Crc16, ChainsAcrossSplits) {
  for (size_t split = 0; split <= sizeof kCheckInput; ++split) {
    const uint16_t first = crc16_ccitt(kCheckInput, split);
    EXPECT_EQ(crc16_ccitt(kCheckInput + split, sizeof kCheckInput - split, first), 0x29B1);
  }
}

TEST(Crc16, DetectsEverySingleBitError) {
  uint8_t msg[60];
  for (size_t i = 0; i < sizeof msg; ++i) msg[i] = static_cast<uint8_t>(i * 37 + 11);
  const uint16_t good = crc16_ccitt(msg, sizeof msg);
  for (size_t i = 0; i < sizeof msg; ++i) {
    for (int bit = 0; bit < 8; ++bit) {
      msg[i] ^= static_cast<uint8_t>(1u << bit);
      EXPECT_NE(crc16_ccitt(msg, sizeof msg), good);
      msg[i] ^= static_cast<uint8_t>(1u << bit);
    }
  }
}

TEST(Crc32, IeeeCheckValue) {
  EXPECT_EQ(crc32(kCheckInput, sizeof kCheckInput), 0xCBF43926u);
  EXPECT_EQ(crc32(nullptr, 0), 0u);
  const uint8_t zeros[4] = {0, 0, 0, 0};
  EXPECT_EQ(crc32(zeros, 4), 0x2144DF1Cu);
}

TEST(Crc32, ChainsAcrossSplits) {
  for (size_t split = 0; split <= sizeof kCheckInput; ++split) {
    const uint32_t first = crc32(kCheckInput, split);
    EXPECT_EQ(crc32(kCheckInput + split, sizeof kCheckInput - split, first), 0xCBF43926u);
  }
}

}  // namespace
}  // namespace btsm
