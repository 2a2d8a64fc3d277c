// AD7794 driver: register transactions over the board's SPI bus (template, no virtual calls).
//
// The register vocabulary is in firmware/ad7794_regs.hpp. This class only moves bytes; sequencing
// with waits (reset, calibrations, conversions) is done by the non-blocking acquisition state
// machine (firmware/acquisition.hpp), which polls `ready()` between other work.
//
// DOUT/RDY shares the MISO line: it signals "conversion ready" only while CS is low, so a
// conversion is started with `start()` which leaves CS asserted, and `finish()` releases it after
// the result has been read.
#ifndef BTSM_FIRMWARE_AD7794_HPP
#define BTSM_FIRMWARE_AD7794_HPP

#include <stdint.h>

#include "common/platform.hpp"
#include "firmware/ad7794_regs.hpp"

namespace btsm {

// What identify() found on the bus.
enum class AdcChip : uint8_t { kNone = 0, kAd7794 = 1, kAd7795 = 2 };

// Calibration coefficients of one channel, kept in MCU RAM (AIN4..AIN6 share one register pair
// on the chip, so the firmware restores each channel's own pair before converting it).
struct AdcCalibration {
  uint32_t offset;      // 24-bit offset register value
  uint32_t full_scale;  // 24-bit full-scale register value
};

template <class Spi>
class Ad7794 {
 public:
  explicit Ad7794(Spi& spi) : spi_(spi) {}

  // 32 ones on DIN reset the whole chip; the caller waits >= 500 us before the next access.
  void reset() {
    spi_.select();
    for (uint8_t i = 0; i < 4; ++i) spi_.transfer(0xFF);
    spi_.deselect();
  }

  // Reads ID and status. The ID's low nibble is 0xF on both AD7794 and AD7795; status bit 3
  // tells them apart. A missing chip reads 0xFF everywhere (MISO pulled up): 0xFF has the ID
  // nibble too, so the fixed-zero status bit 4 is what rejects it.
  AdcChip identify() {
    const uint8_t id = read8(ad7794::kRegId);
    const uint8_t status = read8(ad7794::kRegStatus);
    if ((id & ad7794::kIdMask) != ad7794::kIdAd779x || id == 0xFF) return AdcChip::kNone;
    if (status & 0x10) return AdcChip::kNone;  // bit 4 always reads 0 on a present chip
    return (status & ad7794::kStatusAd7794) ? AdcChip::kAd7794 : AdcChip::kAd7795;
  }

  uint8_t read8(uint8_t reg) { return static_cast<uint8_t>(read(reg, 1)); }
  uint16_t read16(uint8_t reg) { return static_cast<uint16_t>(read(reg, 2)); }
  uint32_t read24(uint8_t reg) { return read(reg, 3); }

  BTSM_NOINLINE uint32_t read(uint8_t reg, uint8_t width) {
    spi_.select();
    const uint32_t v = read_selected(reg, width);
    spi_.deselect();
    return v;
  }

  BTSM_NOINLINE void write(uint8_t reg, uint32_t value, uint8_t width) {
    spi_.select();
    write_selected(reg, value, width);
    spi_.deselect();
  }

  // Puts the chip in idle and writes the channel setup (before a calibration: a chip that was
  // just reset converts continuously). Leaves CS high.
  BTSM_NOINLINE void prepare_channel(uint16_t config, uint8_t fs) {
    spi_.select();
    write_selected(ad7794::kRegMode, ad7794::mode_word(ad7794::kModeIdle, fs), 2);
    write_selected(ad7794::kRegConfig, config, 2);
    spi_.deselect();
  }

  // Writes a channel's configuration -- and its calibration pair when cal is not null -- and
  // starts a single conversion at fs, all in one transaction; CS stays low so DOUT/RDY reports
  // completion through ready() (as after start()). Offset/full-scale writes are taken only in
  // idle or power-down: the caller guarantees one (a finished single conversion leaves the chip
  // powered down, a calibration leaves it idle).
  BTSM_NOINLINE void start_conversion(uint16_t config, const AdcCalibration* cal, uint8_t fs) {
    spi_.select();
    write_selected(ad7794::kRegConfig, config, 2);
    if (cal != 0) {
      write_selected(ad7794::kRegOffset, cal->offset, 3);
      write_selected(ad7794::kRegFullScale, cal->full_scale, 3);
    }
    write_selected(ad7794::kRegMode, ad7794::mode_word(ad7794::kModeSingle, fs), 2);
  }

  // Writes the mode register (single conversion or a calibration) and keeps CS low so DOUT/RDY
  // reports completion through ready().
  BTSM_NOINLINE void start(uint8_t mode, uint8_t fs) {
    spi_.select();
    write_selected(ad7794::kRegMode, ad7794::mode_word(mode, fs), 2);
  }

  // True once the running conversion/calibration finished (DOUT/RDY low while CS is low).
  bool ready() { return !spi_.miso_high(); }

  // Reads status then data of a finished conversion and releases CS.
  void finish_conversion(uint8_t& status, uint32_t& data, uint8_t data_width) {
    status = static_cast<uint8_t>(read_selected(ad7794::kRegStatus, 1));
    data = read_selected(ad7794::kRegData, data_width);
    spi_.deselect();
  }

  // Releases CS after a calibration (or an abandoned conversion).
  void finish() { spi_.deselect(); }

  AdcCalibration read_calibration() {
    AdcCalibration c;
    c.offset = read24(ad7794::kRegOffset);
    c.full_scale = read24(ad7794::kRegFullScale);
    return c;
  }

 private:
  // Unrolled by width (1..3): between two bytes only the next byte's register move, so the SPI
  // runs back to back (a loop added ~10 cycles of index/shift bookkeeping after every byte).
  BTSM_NOINLINE uint32_t read_selected(uint8_t reg, uint8_t width) {
    spi_.transfer(ad7794::comm_read(reg));
    const uint8_t b0 = spi_.transfer(0x00);
    if (width == 1) return b0;
    const uint8_t b1 = spi_.transfer(0x00);
    if (width == 2) return static_cast<uint16_t>(static_cast<uint16_t>(b0) << 8 | b1);
    const uint8_t b2 = spi_.transfer(0x00);
    return static_cast<uint32_t>(b0) << 16 | static_cast<uint16_t>(static_cast<uint16_t>(b1) << 8 | b2);
  }

  // width 1..3 (every AD7794 register is at most 24 bits), most significant byte first. The bytes
  // are split with constant shifts (plain register moves).
  BTSM_NOINLINE void write_selected(uint8_t reg, uint32_t value, uint8_t width) {
    spi_.transfer(ad7794::comm_write(reg));
    if (width >= 3) spi_.transfer(static_cast<uint8_t>(value >> 16));
    if (width >= 2) spi_.transfer(static_cast<uint8_t>(value >> 8));
    spi_.transfer(static_cast<uint8_t>(value));
  }

  Spi& spi_;
};

}  // namespace btsm

#endif
