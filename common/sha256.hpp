// SHA-256 (FIPS 180-4), incremental, sized for the ATmega328P.
//
// RAM: the context is 105 bytes; compress() uses a rolling 16-word message schedule (64 bytes of
// stack) instead of the usual 64-word array (256 bytes). The 64 round constants are the only
// table; on AVR they live in flash (PROGMEM) and are read with pgm_read_dword, elsewhere they are
// an ordinary const array. C++14 without the standard library.
#ifndef BTSM_COMMON_SHA256_HPP
#define BTSM_COMMON_SHA256_HPP

#include <stddef.h>
#include <stdint.h>

#include "platform.hpp"

namespace btsm {

const uint8_t kSha256DigestSize = 32;
const uint8_t kSha256BlockSize = 64;

// Round constant i (0..63): first 32 bits of the fractional parts of the cube roots of the first
// 64 primes.
inline uint32_t sha256_round_constant(uint8_t i) {
  static const uint32_t k[64] BTSM_FLASH = {
      0x428a2f98UL, 0x71374491UL, 0xb5c0fbcfUL, 0xe9b5dba5UL, 0x3956c25bUL, 0x59f111f1UL,
      0x923f82a4UL, 0xab1c5ed5UL, 0xd807aa98UL, 0x12835b01UL, 0x243185beUL, 0x550c7dc3UL,
      0x72be5d74UL, 0x80deb1feUL, 0x9bdc06a7UL, 0xc19bf174UL, 0xe49b69c1UL, 0xefbe4786UL,
      0x0fc19dc6UL, 0x240ca1ccUL, 0x2de92c6fUL, 0x4a7484aaUL, 0x5cb0a9dcUL, 0x76f988daUL,
      0x983e5152UL, 0xa831c66dUL, 0xb00327c8UL, 0xbf597fc7UL, 0xc6e00bf3UL, 0xd5a79147UL,
      0x06ca6351UL, 0x14292967UL, 0x27b70a85UL, 0x2e1b2138UL, 0x4d2c6dfcUL, 0x53380d13UL,
      0x650a7354UL, 0x766a0abbUL, 0x81c2c92eUL, 0x92722c85UL, 0xa2bfe8a1UL, 0xa81a664bUL,
      0xc24b8b70UL, 0xc76c51a3UL, 0xd192e819UL, 0xd6990624UL, 0xf40e3585UL, 0x106aa070UL,
      0x19a4c116UL, 0x1e376c08UL, 0x2748774cUL, 0x34b0bcb5UL, 0x391c0cb3UL, 0x4ed8aa4aUL,
      0x5b9cca4fUL, 0x682e6ff3UL, 0x748f82eeUL, 0x78a5636fUL, 0x84c87814UL, 0x8cc70208UL,
      0x90befffaUL, 0xa4506cebUL, 0xbef9a3f7UL, 0xc67178f2UL};
  return flash_read_u32(&k[i]);
}

// Overwrites memory in a way the optimiser may not drop (for keys and intermediate hashes).
inline void secure_zero(void* p, size_t n) {
  volatile uint8_t* v = static_cast<volatile uint8_t*>(p);
  while (n--) *v++ = 0;
}

class Sha256 {
 public:
  Sha256() { init(); }

  void init() {
    h_[0] = 0x6a09e667UL;
    h_[1] = 0xbb67ae85UL;
    h_[2] = 0x3c6ef372UL;
    h_[3] = 0xa54ff53aUL;
    h_[4] = 0x510e527fUL;
    h_[5] = 0x9b05688cUL;
    h_[6] = 0x1f83d9abUL;
    h_[7] = 0x5be0cd19UL;
    total_ = 0;
    used_ = 0;
  }

  // Continues from a chaining value saved after an exact number of whole blocks (HMAC stores
  // its outer state this way: 32 bytes instead of a whole context).
  void resume(const uint32_t chaining[8], uint32_t bytes_done) {
    for (uint8_t i = 0; i < 8; ++i) h_[i] = chaining[i];
    total_ = bytes_done;
    used_ = 0;
  }

  // Chaining value; only meaningful after a multiple of 64 bytes (see resume()).
  const uint32_t* chaining() const { return h_; }

  void update(const uint8_t* data, size_t n) {
    for (size_t i = 0; i < n; ++i) update_byte(data[i]);
  }

  void update_byte(uint8_t b) {
    block_[used_++] = b;
    if (used_ == kSha256BlockSize) {
      compress();
      used_ = 0;
    }
    ++total_;
  }

