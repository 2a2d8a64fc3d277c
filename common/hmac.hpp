// HMAC-SHA256 (RFC 2104 / FIPS 198-1), incremental, plus a constant-time tag comparison.
//
// Used to authenticate model uploads: tag = HMAC-SHA256(device key, nonce || blob). RAM: the
// inner SHA-256 context plus only the 32-byte chaining value of the outer hash after its key
// block (the outer context is rebuilt from it in final()), about 140 bytes in total, instead of
// two full contexts or a copy of the padded key.
#ifndef BTSM_COMMON_HMAC_HPP
#define BTSM_COMMON_HMAC_HPP

#include <stddef.h>
#include <stdint.h>

#include "sha256.hpp"

namespace btsm {

const uint8_t kHmacSha256Size = kSha256DigestSize;

class HmacSha256 {
 public:
  HmacSha256() {}
  HmacSha256(const uint8_t* key, size_t key_len) { init(key, key_len); }

  // Starts a MAC with the given key (any length; keys over 64 bytes are hashed first).
  // K0 (the key padded with zeros) ^ opad and ^ ipad go into the hash a byte at a time, not
  // through a 64-byte padded copy: this runs inside MODEL_BEGIN, the firmware's deepest stack.
  void init(const uint8_t* key, size_t key_len) {
    if (key_len > kSha256BlockSize) {
      uint8_t hashed[kSha256DigestSize];
      sha256(key, key_len, hashed);
      init(hashed, kSha256DigestSize);
      secure_zero(hashed, sizeof(hashed));
      return;
    }
    // Outer hash: absorb K0 ^ opad, keep only its chaining value.
    absorb_key_block(key, key_len, 0x5c);
    for (uint8_t i = 0; i < 8; ++i) outer_chain_[i] = inner_.chaining()[i];
    // Inner hash: K0 ^ ipad.
    absorb_key_block(key, key_len, 0x36);
  }

  void update(const uint8_t* data, size_t n) { inner_.update(data, n); }

  // Writes the 32-byte tag and wipes the key-derived state.
  void final(uint8_t tag[kHmacSha256Size]) {
    uint8_t inner_digest[kSha256DigestSize];
    inner_.final(inner_digest);
    inner_.resume(outer_chain_, kSha256BlockSize);
    inner_.update(inner_digest, kSha256DigestSize);
    inner_.final(tag);
    secure_zero(inner_digest, sizeof(inner_digest));
    secure_zero(outer_chain_, sizeof(outer_chain_));
  }

 private:
  // A fresh hash over one block of (K0 ^ pad); key_len <= 64.
  void absorb_key_block(const uint8_t* key, size_t key_len, uint8_t pad) {
    inner_.init();
    for (uint8_t i = 0; i < kSha256BlockSize; ++i)
      inner_.update_byte(static_cast<uint8_t>((i < key_len ? key[i] : 0) ^ pad));
  }

  Sha256 inner_;
  uint32_t outer_chain_[8];
};

// One-shot convenience.
inline void hmac_sha256(const uint8_t* key, size_t key_len, const uint8_t* data, size_t n,
                        uint8_t tag[kHmacSha256Size]) {
  HmacSha256 mac(key, key_len);
  mac.update(data, n);
  mac.final(tag);
}

// Compares n bytes in time independent of where they differ (no early exit), so a forged tag
// cannot be found byte by byte from response timing.
inline bool constant_time_equal(const uint8_t* a, const uint8_t* b, size_t n) {
  uint8_t diff = 0;
  for (size_t i = 0; i < n; ++i) diff = static_cast<uint8_t>(diff | (a[i] ^ b[i]));
  // Through a volatile so the compiler cannot turn the loop into an early-exit memcmp.
  volatile uint8_t result = diff;
  return result == 0;
}

}  // namespace btsm

#endif  // BTSM_COMMON_HMAC_HPP
