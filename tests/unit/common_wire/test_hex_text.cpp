// common/hex_text.hpp: the one bytes <-> hex text codec (blob JSON, device keys, UUIDs, Intel HEX).
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "common/hex_text.hpp"

namespace btsm {
namespace {

TEST(HexText, EncodesHighNibbleFirstInLowercase) {
  const uint8_t bytes[] = {0x00, 0x0F, 0xA5, 0xFF, 0x3C};
  std::string text(2 * sizeof bytes, '?');
  hex_encode(bytes, sizeof bytes, &text[0]);
  EXPECT_EQ(text, "000fa5ff3c");
}

TEST(HexText, EveryByteAndRandomBlobsRoundTrip) {
  std::vector<uint8_t> all(256);
  for (int i = 0; i < 256; ++i) all[static_cast<size_t>(i)] = static_cast<uint8_t>(i);
  std::mt19937 rng(16);
  std::vector<std::vector<uint8_t>> cases{all, {}};
  for (int n = 0; n < 50; ++n) {
    std::vector<uint8_t> v(rng() % 600);
    for (auto& b : v) b = static_cast<uint8_t>(rng());
    cases.push_back(v);
  }
  for (const auto& v : cases) {
    std::string text(2 * v.size(), '?');
    hex_encode(v.data(), v.size(), &text[0]);
    std::vector<uint8_t> back(v.size());
    const HexDecodeResult r = hex_decode(text.data(), text.size(), back.data(), back.size(), false);
    ASSERT_EQ(r.status, HexStatus::kOk);
    ASSERT_EQ(r.bytes, v.size());
    EXPECT_EQ(back, v);
  }
}

TEST(HexText, ReadsEitherCaseAndSkipsWhiteSpaceOnlyWhenAsked) {
  const std::string text = "De aD\n bE\tEF";
  uint8_t out[8] = {};
  HexDecodeResult r = hex_decode(text.data(), text.size(), out, sizeof out, true);
  ASSERT_EQ(r.status, HexStatus::kOk);
  ASSERT_EQ(r.bytes, 4u);
  EXPECT_EQ(out[0], 0xDE);
  EXPECT_EQ(out[1], 0xAD);
  EXPECT_EQ(out[2], 0xBE);
  EXPECT_EQ(out[3], 0xEF);
  r = hex_decode(text.data(), text.size(), out, sizeof out, false);
  EXPECT_EQ(r.status, HexStatus::kBadCharacter);
  EXPECT_EQ(r.at, 2u);  // the space
}

TEST(HexText, NamesWhereTheTextStopsBeingHex) {
  uint8_t out[4] = {};
  const std::string bad = "00g1";
  HexDecodeResult r = hex_decode(bad.data(), bad.size(), out, sizeof out, true);
  EXPECT_EQ(r.status, HexStatus::kBadCharacter);
  EXPECT_EQ(r.at, 2u);
  EXPECT_EQ(r.bytes, 1u);  // what was good before it is kept
  const std::string odd = "abc";
  r = hex_decode(odd.data(), odd.size(), out, sizeof out, true);
  EXPECT_EQ(r.status, HexStatus::kOddDigits);
  EXPECT_EQ(r.bytes, 1u);
  const std::string long_text = "0102030405";
  r = hex_decode(long_text.data(), long_text.size(), out, sizeof out, false);
  EXPECT_EQ(r.status, HexStatus::kTooLong);
  EXPECT_EQ(r.at, 8u);
  EXPECT_EQ(r.bytes, 4u);
  EXPECT_EQ(hex_digit_value('/'), -1);
  EXPECT_EQ(hex_digit_value(':'), -1);
  EXPECT_EQ(hex_digit_value('G'), -1);
  EXPECT_EQ(hex_digit_value('F'), 15);
}

}  // namespace
}  // namespace btsm
