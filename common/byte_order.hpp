// Little-endian byte codecs for the wire protocol and the EEPROM model blob.
//
// Every multi-byte field that crosses a boundary (UART, BLE, EEPROM, files) goes through these
// helpers so the byte order is explicit and independent of the CPU. C++14, no standard library:
// this header is shared by the ATmega328P firmware (avr-g++ 5.4) and the host tool (g++ 12).
#ifndef BTSM_COMMON_BYTE_ORDER_HPP
#define BTSM_COMMON_BYTE_ORDER_HPP

#include <stddef.h>
#include <stdint.h>
#include <string.h>

namespace btsm {

inline void put_le16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
}

inline uint16_t get_le16(const uint8_t* p) {
  return static_cast<uint16_t>(static_cast<uint16_t>(p[0]) | (static_cast<uint16_t>(p[1]) << 8));
}

// Signed 24-bit (two's complement). Only the low 24 bits of v are written; callers must keep v in
// [-8388608, 8388607] (see kInt24Min/kInt24Max) — values outside are truncated, not saturated.
inline void put_le24(uint8_t* p, int32_t v) {
  const uint32_t u = static_cast<uint32_t>(v);
  p[0] = static_cast<uint8_t>(u);
  p[1] = static_cast<uint8_t>(u >> 8);
  p[2] = static_cast<uint8_t>(u >> 16);
}

// Reads a signed 24-bit value and sign-extends it to 32 bits.
inline int32_t get_le24s(const uint8_t* p) {
  uint32_t u = static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
               (static_cast<uint32_t>(p[2]) << 16);
  if (u & 0x800000UL) u |= 0xFF000000UL;
  return static_cast<int32_t>(u);
}

// Unsigned 24-bit read (e.g. raw ADC codes).
inline uint32_t get_le24u(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16);
}

const int32_t kInt24Min = -8388608L;
const int32_t kInt24Max = 8388607L;

inline void put_le32(uint8_t* p, uint32_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
  p[2] = static_cast<uint8_t>(v >> 16);
  p[3] = static_cast<uint8_t>(v >> 24);
}

inline uint32_t get_le32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}

// IEEE-754 binary32, little-endian. float is binary32 on both AVR and x86-64; memcpy is the
// aliasing-safe way to reach its bits (compiles to plain moves).
inline void put_le_f32(uint8_t* p, float v) {
  static_assert(sizeof(float) == 4, "float must be IEEE-754 binary32");
  uint32_t bits;
  memcpy(&bits, &v, 4);
  put_le32(p, bits);
}

inline float get_le_f32(const uint8_t* p) {
  const uint32_t bits = get_le32(p);
  float v;
  memcpy(&v, &bits, 4);
  return v;
}

}  // namespace btsm

#endif  // BTSM_COMMON_BYTE_ORDER_HPP
