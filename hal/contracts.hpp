// Hardware contracts of the BTSM firmware core.
//
// The firmware (firmware/app.hpp and the AD7794 driver) is a set of templates over a Board type;
// there is no virtual call anywhere (vtables land in SRAM on AVR, see docs). A Board is a plain
// object with the member sub-objects below. On the ATmega328P they are empty structs whose
// functions are static inline register accesses; on the native simulated board they forward to
// the simulation. `btsm::hal::CheckBoard<Board>` static_asserts the whole contract so a board that
// drifts from it fails to compile with a message naming the missing piece.
//
// Units: time in milliseconds (uint32_t, wraps after 49.7 days: compare with differences only),
// speed in rpm, EEPROM addresses in bytes.
//
// board.spi  -- SPI master, mode 3 (CPOL=1, CPHA=1), MSB first, one device (the AD7794):
//   void    select();                 // chip select low (AD7794 CS)
//   void    deselect();               // chip select high
//   uint8_t transfer(uint8_t mosi);   // full-duplex byte, blocking for 8 SCLK only (~1 us)
//   bool    miso_high();              // level of MISO = AD7794 DOUT/RDY. While CS is low and no
//                                     // transfer runs, low means "conversion ready".
// board.serial -- byte stream to the BLE bridge (UART 115200 8N1), never blocks:
//   bool     read(uint8_t& b);        // false when nothing is buffered
//   uint8_t* tx_claim(uint8_t& n);    // transmit, zero-copy: the free transmit space that is
//                                     // contiguous in memory, n bytes of it (0: full); fill a
//                                     // prefix of it, then
//   void     tx_commit(uint8_t n);    // hand its first n (<= the claimed n) bytes to the UART.
//                                     // Claim again after a commit (a ring wraps: two claims
//                                     // may be needed for all of its free space).
// board.clock -- monotonic time:
//   uint32_t millis();
// board.storage -- EEPROM-like byte storage, kSize bytes, power-loss behaviour of real EEPROM:
//   uint16_t size();
//   uint8_t  read(uint16_t addr);
//   bool     busy();                  // a write is still being programmed
//   void     write(uint16_t addr, uint8_t v);  // starts one byte write; only when !busy()
// board.watchdog:
//   void enable();                    // ~2 s timeout, resets the MCU when not kicked
//   void kick();
//   bool caused_last_reset();         // the previous reset came from the watchdog
// board.power:
//   void idle();                      // sleep until the next interrupt (>= 1 per ms tick)
//   void reboot();                    // software reset (does not return on hardware)
//   uint8_t reset_flags();            // MCUSR bits of the last reset (PORF 1, EXTRF 2, BORF 4, WDRF 8)
// board.tach -- spindle tachometer pulse input:
//   void     set_pulses_per_rev(uint8_t n);   // 1..255
//   uint16_t rpm();                   // 0 when no pulse for > 2 s (spindle stopped)
// board.identity:
//   void     read_key_record(uint8_t* out, uint16_t n); // copy the DeviceKeyRecord bytes
//   uint16_t entropy_bits();          // a few noisy bits (timer jitter); mixed into nonces
#ifndef BTSM_HAL_CONTRACTS_HPP
#define BTSM_HAL_CONTRACTS_HPP

#include <stdint.h>

#include "hal/type_checks.hpp"

