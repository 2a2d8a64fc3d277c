// EEPROM map of the BTSM module (1 KB on the ATmega328P). All fields little-endian.
//
//   0    32  configuration record   [magic 0xC5][version 1][len][payload len bytes][crc16]
//   32    8  persistent counters    [resets u16][watchdog resets u16][crc16][2 spare]
//   48  476  model slot 0           [slot header 12][blob kReducedModelBlobSize]
//   524 476  model slot 1
//   1000 24  spare
//
// Model slot header: [0..1] commit marker 0x5A 0xA5 (written LAST), [2..5] sequence number,
// [6..9] CRC-32 over (sequence LE || blob), [10..11] blob length. A slot is valid when the marker,
// length and CRC match; boot takes the valid slot with the highest sequence number. A new model
// goes to the other slot: marker erased first, blob, sequence + CRC, marker last -- so the slot
// in use is never touched and a power loss at any byte leaves the old or the new model valid.
#ifndef BTSM_FIRMWARE_EEPROM_LAYOUT_HPP
#define BTSM_FIRMWARE_EEPROM_LAYOUT_HPP

#include <stdint.h>

#include "common/model_blob.hpp"

namespace btsm {
namespace eeprom_layout {

static constexpr uint16_t kConfigAddr = 0;
static constexpr uint16_t kConfigSize = 32;
static constexpr uint16_t kCountersAddr = 32;
static constexpr uint16_t kCountersSize = 8;
static constexpr uint16_t kSlotHeaderSize = 12;
static constexpr uint16_t kBlobSize = static_cast<uint16_t>(kReducedModelBlobSize);
static constexpr uint16_t kSlotSize = kSlotHeaderSize + kBlobSize;
static constexpr uint16_t kSlot0Addr = 48;
static constexpr uint16_t kSlotCount = 2;
static constexpr uint16_t kEepromSize = 1024;
static constexpr uint8_t kMarker0 = 0x5A;
static constexpr uint8_t kMarker1 = 0xA5;
static constexpr uint16_t kHdrMarker = 0;
static constexpr uint16_t kHdrSeq = 2;
static constexpr uint16_t kHdrCrc = 6;
static constexpr uint16_t kHdrLen = 10;

inline uint16_t slot_addr(uint8_t slot) { return static_cast<uint16_t>(kSlot0Addr + slot * kSlotSize); }
inline uint16_t blob_addr(uint8_t slot) { return static_cast<uint16_t>(slot_addr(slot) + kSlotHeaderSize); }

static_assert(kSlot0Addr >= kCountersAddr + kCountersSize, "counters overlap the model slots");
static_assert(kSlot0Addr + kSlotCount * kSlotSize <= kEepromSize, "two model slots do not fit 1 KB EEPROM");

}  // namespace eeprom_layout
}  // namespace btsm

#endif
