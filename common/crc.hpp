// CRC-16/CCITT-FALSE (frame check) and CRC-32/IEEE (model blob check).
//
// Bitwise implementations on purpose: a 256-entry table costs 512 B (CRC-16) or 1 KB (CRC-32) of
// the ATmega328P's 32 KB flash, and the data rates here (a 60-byte frame every few seconds, a
// <= 464-byte blob on commit) make the bitwise loop's speed irrelevant.
//
// Both functions are chainable: pass the previous result as `crc` to continue over more data.
//   CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no xorout; check("123456789")=0x29B1
//   CRC-32 (IEEE 802.3): poly 0x04C11DB7 reflected (0xEDB88320), init/xorout 0xFFFFFFFF;
//                        check("123456789")=0xCBF43926. Start with crc = 0.
#ifndef BTSM_COMMON_CRC_HPP
#define BTSM_COMMON_CRC_HPP

#include <stddef.h>
#include <stdint.h>

namespace btsm {

inline uint16_t crc16_ccitt_byte(uint16_t crc, uint8_t b) {
  crc = static_cast<uint16_t>(crc ^ (static_cast<uint16_t>(b) << 8));
  for (uint8_t i = 0; i < 8; ++i) {
    crc = (crc & 0x8000U) ? static_cast<uint16_t>((crc << 1) ^ 0x1021U)
                          : static_cast<uint16_t>(crc << 1);
  }
  return crc;
}

inline uint16_t crc16_ccitt(const uint8_t* d, size_t n, uint16_t crc = 0xFFFF) {
  for (size_t i = 0; i < n; ++i) crc = crc16_ccitt_byte(crc, d[i]);
  return crc;
}

// `crc` is the value returned by a previous call (0 to start): the xorout is undone on entry and
// re-applied on exit, which is what makes crc32(b, nb, crc32(a, na)) == crc32(a||b).
inline uint32_t crc32(const uint8_t* d, size_t n, uint32_t crc = 0) {
  crc = ~crc;
  for (size_t i = 0; i < n; ++i) {
    crc ^= d[i];
    for (uint8_t k = 0; k < 8; ++k) {
      crc = (crc & 1U) ? ((crc >> 1) ^ 0xEDB88320UL) : (crc >> 1);
    }
  }
  return ~crc;
}

}  // namespace btsm

#endif  // BTSM_COMMON_CRC_HPP
