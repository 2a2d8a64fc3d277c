// AD7794 register map and field encodings: the chip's vocabulary without any bus. Shared by the
// driver (firmware/ad7794.hpp), the register-level model (boards/sim/ad7794_model.*) and tests.
// Bit positions: AD7794/AD7795 datasheet Rev. D register tables (communications, status, mode and
// configuration registers); derived command bytes are checked in the unit tests.
#ifndef BTSM_FIRMWARE_AD7794_REGS_HPP
#define BTSM_FIRMWARE_AD7794_REGS_HPP

#include <stdint.h>

#include "common/platform.hpp"

namespace btsm {

struct ad7794 {
  // Register addresses (RS2..RS0 of the communications register).
  enum Reg : uint8_t {
    kRegComm = 0,  // write: communications; read: status
    kRegStatus = 0,
    kRegMode = 1,
    kRegConfig = 2,
    kRegData = 3,
    kRegId = 4,
    kRegIo = 5,
    kRegOffset = 6,
    kRegFullScale = 7,
  };
  // Width in bytes of each register on the AD7794 (24-bit part; AD7795 data is 16 bit).
  // (No lookup tables here: on AVR a const table lands in SRAM unless placed in PROGMEM.)
  static constexpr uint8_t width(uint8_t reg) {
    return (reg & 7) == kRegMode || (reg & 7) == kRegConfig
               ? uint8_t(2)
               : ((reg & 7) == kRegData || (reg & 7) >= kRegOffset ? uint8_t(3) : uint8_t(1));
  }

  // Communications register: b7 WEN (0), b6 R/W, b5:3 RS, b2 CREAD, b1:0 = 0.
  static constexpr uint8_t kCommWen = 0x80;
  static constexpr uint8_t kCommRead = 0x40;
  static constexpr uint8_t kCommCread = 0x04;
  static constexpr uint8_t comm_read(uint8_t reg) { return uint8_t(kCommRead | ((reg & 7) << 3)); }
  static constexpr uint8_t comm_write(uint8_t reg) { return uint8_t((reg & 7) << 3); }
  static constexpr uint8_t kCommEnterContinuousRead = 0x5C;
  static constexpr uint8_t kCommLeaveContinuousRead = 0x58;

  // Status register.
  static constexpr uint8_t kStatusNotReady = 0x80;  // RDY: 0 = new data
  static constexpr uint8_t kStatusErr = 0x40;       // result clamped (over/under range, no ref)
  static constexpr uint8_t kStatusNoXref = 0x20;    // reference absent (REF_DET on)
  static constexpr uint8_t kStatusAd7794 = 0x08;    // 1 on AD7794 (24 bit), 0 on AD7795 (16 bit)
  static constexpr uint8_t kStatusChannelMask = 0x07;
  static constexpr uint8_t kStatusPowerOn = 0x88;

  // Mode register: b15:13 MD, b12 PSW, b9 AMP-CM, b7:6 CLK, b4 CHOP-DIS, b3:0 FS.
  enum Mode : uint8_t {
    kModeContinuous = 0,
    kModeSingle = 1,
    kModeIdle = 2,
    kModePowerDown = 3,
    kModeInternalZeroCal = 4,
    kModeInternalFullCal = 5,
    kModeSystemZeroCal = 6,
    kModeSystemFullCal = 7,
  };
  static constexpr uint16_t kModeMdShift = 13;
  static constexpr uint16_t kModeMdMask = 0xE000;
  static constexpr uint16_t kModePsw = 0x1000;
  static constexpr uint16_t kModeAmpCm = 0x0200;
  static constexpr uint16_t kModeClkShift = 6;
  static constexpr uint16_t kModeClkMask = 0x00C0;
  static constexpr uint16_t kModeChopDis = 0x0010;
  static constexpr uint16_t kModeFsMask = 0x000F;
  static constexpr uint16_t kModePowerOn = 0x000A;
  static constexpr uint16_t mode_word(uint8_t md, uint8_t fs) {
    return uint16_t((uint16_t(md & 7) << kModeMdShift) | (fs & kModeFsMask));
  }
  static constexpr uint8_t mode_of(uint16_t mode_reg) { return uint8_t(mode_reg >> kModeMdShift); }

