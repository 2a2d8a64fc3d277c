// Framing: encoder layout, decoder acceptance rules, counters, sizes and the '+' guarantee.
#include <gtest/gtest.h>

#include <random>

#include "wire_test_support.hpp"

namespace btsm::wire {
namespace {

using testing::Bytes;
using testing::feed;
using testing::RawFrame;

TEST(WireFrame, EncoderLayoutIsFlagStuffedRawFlag) {
  const Bytes payload = {0x10, 0x7E, 0x2B, 0x7D, 0x20};
  const Bytes wire = testing::encode(0x41, 0x05, payload);
  const RawFrame raw = testing::raw_of(kProtocolVersion, 0x41, 0x05, payload);
  ASSERT_EQ(raw.raw.size(), 4u + payload.size() + 2u);
  EXPECT_EQ(raw.raw[0], kProtocolVersion);
  EXPECT_EQ(raw.raw[3], payload.size());
  EXPECT_EQ(get_le16(raw.raw.data() + raw.raw.size() - 2),
            crc16_ccitt(raw.raw.data(), raw.raw.size() - 2));
  EXPECT_EQ(wire, testing::stuff(raw.raw));
  // The three reserved payload bytes appear escaped.
  const Bytes expected_middle = {0x10, 0x7D, 0x5E, 0x7D, 0x0B, 0x7D, 0x5D, 0x20};
  EXPECT_EQ(Bytes(wire.begin() + 5, wire.begin() + 5 + 8), expected_middle);
  EXPECT_EQ(wire.front(), kFlag);
  EXPECT_EQ(wire.back(), kFlag);
  EXPECT_EQ(encoded_frame_size(0x41, 0x05, payload.data(), 5), wire.size());
}

TEST(WireFrame, EveryPayloadSizeRoundTrips) {
  std::mt19937 rng(1);
  FrameDecoder d;
  for (int len = 0; len <= kMaxPayload; ++len) {
    Bytes p(len);
    for (auto& b : p) b = static_cast<uint8_t>(rng());
    const auto got = feed(d, testing::encode(0x01, static_cast<uint8_t>(len), p));
    ASSERT_EQ(got.size(), 1u) << len;
    EXPECT_EQ(got[0], testing::raw_of(kProtocolVersion, 0x01, static_cast<uint8_t>(len), p));
    EXPECT_EQ(d.payload_len(), len);
    EXPECT_EQ(d.type(), 0x01);
    EXPECT_EQ(d.seq(), len);
    EXPECT_EQ(d.version(), kProtocolVersion);
  }
  EXPECT_EQ(d.counters().frames_ok, kMaxPayload + 1);
  EXPECT_EQ(d.counters().frame_errors(), 0);
}

TEST(WireFrame, MaxSizeFrameWorstCaseEscaping) {
  const Bytes p(kMaxPayload, kEsc);
  Bytes out(kMaxEncodedFrame);
  // type/seq/len chosen to need escapes too; the CRC may or may not.
  const size_t n = encode_frame(0x7E, 0x2B, p.data(), kMaxPayload, out.data(), out.size());
  ASSERT_GT(n, 0u);
  EXPECT_LE(n, kMaxEncodedFrame);
  EXPECT_GE(n, 2u + 2u * (kMaxPayload + 2u) + 2u + 2u);
  out.resize(n);
  FrameDecoder d;
  ASSERT_EQ(feed(d, out).size(), 1u);
  EXPECT_EQ(d.raw_size(), kMaxRawFrame);
  // Too small a buffer and too long a payload are refused, nothing partial reported.
  uint8_t small[kMaxEncodedFrame];
  EXPECT_EQ(encode_frame(0x7E, 0x2B, p.data(), kMaxPayload, small, n - 1), 0u);
  const Bytes too_long(kMaxPayload + 1, 0);
  EXPECT_EQ(encode_frame(1, 1, too_long.data(), kMaxPayload + 1, small, sizeof small), 0u);
  EXPECT_EQ(encoded_frame_size(1, 1, too_long.data(), kMaxPayload + 1), 0u);
  uint8_t raw[kMaxRawFrame + 8];
  EXPECT_EQ(build_raw_frame(1, 1, 1, too_long.data(), kMaxPayload + 1, raw), 0u);
}

TEST(WireFrame, OverlongFrameIsDroppedAndNextFrameRecovered) {
  // 65 raw bytes with a correct CRC: only the size makes it invalid.
  Bytes raw(kMaxRawFrame + 1, 0x11);
  raw[0] = kProtocolVersion;
  raw[3] = static_cast<uint8_t>(raw.size() - 6);
  put_le16(raw.data() + raw.size() - 2, crc16_ccitt(raw.data(), raw.size() - 2));
  Bytes stream = testing::stuff(raw);
  const Bytes good = testing::encode(0x02, 9, {1, 2, 3});
  stream.insert(stream.end(), good.begin(), good.end());
  FrameDecoder d;
  const auto got = feed(d, stream);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0], testing::raw_of(kProtocolVersion, 0x02, 9, {1, 2, 3}));
  EXPECT_EQ(d.counters().too_long, 1);
  EXPECT_EQ(d.counters().frame_errors(), 1);
}

