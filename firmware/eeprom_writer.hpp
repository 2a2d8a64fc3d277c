// Non-blocking EEPROM writer: one byte per step() while the storage is not busy (an AVR EEPROM
// byte takes 3.4 ms), so the main loop keeps sampling and serving the UART while a model or the
// configuration is stored. Bytes that already hold the value are skipped (wear, time).
// Up to kMaxSegments segments are written in order; the model store relies on that order.
#ifndef BTSM_FIRMWARE_EEPROM_WRITER_HPP
#define BTSM_FIRMWARE_EEPROM_WRITER_HPP

#include <stdint.h>

namespace btsm {

template <class Storage, uint8_t kCapacity>
class EepromWriter {
 public:
  static constexpr uint8_t kMaxSegments = 2;

  explicit EepromWriter(Storage& storage) : storage_(storage) {}

  bool busy() const { return segments_ != 0; }

  // Queues bytes for address `addr`. Returns false (nothing queued) when full.
  bool queue(uint16_t addr, const uint8_t* data, uint8_t n) {
    if (segments_ >= kMaxSegments || used_ + n > kCapacity) return false;
    seg_addr_[segments_] = addr;
    seg_len_[segments_] = n;
    for (uint8_t i = 0; i < n; ++i) buf_[used_ + i] = data[i];
    used_ = static_cast<uint8_t>(used_ + n);
    ++segments_;
    return true;
  }

  // Writes at most one byte. Returns true when everything queued has been written.
  bool step() {
    while (segments_ != 0) {
      if (storage_.busy()) return false;
      if (pos_ >= seg_len_[current_]) {
        ++current_;
        pos_ = 0;
        if (current_ >= segments_) {
          segments_ = 0;
          current_ = 0;
          used_ = 0;
          base_ = 0;
          return true;
        }
        base_ = static_cast<uint8_t>(base_ + seg_len_[current_ - 1]);
        continue;
      }
      const uint16_t addr = static_cast<uint16_t>(seg_addr_[current_] + pos_);
      const uint8_t value = buf_[base_ + pos_];
      ++pos_;
      if (storage_.read(addr) != value) {
        storage_.write(addr, value);
        return false;
      }
    }
    return true;
  }

 private:
  Storage& storage_;
  uint8_t buf_[kCapacity];
  uint16_t seg_addr_[kMaxSegments];
  uint8_t seg_len_[kMaxSegments];
  uint8_t segments_ = 0;
  uint8_t current_ = 0;
  uint8_t pos_ = 0;
  uint8_t base_ = 0;
  uint8_t used_ = 0;
};

}  // namespace btsm

#endif
