// Bluno Beetle (ATmega328P, 16 MHz) board: the hal/contracts.hpp Board contract at register level.
//
// Pin aliases (Arduino numbering / ATmega328P port pin):
//   AD7794 CS        D10 / PB2   (output, idle high)
//   AD7794 DIN       D11 / PB3   (MOSI)
//   AD7794 DOUT/RDY  D12 / PB4   (MISO; also read as the RDY level while CS is low)
//   AD7794 SCLK      D13 / PB5   (SCK)
//   Tachometer       D2  / PD2   (INT0, falling edge, internal pull-up)
//   BLE bridge UART  D0/D1 PD0/PD1 (115200 8N1, U2X, interrupt-driven ring buffers)
// Peripherals used: SPI (mode 3, f/4 = 4 MHz), USART0, Timer0 (1 ms tick), Timer1 (free-running
// 4 us time base for the tach period), EEPROM, watchdog (2 s), idle sleep.
#ifndef BTSM_BOARDS_BLUNO_BEETLE_BOARD_HPP
#define BTSM_BOARDS_BLUNO_BEETLE_BOARD_HPP

#include <avr/io.h>
#include <stdint.h>

#include "common/platform.hpp"

namespace btsm {
namespace bluno {

// Pin aliases: bit numbers in their port.
struct Pins {
  static constexpr uint8_t kAdcCs = PB2;
  static constexpr uint8_t kMosi = PB3;
  static constexpr uint8_t kMiso = PB4;  // = AD7794 DOUT/RDY
  static constexpr uint8_t kSck = PB5;
  static constexpr uint8_t kTach = PD2;  // INT0
};

static constexpr uint16_t kRxBufferBytes = 48;
// 72: a SAMPLE frame (~62-66 wire bytes) fits whole, so it is queued in one poll instead of being
// refilled over several (each poll costs a few hundred cycles). Ring indices are uint8_t.
static constexpr uint16_t kTxBufferBytes = 72;

// Forced inline (BTSM_ALWAYS_INLINE): each is one to four instructions, smaller than a call with
// its register shuffling, and transfer() runs ~200 times per sweep.
struct Spi {
  static BTSM_ALWAYS_INLINE void select() { PORTB &= static_cast<uint8_t>(~(1 << Pins::kAdcCs)); }
  static BTSM_ALWAYS_INLINE void deselect() { PORTB |= static_cast<uint8_t>(1 << Pins::kAdcCs); }
  static BTSM_ALWAYS_INLINE uint8_t transfer(uint8_t mosi) {
    SPDR = mosi;
    while (!(SPSR & (1 << SPIF))) {
    }
    return SPDR;
  }
  static BTSM_ALWAYS_INLINE bool miso_high() { return (PINB & (1 << Pins::kMiso)) != 0; }
};

namespace detail {
extern volatile uint8_t tx_buf[kTxBufferBytes];
extern volatile uint8_t tx_head, tx_tail;
extern volatile uint32_t ms_ticks;  // 1 ms tick count (little-endian: its first byte is the low one)
}  // namespace detail

struct Serial {
  static bool read(uint8_t& b);
  // Zero-copy transmit (the frame encoder stuffs its bytes straight into the ring): from head up
  // to the slot before tail, or to the end of the array when tail is not ahead of head. One
  // slot always stays empty (head == tail means empty). The tail read is a snapshot: the UDRE
  // interrupt only ever frees more.
  static BTSM_ALWAYS_INLINE uint8_t* tx_claim(uint8_t& n) {
    const uint8_t head = detail::tx_head;
    const uint8_t tail = detail::tx_tail;
    if (tail > head) {
      n = static_cast<uint8_t>(tail - head - 1);
    } else {
      n = static_cast<uint8_t>(kTxBufferBytes - head - (tail == 0 ? 1 : 0));
    }
    return const_cast<uint8_t*>(detail::tx_buf) + head;
  }
  // n <= the claimed n: head + n stays within the array (== its end wraps to 0).
  static BTSM_ALWAYS_INLINE void tx_commit(uint8_t n) {
    if (n == 0) return;
    // The bytes were stored through a plain pointer: keep the compiler from sinking those stores
    // below the head update that hands them to the interrupt (no instruction is emitted).
    asm volatile("" ::: "memory");
    uint8_t head = static_cast<uint8_t>(detail::tx_head + n);
    if (head == kTxBufferBytes) head = 0;
    detail::tx_head = head;  // only tx_commit writes it
    UCSR0B |= (1 << UDRIE0);
  }
};

struct Clock {
  static uint32_t millis();
  // Board-specific (not in the HAL contract), for the sleep loop in main.cpp: the low byte of the
  // 1 ms tick count -- one byte, so read without blocking interrupts.
  static BTSM_ALWAYS_INLINE uint8_t ticks_low() { return *reinterpret_cast<volatile uint8_t*>(&detail::ms_ticks); }
};

struct Storage {
  static uint16_t size() { return 1024; }
  // Forced inline: six instructions; the model step reads a 48-byte breakpoint every sweep, where
  // the call and its register shuffling doubled the cost per byte.
  static BTSM_ALWAYS_INLINE uint8_t read(uint16_t addr) {
    while (EECR & (1 << EEPE)) {
    }
    EEAR = addr;
    EECR |= (1 << EERE);
    return EEDR;
  }
  static bool busy() { return (EECR & (1 << EEPE)) != 0; }
  static void write(uint16_t addr, uint8_t value);
};

struct Watchdog {
  static void enable();
  static void kick();
  static bool caused_last_reset();
};

struct Power {
  // Idle sleep until the next interrupt. initialize() selects idle mode and sets the sleep-enable
  // bit once (nothing else in the image executes `sleep`), so this is the one instruction: the
  // loop in main.cpp wakes for every transmitted UART byte (~60 per frame) and every 1 ms tick,
  // and rewriting SMCR around each sleep cost ~11 cycles a wake. No lost wake-up: the caller
  // checks its events after the sleep, and the 1 ms tick bounds any sleep.
  static BTSM_ALWAYS_INLINE void idle() { asm volatile("sleep" ::: "memory"); }
  // True when poll() has work before its sleep budget ends: a received byte, or a finished AD7794
  // conversion (DOUT/RDY low while CS is held low, as Ad7794::start() leaves it).
  static bool wake_event();
  static void reboot();
  static uint8_t reset_flags();
};

struct Tach {
  static void set_pulses_per_rev(uint8_t n);
  static uint16_t rpm();
};

struct Identity {
  static void read_key_record(uint8_t* out, uint16_t n);
  static uint16_t entropy_bits();
};

struct Board {
  Spi spi;
  Serial serial;
  Clock clock;
  Storage storage;
  Watchdog watchdog;
  Power power;
  Tach tach;
  Identity identity;
  // Configures pins, SPI, UART, timers, the tach interrupt, and enables interrupts.
  static void initialize();
};

}  // namespace bluno
}  // namespace btsm

#endif