namespace btsm {
namespace hal {
namespace contract {

BTSM_HAL_REQUIRE(SpiSelect, void, BTSM_BOARD.spi.select())
BTSM_HAL_REQUIRE(SpiDeselect, void, BTSM_BOARD.spi.deselect())
BTSM_HAL_REQUIRE(SpiTransfer, uint8_t, BTSM_BOARD.spi.transfer(uint8_t(0)))
BTSM_HAL_REQUIRE(SpiMisoHigh, bool, BTSM_BOARD.spi.miso_high())

BTSM_HAL_REQUIRE(SerialRead, bool, BTSM_BOARD.serial.read(::btsm::hal::detail::lvalue<uint8_t>()))
BTSM_HAL_REQUIRE(SerialTxClaim, uint8_t*, BTSM_BOARD.serial.tx_claim(::btsm::hal::detail::lvalue<uint8_t>()))
BTSM_HAL_REQUIRE(SerialTxCommit, void, BTSM_BOARD.serial.tx_commit(uint8_t(0)))

BTSM_HAL_REQUIRE(ClockMillis, uint32_t, BTSM_BOARD.clock.millis())

BTSM_HAL_REQUIRE(StorageSize, uint16_t, BTSM_BOARD.storage.size())
BTSM_HAL_REQUIRE(StorageRead, uint8_t, BTSM_BOARD.storage.read(uint16_t(0)))
BTSM_HAL_REQUIRE(StorageBusy, bool, BTSM_BOARD.storage.busy())
BTSM_HAL_REQUIRE(StorageWrite, void, BTSM_BOARD.storage.write(uint16_t(0), uint8_t(0)))

BTSM_HAL_REQUIRE(WatchdogEnable, void, BTSM_BOARD.watchdog.enable())
BTSM_HAL_REQUIRE(WatchdogKick, void, BTSM_BOARD.watchdog.kick())
BTSM_HAL_REQUIRE(WatchdogCause, bool, BTSM_BOARD.watchdog.caused_last_reset())

BTSM_HAL_REQUIRE(PowerIdle, void, BTSM_BOARD.power.idle())
BTSM_HAL_REQUIRE(PowerReboot, void, BTSM_BOARD.power.reboot())
BTSM_HAL_REQUIRE(PowerResetFlags, uint8_t, BTSM_BOARD.power.reset_flags())

BTSM_HAL_REQUIRE(TachPulses, void, BTSM_BOARD.tach.set_pulses_per_rev(uint8_t(1)))
BTSM_HAL_REQUIRE(TachRpm, uint16_t, BTSM_BOARD.tach.rpm())

BTSM_HAL_REQUIRE(IdentityKey, void,
                 BTSM_BOARD.identity.read_key_record(static_cast<uint8_t*>(0), uint16_t(0)))
BTSM_HAL_REQUIRE(IdentityEntropy, uint16_t, BTSM_BOARD.identity.entropy_bits())

}  // namespace contract

// Instantiate (e.g. `static_assert(CheckBoard<B>::value, "")` or as a base) to check a Board.
template <class Board>
struct CheckBoard {
  static_assert(contract::SpiSelect<Board>::value, "Board::spi.select() -> void missing");
  static_assert(contract::SpiDeselect<Board>::value, "Board::spi.deselect() -> void missing");
  static_assert(contract::SpiTransfer<Board>::value, "Board::spi.transfer(uint8_t) -> uint8_t missing");
  static_assert(contract::SpiMisoHigh<Board>::value, "Board::spi.miso_high() -> bool missing");
  static_assert(contract::SerialRead<Board>::value, "Board::serial.read(uint8_t&) -> bool missing");
  static_assert(contract::SerialTxClaim<Board>::value, "Board::serial.tx_claim(uint8_t&) -> uint8_t* missing");
  static_assert(contract::SerialTxCommit<Board>::value, "Board::serial.tx_commit(uint8_t) -> void missing");
  static_assert(contract::ClockMillis<Board>::value, "Board::clock.millis() -> uint32_t missing");
  static_assert(contract::StorageSize<Board>::value, "Board::storage.size() -> uint16_t missing");
  static_assert(contract::StorageRead<Board>::value, "Board::storage.read(uint16_t) -> uint8_t missing");
  static_assert(contract::StorageBusy<Board>::value, "Board::storage.busy() -> bool missing");
  static_assert(contract::StorageWrite<Board>::value, "Board::storage.write(uint16_t, uint8_t) -> void missing");
  static_assert(contract::WatchdogEnable<Board>::value, "Board::watchdog.enable() -> void missing");
  static_assert(contract::WatchdogKick<Board>::value, "Board::watchdog.kick() -> void missing");
  static_assert(contract::WatchdogCause<Board>::value, "Board::watchdog.caused_last_reset() -> bool missing");
  static_assert(contract::PowerIdle<Board>::value, "Board::power.idle() -> void missing");
  static_assert(contract::PowerReboot<Board>::value, "Board::power.reboot() -> void missing");
  static_assert(contract::PowerResetFlags<Board>::value, "Board::power.reset_flags() -> uint8_t missing");
  static_assert(contract::TachPulses<Board>::value, "Board::tach.set_pulses_per_rev(uint8_t) -> void missing");
  static_assert(contract::TachRpm<Board>::value, "Board::tach.rpm() -> uint16_t missing");
  static_assert(contract::IdentityKey<Board>::value,
                "Board::identity.read_key_record(uint8_t*, uint16_t) -> void missing");
  static_assert(contract::IdentityEntropy<Board>::value, "Board::identity.entropy_bits() -> uint16_t missing");
  static constexpr bool value = true;
};

}  // namespace hal
}  // namespace btsm

#endif
