// The resumable frame encoder (wire::seal_raw_frame + resume_stuffed, which the firmware uses to
// stream frames into a UART ring smaller than a frame) produces exactly write_frame's bytes
// whatever the ring refuses.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "common/wire_frame.hpp"

namespace btsm {
namespace {

struct LimitedPut {
  std::vector<uint8_t>* out;
  int room;
  bool operator()(uint8_t b) {
    if (room <= 0) return false;
    --room;
    out->push_back(b);
    return true;
  }
};

TEST(FrameResume, RawBufferEncoderGivesWriteFrameBytesForAnyRefusalPattern) {
  std::mt19937 rng(5);
  for (int it = 0; it < 20000; ++it) {
    const uint8_t len = static_cast<uint8_t>(rng() % (wire::kMaxPayload + 1));
    uint8_t raw[wire::kMaxRawFrame];
    uint8_t* payload = raw + wire::kHeaderSize;
    for (uint8_t i = 0; i < len; ++i) {
      const unsigned r = rng() % 6;
      payload[i] = r == 0 ? wire::kFlag : r == 1 ? wire::kEsc : r == 2 ? wire::kAtModeChar : static_cast<uint8_t>(rng());
    }
    const uint8_t type = static_cast<uint8_t>(rng()), seq = static_cast<uint8_t>(rng() % 3 == 0 ? 0x2B : rng());
    uint8_t expected[wire::kMaxEncodedFrame];
    const size_t n = wire::encode_frame(type, seq, payload, len, expected, sizeof expected);
    ASSERT_GT(n, 0u);
    const uint8_t raw_n = wire::seal_raw_frame(raw, type, seq, len);
    ASSERT_EQ(raw_n, wire::kHeaderSize + len + wire::kCrcSize);
    std::vector<uint8_t> out;
    wire::StuffCursor c;
    wire::start_stuffed(c);
    int calls = 0;
    for (;;) {
      LimitedPut put = {&out, static_cast<int>(rng() % 5)};
      if (wire::resume_stuffed(put, c, raw, raw_n)) break;
      ASSERT_LT(++calls, 10000);
    }
    ASSERT_EQ(out, std::vector<uint8_t>(expected, expected + n)) << "iteration " << it;
  }
  uint8_t raw[wire::kMaxRawFrame];
  EXPECT_EQ(wire::seal_raw_frame(raw, 1, 2, wire::kMaxPayload + 1), 0);
}

}  // namespace
}  // namespace btsm