  // Writes the 32-byte digest and wipes the context (call init() to reuse it).
  void final(uint8_t digest[kSha256DigestSize]) {
    // Message length in bits, big-endian 64-bit. total_ counts bytes in 32 bits, so messages up
    // to 4 GiB are supported — far beyond anything the firmware or host hash here.
    const uint32_t bits_lo = total_ << 3;
    const uint32_t bits_hi = total_ >> 29;
    block_[used_++] = 0x80;
    if (used_ > kSha256BlockSize - 8) {
      while (used_ < kSha256BlockSize) block_[used_++] = 0;
      compress();
      used_ = 0;
    }
    while (used_ < kSha256BlockSize - 8) block_[used_++] = 0;
    put_be32(block_ + 56, bits_hi);
    put_be32(block_ + 60, bits_lo);
    compress();
    for (uint8_t i = 0; i < 8; ++i) put_be32(digest + 4 * i, h_[i]);
    secure_zero(this, sizeof(*this));
  }

 private:
#if defined(__AVR__)
  // The AVR has no barrel shifter: an inlined rotate by a constant expands to dozens of
  // instructions, 24 times per round. One out-of-line routine (whole bytes moved first) roughly
  // halves compress()'s flash size; the speed cost is irrelevant for a few blocks per upload.
  static uint32_t __attribute__((noinline)) rotr(uint32_t x, uint8_t n) {
    while (n >= 8) {
      x = (x >> 8) | (x << 24);
      n = static_cast<uint8_t>(n - 8);
    }
    while (n != 0) {
      x = (x >> 1) | (x << 31);
      --n;
    }
    return x;
  }
#else
  static uint32_t rotr(uint32_t x, uint8_t n) { return (x >> n) | (x << (32 - n)); }
#endif
  static uint32_t get_be32(const uint8_t* p) {
    return (static_cast<uint32_t>(p[0]) << 24) | (static_cast<uint32_t>(p[1]) << 16) |
           (static_cast<uint32_t>(p[2]) << 8) | static_cast<uint32_t>(p[3]);
  }
  static void put_be32(uint8_t* p, uint32_t v) {
    p[0] = static_cast<uint8_t>(v >> 24);
    p[1] = static_cast<uint8_t>(v >> 16);
    p[2] = static_cast<uint8_t>(v >> 8);
    p[3] = static_cast<uint8_t>(v);
  }

  // rotr(x,a) ^ rotr(x,b) ^ rotr(x,c): the four Sigma/sigma functions share this shape.
  static uint32_t rot3(uint32_t x, uint8_t a, uint8_t b, uint8_t c) {
    return rotr(x, a) ^ rotr(x, b) ^ rotr(x, c);
  }

  // Working variables live in an array (v[0] = a ... v[7] = h) and shift down each round. On AVR
  // that keeps register pressure and code size low (32-bit ops cost 4 instructions each); on the
  // host the compiler unrolls the shift into register renames.
  void compress() {
    uint32_t w[16];  // rolling schedule: w[t & 15] holds W_t
    for (uint8_t t = 0; t < 16; ++t) w[t] = get_be32(block_ + 4 * t);
    uint32_t v[8];
    for (uint8_t i = 0; i < 8; ++i) v[i] = h_[i];
    for (uint8_t t = 0; t < 64; ++t) {
      if (t >= 16) {
        const uint32_t w15 = w[(t - 15) & 15];
        const uint32_t w2 = w[(t - 2) & 15];
        // sigma0 = rotr7 ^ rotr18 ^ shr3, sigma1 = rotr17 ^ rotr19 ^ shr10
        const uint32_t s0 = rotr(w15, 7) ^ rotr(w15, 18) ^ (w15 >> 3);
        const uint32_t s1 = rotr(w2, 17) ^ rotr(w2, 19) ^ (w2 >> 10);
        w[t & 15] += s0 + w[(t - 7) & 15] + s1;
      }
      const uint32_t e = v[4];
      const uint32_t ch = (e & v[5]) ^ (~e & v[6]);
      const uint32_t t1 = v[7] + rot3(e, 6, 11, 25) + ch + sha256_round_constant(t) + w[t & 15];
      const uint32_t a = v[0];
      const uint32_t maj = (a & v[1]) ^ (a & v[2]) ^ (v[1] & v[2]);
      const uint32_t t2 = rot3(a, 2, 13, 22) + maj;
      for (uint8_t i = 7; i > 0; --i) v[i] = v[i - 1];
      v[4] += t1;
      v[0] = t1 + t2;
    }
    for (uint8_t i = 0; i < 8; ++i) h_[i] += v[i];
    secure_zero(w, sizeof(w));
    secure_zero(v, sizeof(v));
  }

  uint32_t h_[8];
  uint32_t total_;  // bytes hashed so far
  uint8_t block_[kSha256BlockSize];
  uint8_t used_;  // bytes in block_
};

// One-shot convenience.
inline void sha256(const uint8_t* data, size_t n, uint8_t digest[kSha256DigestSize]) {
  Sha256 s;
  s.update(data, n);
  s.final(digest);
}

}  // namespace btsm

#endif  // BTSM_COMMON_SHA256_HPP
