// What differs between the ATmega328P (avr-g++ 5.4) and the host (g++ 12), in one place:
//  - inlining hints: on AVR with LTO a small helper inlined everywhere costs flash the 32 KB part
//    does not have (BTSM_NOINLINE), while a per-byte helper of a few instructions is cheaper than
//    the call's register shuffling (BTSM_ALWAYS_INLINE; -finline-limit=10 would keep it a call);
//  - constant tables in flash: on AVR a const table is copied into the 2 KB of RAM unless it is
//    placed in program memory (BTSM_FLASH) and read with the LPM instruction (flash_read_*);
//  - the CPU's byte order, for the few places that read an integer's words in place
//    (BTSM_LITTLE_ENDIAN); data that crosses a boundary always goes through byte_order.hpp.
// C++14, no standard library.
#ifndef BTSM_COMMON_PLATFORM_HPP
#define BTSM_COMMON_PLATFORM_HPP

#include <stdint.h>

#if defined(__AVR__)
#include <avr/pgmspace.h>
#endif

#if defined(__GNUC__)
#define BTSM_ALWAYS_INLINE inline __attribute__((always_inline))
#define BTSM_NOINLINE __attribute__((noinline))
#else
#define BTSM_ALWAYS_INLINE inline
#define BTSM_NOINLINE
#endif

#if defined(__AVR__)
#define BTSM_FLASH PROGMEM
#else
#define BTSM_FLASH
#endif

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
#define BTSM_LITTLE_ENDIAN 1
#else
#define BTSM_LITTLE_ENDIAN 0
#endif

namespace btsm {

// Reads of a BTSM_FLASH table entry (an ordinary load off the AVR).
#if defined(__AVR__)
BTSM_ALWAYS_INLINE uint32_t flash_read_u32(const uint32_t* p) { return pgm_read_dword(p); }
BTSM_ALWAYS_INLINE int32_t flash_read_i32(const int32_t* p) { return static_cast<int32_t>(pgm_read_dword(p)); }
BTSM_ALWAYS_INLINE uint16_t flash_read_u16(const uint16_t* p) { return pgm_read_word(p); }
BTSM_ALWAYS_INLINE uint8_t flash_read_u8(const uint8_t* p) { return pgm_read_byte(p); }
#else
BTSM_ALWAYS_INLINE uint32_t flash_read_u32(const uint32_t* p) { return *p; }
BTSM_ALWAYS_INLINE int32_t flash_read_i32(const int32_t* p) { return *p; }
BTSM_ALWAYS_INLINE uint16_t flash_read_u16(const uint16_t* p) { return *p; }
BTSM_ALWAYS_INLINE uint8_t flash_read_u8(const uint8_t* p) { return *p; }
#endif

}  // namespace btsm

#endif
