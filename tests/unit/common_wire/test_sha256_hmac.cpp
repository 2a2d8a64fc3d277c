// SHA-256 (FIPS 180-2 appendix B vectors) and HMAC-SHA256 (RFC 4231 test cases 1-7).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "common/hmac.hpp"
#include "common/sha256.hpp"

namespace btsm {
namespace {

std::vector<uint8_t> bytes(const std::string& s) { return std::vector<uint8_t>(s.begin(), s.end()); }

std::string hex(const uint8_t* p, size_t n) {
  static const char* digits = "0123456789abcdef";
  std::string s;
  for (size_t i = 0; i < n; ++i) {
    s += digits[p[i] >> 4];
    s += digits[p[i] & 15];
  }
  return s;
}

std::string sha_hex(const std::vector<uint8_t>& m) {
  uint8_t d[32];
  sha256(m.data(), m.size(), d);
  return hex(d, 32);
}

std::string hmac_hex(const std::vector<uint8_t>& key, const std::vector<uint8_t>& msg) {
  uint8_t t[32];
  hmac_sha256(key.data(), key.size(), msg.data(), msg.size(), t);
  return hex(t, 32);
}

TEST(Sha256, Fips180Vectors) {
  EXPECT_EQ(sha_hex(bytes("abc")),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha_hex(bytes("")),
            "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  // 56 bytes: the length no longer fits after the 0x80, forcing a second padding block.
  EXPECT_EQ(sha_hex(bytes("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq")),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

TEST(Sha256, MillionAInPiecesOfVaryingSize) {
  Sha256 s;
  std::vector<uint8_t> chunk(1000, 'a');
  size_t done = 0;
  size_t piece = 1;
  while (done < 1000000) {
    size_t n = piece % 997 + 1;
    if (n > 1000000 - done) n = 1000000 - done;
    s.update(chunk.data(), n);
    done += n;
    piece = piece * 7 + 3;
  }
  uint8_t d[32];
  s.final(d);
  EXPECT_EQ(hex(d, 32), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

TEST(Sha256, EverySplitPointGivesTheOneShotDigest) {
  // Lengths around the 55/56/64-byte padding boundaries.
  for (size_t len : {0u, 1u, 55u, 56u, 57u, 63u, 64u, 65u, 119u, 120u, 128u, 200u}) {
    std::vector<uint8_t> m(len);
    for (size_t i = 0; i < len; ++i) m[i] = static_cast<uint8_t>(i * 131 + len);
    const std::string whole = sha_hex(m);
    for (size_t split = 0; split <= len; ++split) {
      Sha256 s;
      s.update(m.data(), split);
      s.update(m.data() + split, len - split);
      uint8_t d[32];
      s.final(d);
      ASSERT_EQ(hex(d, 32), whole) << "len " << len << " split " << split;
    }
  }
}

TEST(Sha256, ReusableAfterInit) {
  Sha256 s;
  uint8_t d[32];
  s.update(reinterpret_cast<const uint8_t*>("garbage"), 7);
  s.final(d);
  s.init();
  s.update(reinterpret_cast<const uint8_t*>("abc"), 3);
  s.final(d);
  EXPECT_EQ(hex(d, 32), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

TEST(HmacSha256, Rfc4231Cases) {
  // Case 1
  EXPECT_EQ(hmac_hex(std::vector<uint8_t>(20, 0x0b), bytes("Hi There")),
            "b0344c61d8db38535ca8afceaf0bf12b881dc200c9833da726e9376c2e32cff7");
  // Case 2: key shorter than the output
  EXPECT_EQ(hmac_hex(bytes("Jefe"), bytes("what do ya want for nothing?")),
            "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843");
  // Case 3
  EXPECT_EQ(hmac_hex(std::vector<uint8_t>(20, 0xaa), std::vector<uint8_t>(50, 0xdd)),
            "773ea91e36800e46854db8ebd09181a72959098b3ef8c122d9635514ced565fe");
  // Case 4
  std::vector<uint8_t> key4;
  for (uint8_t b = 1; b <= 25; ++b) key4.push_back(b);
  EXPECT_EQ(hmac_hex(key4, std::vector<uint8_t>(50, 0xcd)),
            "82558a389a443c0ea4cc819899f2083a85f0faa3e578f8077a2e3ff46729665b");
  // Case 5: truncated to 128 bits
  EXPECT_EQ(hmac_hex(std::vector<uint8_t>(20, 0x0c), bytes("Test With Truncation")).substr(0, 32),
            "a3b6167473100ee06e0c796c2955552b");
  // Case 6: key larger than one block is hashed first
  EXPECT_EQ(hmac_hex(std::vector<uint8_t>(131, 0xaa),
                     bytes("Test Using Larger Than Block-Size Key - Hash Key First")),
            "60e431591ee0b67f0d8a26aacbf5b77f8e0bc6213728c5140546040f0ee37f54");
  // Case 7: large key and large data
  EXPECT_EQ(hmac_hex(std::vector<uint8_t>(131, 0xaa),
                     bytes("This is a test using a larger than block-size key and a larger than "
                           "block-size data. The key needs to be hashed before being used by the "
                           "HMAC algorithm.")),
            "9b09ffa71b942fcb27635fbcd5b0e944bfdc63644f0713938a7f51535c3a35e2");
}

TEST(HmacSha256, IncrementalNonceThenBlobMatchesOneShot) {
  // The model upload MACs nonce || blob as two updates (nonce first, then chunks).
  std::vector<uint8_t> key(32);
  for (size_t i = 0; i < key.size(); ++i) key[i] = static_cast<uint8_t>(0xA0 + i);
  std::vector<uint8_t> msg(16 + 464);
  for (size_t i = 0; i < msg.size(); ++i) msg[i] = static_cast<uint8_t>(i * 29);
  const std::string whole = hmac_hex(key, msg);
  HmacSha256 mac(key.data(), key.size());
  mac.update(msg.data(), 16);
  for (size_t off = 16; off < msg.size(); off += 10) {
    const size_t n = msg.size() - off < 10 ? msg.size() - off : 10;
    mac.update(msg.data() + off, n);
  }
  uint8_t tag[32];
  mac.final(tag);
  EXPECT_EQ(hex(tag, 32), whole);
}

TEST(ConstantTimeEqual, DetectsADifferenceAtEveryPositionAndBit) {
  uint8_t a[32], b[32];
  for (int i = 0; i < 32; ++i) a[i] = b[i] = static_cast<uint8_t>(i * 7);
  EXPECT_TRUE(constant_time_equal(a, b, 32));
  EXPECT_TRUE(constant_time_equal(a, b, 0));
  for (int i = 0; i < 32; ++i) {
    for (int bit = 0; bit < 8; ++bit) {
      b[i] ^= static_cast<uint8_t>(1u << bit);
      EXPECT_FALSE(constant_time_equal(a, b, 32)) << i << ":" << bit;
      b[i] ^= static_cast<uint8_t>(1u << bit);
    }
  }
}

}  // namespace
}  // namespace btsm
