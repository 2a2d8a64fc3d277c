// Fault injection at every byte of encoded frames. Each case sends good frame A, a damaged frame B
// and good frame C through one decoder. Required: a damaged B is never accepted (only A and C
// come out, byte-identical), C is always recovered, and the damage is counted. Damage that leaves
// B's bytes between two flags intact (a lost or doubled flag, garbage outside the flags) must
// still deliver B.
#include <gtest/gtest.h>

#include <random>

#include "wire_test_support.hpp"

namespace btsm::wire {
namespace {

using testing::Bytes;
using testing::NamedFrame;
using testing::RawFrame;

const NamedFrame kFrameA{"A", type_code(MsgType::GetInfo), 0xA0, {}};
const NamedFrame kFrameC{"C", type_code(MsgType::SetSpeed), 0xC0, {0x10, 0x27}};

struct Outcome {
  std::vector<RawFrame> accepted;
  uint16_t errors_before_c;
};

Outcome run(const Bytes& damaged_b) {
  FrameDecoder d;
  Outcome o{};
  for (uint8_t b : kFrameA.wire()) {
    if (d.push(b)) o.accepted.push_back(RawFrame{Bytes(d.raw(), d.raw() + d.raw_size())});
  }
  const uint16_t before = d.counters().frame_errors();
  Bytes rest = damaged_b;
  const Bytes c = kFrameC.wire();
  rest.insert(rest.end(), c.begin(), c.end());
  for (uint8_t b : rest) {
    if (d.push(b)) o.accepted.push_back(RawFrame{Bytes(d.raw(), d.raw() + d.raw_size())});
  }
  o.errors_before_c = static_cast<uint16_t>(d.counters().frame_errors() - before);
  return o;
}

std::vector<RawFrame> expected(const NamedFrame& b, bool b_survives) {
  if (b_survives) return {kFrameA.raw(), b.raw(), kFrameC.raw()};
  return {kFrameA.raw(), kFrameC.raw()};
}

class FaultInjection : public ::testing::TestWithParam<NamedFrame> {};

TEST_P(FaultInjection, IntactFrameIsAccepted) {
  const NamedFrame& b = GetParam();
  const Outcome o = run(b.wire());
  EXPECT_EQ(o.accepted, expected(b, true));
  EXPECT_EQ(o.errors_before_c, 0);
}

TEST_P(FaultInjection, EveryBitFlipIsRejectedAndCounted) {
  const NamedFrame& b = GetParam();
  const Bytes wire = b.wire();
  for (size_t i = 0; i < wire.size(); ++i) {
    for (int bit = 0; bit < 8; ++bit) {
      Bytes damaged = wire;
      damaged[i] ^= static_cast<uint8_t>(1u << bit);
      const Outcome o = run(damaged);
      ASSERT_EQ(o.accepted, expected(b, false)) << b.name << " byte " << i << " bit " << bit;
      ASSERT_GE(o.errors_before_c, 1) << b.name << " byte " << i << " bit " << bit;
    }
  }
}

TEST_P(FaultInjection, EveryDroppedByteIsRejectedUnlessItWasAFlag) {
  const NamedFrame& b = GetParam();
  const Bytes wire = b.wire();
  for (size_t i = 0; i < wire.size(); ++i) {
    Bytes damaged = wire;
    damaged.erase(damaged.begin() + static_cast<long>(i));
    const bool flag_lost = wire[i] == kFlag;  // neighbour's flag takes over
    const Outcome o = run(damaged);
    ASSERT_EQ(o.accepted, expected(b, flag_lost)) << b.name << " drop " << i;
    if (!flag_lost) {
      ASSERT_GE(o.errors_before_c, 1) << b.name << " drop " << i;
    }
  }
}

TEST_P(FaultInjection, EveryTruncationIsRejectedAndNextFrameRecovered) {
  const NamedFrame& b = GetParam();
  const Bytes wire = b.wire();
  for (size_t keep = 0; keep < wire.size(); ++keep) {
    const Bytes damaged(wire.begin(), wire.begin() + static_cast<long>(keep));
    // Losing only the closing flag is harmless: C's opening flag closes B.
    const bool survives = keep == wire.size() - 1;
    const Outcome o = run(damaged);
    ASSERT_EQ(o.accepted, expected(b, survives)) << b.name << " keep " << keep;
    if (keep >= 2 && !survives) {
      ASSERT_GE(o.errors_before_c, 1) << b.name << " keep " << keep;
    }
  }
}

TEST_P(FaultInjection, GarbageInsertedAtEveryPositionIsRejected) {
  const NamedFrame& b = GetParam();
  const Bytes wire = b.wire();
  const uint8_t garbage[] = {0x00, 0xFF, kFlag, kEsc, kAtModeChar, 0x5E, 0x5D, 0x0B, 0x01, 0x55};
  for (size_t i = 0; i <= wire.size(); ++i) {
    for (uint8_t g : garbage) {
      Bytes damaged = wire;
      damaged.insert(damaged.begin() + static_cast<long>(i), g);
      // Outside the flags, or an extra flag next to one, leaves B's content intact.
      const bool survives =
          i == 0 || i == wire.size() || (g == kFlag && (i == 1 || i == wire.size() - 1));
      const Outcome o = run(damaged);
      ASSERT_EQ(o.accepted, expected(b, survives))
          << b.name << " insert 0x" << std::hex << int(g) << " at " << std::dec << i;
      if (!survives) {
        ASSERT_GE(o.errors_before_c, 1) << b.name << " insert at " << i;
      }
    }
  }
}

TEST_P(FaultInjection, EveryByteSubstitutedIsRejected) {
  const NamedFrame& b = GetParam();
  const Bytes wire = b.wire();
  for (size_t i = 1; i + 1 < wire.size(); ++i) {  // flags are covered by the flip test
    for (int v = 0; v < 256; ++v) {
      if (v == wire[i]) continue;
      Bytes damaged = wire;
      damaged[i] = static_cast<uint8_t>(v);
      const Outcome o = run(damaged);
      ASSERT_EQ(o.accepted, expected(b, false)) << b.name << " byte " << i << " = " << v;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(AllMessages, FaultInjection,
                         ::testing::ValuesIn(testing::representative_frames()),
                         [](const ::testing::TestParamInfo<NamedFrame>& info) {
                           return info.param.name;
                         });

// Random streams: frames, random bursts of damage and garbage. Whatever is accepted must be a
// frame that was sent, byte for byte; every frame sent with intact bytes must arrive.
TEST(FaultInjectionRandom, NothingButSentFramesIsEverAccepted) {
  std::mt19937 rng(2024);
  const auto frames = testing::representative_frames();
  size_t damaged_frames = 0;
  for (int round = 0; round < 300; ++round) {
    Bytes stream;
    std::vector<RawFrame> sent;
    std::vector<bool> intact;
    for (int k = 0; k < 20; ++k) {
      const NamedFrame& f = frames[rng() % frames.size()];
      Bytes w = f.wire();
      bool ok = true;
      switch (rng() % 6) {
        case 0:  // burst of up to 4 random bytes overwritten inside the frame
        {
          const size_t at = 1 + rng() % (w.size() - 2);
          const size_t n = 1 + rng() % 4;
          for (size_t j = at; j < at + n && j + 1 < w.size(); ++j) {
            const uint8_t before = w[j];
            w[j] = static_cast<uint8_t>(rng());
            if (w[j] != before) ok = false;
          }
          break;
        }
        case 1:  // garbage between frames (may contain flags, runts)
          for (size_t j = rng() % 8; j > 0; --j) stream.push_back(static_cast<uint8_t>(rng()));
          break;
        default:
          break;
      }
      stream.insert(stream.end(), w.begin(), w.end());
      sent.push_back(f.raw());
      intact.push_back(ok);
      if (!ok) ++damaged_frames;
    }
    FrameDecoder d;
    const auto got = testing::feed(d, stream);
    // Accepted frames must appear in sent order; intact frames must all be there.
    size_t j = 0;
    for (const RawFrame& g : got) {
      while (j < sent.size() && !(sent[j] == g && intact[j])) {
        ASSERT_FALSE(intact[j]) << "intact frame " << j << " lost in round " << round;
        ++j;
      }
      ASSERT_LT(j, sent.size()) << "accepted a frame that was never sent intact, round " << round;
      ++j;
    }
    for (; j < sent.size(); ++j) ASSERT_FALSE(intact[j]) << "trailing intact frame lost";
  }
  EXPECT_GT(damaged_frames, 500u);
}

}  // namespace
}  // namespace btsm::wire