  // Configuration register: b15:14 VBIAS, b13 BO, b12 U/B, b11 BOOST, b10:8 G, b7:6 REFSEL,
  // b5 REF_DET, b4 BUF, b3:0 CH.
  static constexpr uint16_t kConfVbiasMask = 0xC000;
  static constexpr uint16_t kConfBurnout = 0x2000;
  static constexpr uint16_t kConfUnipolar = 0x1000;
  static constexpr uint16_t kConfBoost = 0x0800;
  static constexpr uint16_t kConfGainShift = 8;
  static constexpr uint16_t kConfGainMask = 0x0700;
  static constexpr uint16_t kConfRefselShift = 6;
  static constexpr uint16_t kConfRefselMask = 0x00C0;
  static constexpr uint16_t kConfRefDet = 0x0020;
  static constexpr uint16_t kConfBuf = 0x0010;
  static constexpr uint16_t kConfChannelMask = 0x000F;
  static constexpr uint16_t kConfPowerOn = 0x0710;
  enum RefSel : uint8_t { kRefIn1 = 0, kRefIn2 = 1, kRefInternal = 2 };
  static constexpr uint8_t gain_code_of(uint16_t conf) { return uint8_t((conf & kConfGainMask) >> kConfGainShift); }
  static constexpr uint8_t channel_of(uint16_t conf) { return uint8_t(conf & kConfChannelMask); }
  static constexpr uint8_t refsel_of(uint16_t conf) { return uint8_t((conf & kConfRefselMask) >> kConfRefselShift); }

  // Channel codes (CH3..0).
  enum Channel : uint8_t {
    kAin1 = 0, kAin2 = 1, kAin3 = 2, kAin4 = 3, kAin5 = 4, kAin6 = 5,
    kTempSensor = 6, kAvddMonitor = 7, kAin1Shorted = 8,
  };
  // AIN1..AIN3 each have their own offset/full-scale register pair; AIN4..AIN6 share one.
  static constexpr uint8_t kFirstSharedCalChannel = kAin4;
  // Calibration register pair used by a channel: AIN1..AIN3 own one each, AIN4..AIN6 share pair 3.
  // Pair 4 is the internal one of the temperature sensor and AVDD monitor channels.
  static constexpr uint8_t kCalPairs = 5;
  static constexpr uint8_t cal_pair(uint8_t ch) {
    return ch <= kAin3 ? ch : (ch <= kAin6 ? uint8_t(3) : (ch == kAin1Shorted ? uint8_t(0) : uint8_t(4)));
  }

  // IO register: b6 IOEN, b5 IO2DAT, b4 IO1DAT, b3:2 IEXCDIR, b1:0 IEXCEN.
  enum Iexc : uint8_t { kIexcOff = 0, kIexc10uA = 1, kIexc210uA = 2, kIexc1mA = 3 };
  enum IexcDir : uint8_t {
    kIexc1ToIout1 = 0,   // IEXC1 -> IOUT1, IEXC2 -> IOUT2
    kIexc1ToIout2 = 1,   // swapped
    kIexcBothIout1 = 2,  // both to IOUT1 (10 uA / 210 uA only)
    kIexcBothIout2 = 3,
  };
  static constexpr uint8_t kIoEn = 0x40;
  static constexpr uint8_t kIoDirShift = 2;
  static constexpr uint8_t kIoDirMask = 0x0C;
  static constexpr uint8_t kIoEnMask = 0x03;
  static constexpr uint8_t io_word(uint8_t dir, uint8_t iexc) {
    return uint8_t(((dir & 3) << kIoDirShift) | (iexc & kIoEnMask));
  }

  static constexpr uint32_t kOffsetPowerOn = 0x800000UL;
  static constexpr uint8_t kIdMask = 0x0F;
  static constexpr uint8_t kIdAd779x = 0x0F;

  // Update rates (chop on, internal 64 kHz clock). Index = FS code, 0 is reserved.
  // Output data rate in mHz and the settling time (= 2 / f_ADC) in milliseconds.
  // (Switches, built with -fno-tree-switch-conversion on AVR so no table lands in SRAM.)
  static uint32_t rate_mhz(uint8_t fs) {
    switch (fs & 15) {
      case 1: return 470000; case 2: return 242000; case 3: return 123000; case 4: return 62000;
      case 5: return 50000; case 6: return 39000; case 7: return 33200; case 8: return 19600;
      case 9: return 16700; case 10: return 16700; case 11: return 12500; case 12: return 10000;
      case 13: return 8330; case 14: return 6250; case 15: return 4170; default: return 0;
    }
  }
  static uint16_t settle_ms(uint8_t fs) {
    switch (fs & 15) {
      case 1: return 4; case 2: return 8; case 3: return 16; case 4: return 32; case 5: return 40;
      case 6: return 48; case 7: return 60; case 8: return 101; case 9: return 120; case 10: return 120;
      case 11: return 160; case 12: return 200; case 13: return 240; case 14: return 320;
      case 15: return 480; default: return 0;
    }
  }
  static constexpr uint8_t gain_of_code(uint8_t code) { return uint8_t(1u << (code & 7)); }
};

}  // namespace btsm

#endif
