// Per-device authentication key record: where it lives in the AVR image and its byte format.
//
// The HMAC-SHA256 key that authenticates model uploads is not compiled into the firmware source.
// The image reserves a fixed 64-byte record in application flash (linker section `.btsm_key`,
// placed with --section-start at kFlashAddress, just below the 512-byte bootloader). The host's
// `btsm flash-firmware` patches the record in the .hex/.elf before upload. Layout, little-endian:
//
//   offset size  field
//   0      4     magic     kMagic ("BTK1": 0x42 0x54 0x4B 0x31)
//   4      4     device_id u32, reported in INFO
//   8      32    key       HMAC-SHA256 key
//   40     4     crc32     CRC-32/IEEE (common/crc.hpp) over bytes 0..39
//   44     20    reserved  0xFF
//
// The image as built holds all 0xFF ("erased"): magic and CRC do not match, the device has no
// key and refuses every model write (NACK AUTH_FAILED) until a key is patched in. A development
// image (CMake -DBTSM_DEV_KEY=ON) carries kDevKey below with device_id kDevDeviceId; it is public
// and must never be used in production.
#ifndef BTSM_COMMON_DEVICE_KEY_HPP
#define BTSM_COMMON_DEVICE_KEY_HPP

#include <stdint.h>

#include "common/byte_order.hpp"
#include "common/crc.hpp"

namespace btsm {
namespace device_key {

static constexpr uint32_t kFlashAddress = 0x7DC0;  // byte address; bootloader starts at 0x7E00
static constexpr uint16_t kRecordSize = 64;
static constexpr uint16_t kOffsetMagic = 0;
static constexpr uint16_t kOffsetDeviceId = 4;
static constexpr uint16_t kOffsetKey = 8;
static constexpr uint16_t kKeySize = 32;
static constexpr uint16_t kOffsetCrc = 40;
static constexpr uint16_t kCrcCoverage = 40;  // bytes 0..39
static constexpr uint32_t kMagic = 0x314B5442UL;
static constexpr uint32_t kDevDeviceId = 0x0000DE70UL;
// Development key: the bytes 0x00, 0x01, ..., 0x1F. Public. Tests and the simulated board use it.
inline uint8_t dev_key_byte(uint8_t i) { return i; }

// Builds a valid record (host tool, native board, tests).
inline void build_record(uint8_t* rec, uint32_t device_id, const uint8_t* key) {
  for (uint16_t i = 0; i < kRecordSize; ++i) rec[i] = 0xFF;
  put_le32(rec + kOffsetMagic, kMagic);
  put_le32(rec + kOffsetDeviceId, device_id);
  for (uint16_t i = 0; i < kKeySize; ++i) rec[kOffsetKey + i] = key[i];
  put_le32(rec + kOffsetCrc, crc32(rec, kCrcCoverage));
}

// True when `rec` (kRecordSize bytes) holds a key: magic and CRC match.
inline bool record_valid(const uint8_t* rec) {
  return get_le32(rec + kOffsetMagic) == kMagic &&
         get_le32(rec + kOffsetCrc) == crc32(rec, kCrcCoverage);
}

}  // namespace device_key
}  // namespace btsm
#endif