TEST(WireFrame, WrongVersionIsCountedNotAccepted) {
  for (uint8_t version : {0, 2, 0xFF}) {
    const RawFrame other = testing::raw_of(version, 0x40, 1, {});
    Bytes stream = testing::stuff(other.raw);
    const Bytes good = testing::encode(0x40, 2, {});
    stream.insert(stream.end(), good.begin(), good.end());
    FrameDecoder d;
    const auto got = feed(d, stream);
    ASSERT_EQ(got.size(), 1u);
    EXPECT_EQ(got[0], testing::raw_of(kProtocolVersion, 0x40, 2, {}));
    EXPECT_EQ(d.counters().bad_version, 1);
    EXPECT_EQ(d.counters().frame_errors(), 1);
  }
}

TEST(WireFrame, LengthFieldMismatchWithValidCrcIsRejected) {
  RawFrame f = testing::raw_of(kProtocolVersion, 0x41, 1, {0x10, 0x27});
  f.raw[3] = 3;  // claims one byte more than sent
  put_le16(f.raw.data() + f.raw.size() - 2, crc16_ccitt(f.raw.data(), f.raw.size() - 2));
  FrameDecoder d;
  EXPECT_TRUE(feed(d, testing::stuff(f.raw)).empty());
  EXPECT_EQ(d.counters().bad_length, 1);
  EXPECT_EQ(d.last_error(), FrameError::BadLength);
}

TEST(WireFrame, RuntsEscapesAndUnescapedPlusAreRejected) {
  FrameDecoder d;
  EXPECT_TRUE(feed(d, {kFlag, 1, 2, 3, 4, 5, kFlag}).empty());
  EXPECT_EQ(d.counters().runt, 1);
  EXPECT_TRUE(feed(d, {kFlag, 1, kEsc, 0x41, 2, kFlag}).empty());  // escapes 0x61: not reserved
  EXPECT_EQ(d.counters().bad_escape, 1);
  EXPECT_TRUE(feed(d, {kFlag, 1, 2, kAtModeChar, 4, 5, 6, 7, kFlag}).empty());
  EXPECT_EQ(d.counters().bad_escape, 2);
  EXPECT_TRUE(feed(d, {kFlag, 1, 2, 3, kEsc, kFlag}).empty());  // ESC FLAG = abort
  EXPECT_EQ(d.counters().bad_escape, 3);
  EXPECT_EQ(d.counters().frames_ok, 0);
}

TEST(WireFrame, GarbageBeforeFirstFlagAndIdleFlagsAreHarmless) {
  Bytes stream = {0x00, 0xFF, 0x41, 0x0D, 0x0A};
  const Bytes good = testing::encode(0x01, 1, {5});
  stream.insert(stream.end(), good.begin(), good.end());
  stream.insert(stream.end(), {kFlag, kFlag, kFlag});
  stream.insert(stream.end(), good.begin() + 1, good.end());  // shares the previous flag
  FrameDecoder d;
  EXPECT_EQ(feed(d, stream).size(), 2u);
  EXPECT_EQ(d.counters().discarded_bytes, 5);
  EXPECT_EQ(d.counters().frame_errors(), 0);
}

TEST(WireFrame, CountersSaturateInsteadOfWrapping) {
  FrameDecoder d;
  const Bytes runt = {kFlag, 1, kFlag};
  for (int i = 0; i < 70000; ++i) feed(d, runt);
  EXPECT_EQ(d.counters().runt, 0xFFFF);
  EXPECT_EQ(d.counters().frame_errors(), 0xFFFF);
  d.reset_all();
  EXPECT_EQ(d.counters().runt, 0);
}

TEST(WireFrame, EncodedStreamsNeverContainPlus) {
  // Every byte value in every position of header and payload, and CRCs that hit 0x2B.
  for (int v = 0; v < 256; ++v) {
    const uint8_t b = static_cast<uint8_t>(v);
    const Bytes wire = testing::encode(b, b, Bytes(kMaxPayload, b));
    for (uint8_t w : wire) ASSERT_NE(w, kAtModeChar);
  }
  std::mt19937 rng(7);
  int crc_bytes_escaped = 0;
  for (int i = 0; i < 20000; ++i) {
    Bytes p(rng() % (kMaxPayload + 1));
    for (auto& b : p) b = static_cast<uint8_t>(rng() % 4 == 0 ? 0x2B : rng());
    const Bytes wire = testing::encode(static_cast<uint8_t>(rng()), static_cast<uint8_t>(rng()), p);
    for (uint8_t w : wire) ASSERT_NE(w, kAtModeChar);
    if (wire.size() >= 3 && wire[wire.size() - 3] == kEsc) ++crc_bytes_escaped;
  }
  EXPECT_GT(crc_bytes_escaped, 0);  // the CRC's own escaping was exercised
}

TEST(WireFrame, FrameErrorNamesAreDistinct) {
  EXPECT_STREQ(frame_error_name(FrameError::BadCrc), "bad CRC");
  for (int a = 0; a <= 6; ++a) {
    for (int b = a + 1; b <= 6; ++b) {
      EXPECT_STRNE(frame_error_name(static_cast<FrameError>(a)),
                   frame_error_name(static_cast<FrameError>(b)));
    }
  }
}

}  // namespace
}  // namespace btsm::wire
