// Bluno Beetle board implementation (register level, avr-libc).
#include "boards/bluno_beetle/board.hpp"

#include <avr/interrupt.h>
#include <avr/pgmspace.h>
#include <avr/wdt.h>
#include <util/atomic.h>

#include "common/device_key.hpp"
#include "hal/contracts.hpp"

static_assert(btsm::hal::CheckBoard<btsm::bluno::Board>::value, "Bluno board must satisfy the HAL contract");
#if defined(BTSM_KEY_SECTION_ADDR)
static_assert(BTSM_KEY_SECTION_ADDR == btsm::device_key::kFlashAddress, "linker address of .btsm_key != device_key.hpp");
#endif
static_assert(sizeof(double) == 4, "avr-g++: double is 32-bit; the firmware must not rely on more");

// The per-device key record (common/device_key.hpp), linked at device_key::kFlashAddress by
// --section-start=.btsm_key. Erased (no key) unless the image is built with BTSM_DEV_KEY.
extern "C" const uint8_t btsm_device_key_record[btsm::device_key::kRecordSize]
    __attribute__((used, section(".btsm_key"))) = {
#if defined(BTSM_DEV_KEY)
        // magic "BTK1", device id 0x0000DE70, key 00..1F, CRC-32 over bytes 0..39 (little-endian).
        0x42, 0x54, 0x4B, 0x31, 0x70, 0xDE, 0x00, 0x00, 0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07,
        0x08, 0x09, 0x0A, 0x0B, 0x0C, 0x0D, 0x0E, 0x0F, 0x10, 0x11, 0x12, 0x13, 0x14, 0x15, 0x16, 0x17,
        0x18, 0x19, 0x1A, 0x1B, 0x1C, 0x1D, 0x1E, 0x1F, 0x4A, 0x46, 0xFE, 0x8E,
        0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF,
        0xFF, 0xFF, 0xFF,
#else
        0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF,
        0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF,
        0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF,
        0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF,
#endif
};

// Transmit ring, shared with the inline Serial::tx_claim/tx_commit in board.hpp.
volatile uint8_t btsm::bluno::detail::tx_buf[btsm::bluno::kTxBufferBytes];
volatile uint8_t btsm::bluno::detail::tx_head;  // written by Serial::tx_commit
volatile uint8_t btsm::bluno::detail::tx_tail;  // written by the UDRE ISR
volatile uint32_t btsm::bluno::detail::ms_ticks;  // written by the tick ISR

namespace {
using btsm::bluno::detail::tx_buf;
using btsm::bluno::detail::tx_head;
using btsm::bluno::detail::tx_tail;
using btsm::bluno::detail::ms_ticks;

volatile uint8_t rx_buf[btsm::bluno::kRxBufferBytes];
volatile uint8_t rx_head, rx_tail;  // head: written by ISR

volatile uint16_t timer1_high;      // Timer1 overflow count: 32-bit time base of 4 us ticks
volatile uint32_t tach_period_ticks;
volatile uint32_t tach_last_ticks;
volatile bool tach_seen;
uint8_t tach_ppr = 1;
uint8_t saved_mcusr;

// Ring index + 1 with wrap-around. A compare instead of `% size`: the ring sizes are not powers of
// two and the ATmega328P has no divider (a 16-bit modulo is a ~200-cycle library call, and this
// runs twice per UART byte, once in an ISR).
inline uint8_t ring_next(uint8_t i, uint8_t size) {
  ++i;
  return i == size ? 0 : i;
}

uint32_t timer1_now() {
  // Caller has interrupts disabled.
  uint16_t high = timer1_high;
  const uint16_t low = TCNT1;
  if ((TIFR1 & (1 << TOV1)) && low < 0x8000) ++high;  // overflow pending, not yet counted
  return (static_cast<uint32_t>(high) << 16) | low;
}

}  // namespace

// Runs before main and before any constructor: keep the reset cause, stop a watchdog that is
// still armed after a watchdog reset (it stays enabled with its shortest period otherwise).
extern "C" void btsm_early_init(void) __attribute__((naked, used, section(".init3")));
extern "C" void btsm_early_init(void) {
  saved_mcusr = MCUSR;
  MCUSR = 0;
  wdt_disable();
}

ISR(USART_RX_vect) {
  const uint8_t b = UDR0;
  const uint8_t next = ring_next(rx_head, btsm::bluno::kRxBufferBytes);
  if (next != rx_tail) {
    rx_buf[rx_head] = b;
    rx_head = next;
  }
}

// One transmitted byte (or, with the ring empty, UDRIE off): in C this was
//   tail = tx_tail; if (tx_head == tail) { UDRIE off; return; }
//   UDR0 = tx_buf[tail]; tx_tail = ring_next(tail, kTxBufferBytes);
// Hand-written because it runs for every byte of every frame (~60 per sample): saving three
// registers instead of seven (no r0/r1 needed) and reusing the post-incremented pointer for the
// next index make it ~46 cycles instead of ~56 including entry and reti.
static_assert(btsm::bluno::kTxBufferBytes < 256, "ring index is one byte");
ISR(USART_UDRE_vect, ISR_NAKED) {
  asm volatile(
      "push r24                        \n\t"
      "in   r24, __SREG__              \n\t"
      "push r24                        \n\t"
      "push r30                        \n\t"
      "push r31                        \n\t"
      "lds  r30, %[tail]               \n\t"
      "lds  r24, %[head]               \n\t"
      "cp   r30, r24                   \n\t"
      "breq 2f                         \n\t"
      "ldi  r31, 0                     \n\t"
      "subi r30, lo8(-(%[buf]))        \n\t"
      "sbci r31, hi8(-(%[buf]))        \n\t"
      "ld   r24, Z+                    \n\t"
      "sts  %[udr], r24                \n\t"
      "subi r30, lo8(%[buf])           \n\t"  // = tail + 1 (mod 256)
      "cpi  r30, %[size]               \n\t"
      "brne 1f                         \n\t"
      "ldi  r30, 0                     \n\t"
      "1:                              \n\t"
      "sts  %[tail], r30               \n\t"
      "3:                              \n\t"
      "pop  r31                        \n\t"
      "pop  r30                        \n\t"
      "pop  r24                        \n\t"
      "out  __SREG__, r24              \n\t"
      "pop  r24                        \n\t"
      "reti                            \n\t"
      "2:                              \n\t"
      "lds  r24, %[ucsrb]              \n\t"
      "andi r24, %[no_udrie]           \n\t"
      "sts  %[ucsrb], r24              \n\t"
      "rjmp 3b                         \n\t"
      :
      : [tail] "i"(&tx_tail), [head] "i"(&tx_head), [buf] "i"(tx_buf), [udr] "n"(_SFR_MEM_ADDR(UDR0)),
        [ucsrb] "n"(_SFR_MEM_ADDR(UCSR0B)), [size] "n"(btsm::bluno::kTxBufferBytes),
        [no_udrie] "n"(static_cast<uint8_t>(~(1 << UDRIE0))));
}

ISR(TIMER0_COMPA_vect) { ms_ticks = ms_ticks + 1; }

ISR(TIMER1_OVF_vect) { timer1_high = static_cast<uint16_t>(timer1_high + 1); }

// Tach period between falling edges, with a dead-band of one tick: a period within +-1 tick
// (+-4 us) of the stored one keeps the stored one. The timestamp of an edge is late by the
// interrupt latency and rounded down to a tick, so a constant speed reads as period +-1 tick; at
// 6000 rpm (2500 ticks) that alternated the reported speed between 6000 and 5998 rpm, each
// alternation a speed change for the model (new coefficients from EEPROM). The dead-band is the
// measurement's own resolution, rpm^2 * ppr / 15e6: +-2.4 rpm at 6000 rpm, +-0.6 at 3000, +-27 at
// 20000 (ppr 1) -- far below anything a thermal model of the spindle resolves (its breakpoints
// are thousands of rpm apart). A genuine change of 2 ticks or more is taken at once.
ISR(INT0_vect) {
  const uint32_t now = timer1_now();
  if (tach_seen) {
    const uint32_t period = now - tach_last_ticks;
    if (static_cast<uint32_t>(period - tach_period_ticks + 1) > 2) tach_period_ticks = period;
  }
  tach_last_ticks = now;
  tach_seen = true;
}

namespace btsm {
namespace bluno {

bool Serial::read(uint8_t& b) {
  if (rx_head == rx_tail) return false;
  b = rx_buf[rx_tail];
  rx_tail = ring_next(rx_tail, kRxBufferBytes);
  return true;
}

uint32_t Clock::millis() {
  uint32_t t;
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { t = ms_ticks; }
  return t;
}

void Storage::write(uint16_t addr, uint8_t value) {
  while (EECR & (1 << EEPE)) {
  }
  EEAR = addr;
  EEDR = value;
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
    EECR |= (1 << EEMPE);  // EEPE must follow within 4 cycles
    EECR |= (1 << EEPE);
  }
}

void Watchdog::enable() { wdt_enable(WDTO_2S); }
void Watchdog::kick() { wdt_reset(); }
bool Watchdog::caused_last_reset() { return (saved_mcusr & (1 << WDRF)) != 0; }

bool Power::wake_event() {
  if (rx_head != rx_tail) return true;
  const uint8_t pins = PINB;
  return (pins & ((1 << Pins::kAdcCs) | (1 << Pins::kMiso))) == 0;
}

void Power::reboot() {
  wdt_enable(WDTO_15MS);
  for (;;) {
  }
}

uint8_t Power::reset_flags() { return saved_mcusr; }

void Tach::set_pulses_per_rev(uint8_t n) { tach_ppr = n == 0 ? 1 : n; }

uint16_t Tach::rpm() {
  uint32_t period, last, now;
  bool seen;
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
    period = tach_period_ticks;
    last = tach_last_ticks;
    seen = tach_seen;
    now = timer1_now();
  }
  // No pulse for 2 s (500000 ticks of 4 us): stopped.
  if (!seen || period == 0 || now - last > 500000UL) return 0;
  // rpm = 60 s / (period * 4 us * pulses per rev) = 15e6 / (period * ppr), rounded, at most 65534
  const uint32_t denom = period * tach_ppr;
  if (denom <= 228) return 65534U;  // (15e6 + denom / 2) / denom > 65534 (also denom 0)
  // The quotient has 16 bits (<= 65502), so 16 steps of long division (libgcc's 32-bit division
  // runs 32, ~600 cycles every sweep); the remainder never exceeds n >> 1, no overflow.
  const uint32_t n = 15000000UL + denom / 2;
  uint32_t r = n >> 16;
  uint16_t low = static_cast<uint16_t>(n);
  uint16_t q = 0;
  for (uint8_t i = 0; i < 16; ++i) {
    r <<= 1;
    if (low & 0x8000U) r |= 1;  // a bit test: "| (low >> 15)" compiled to a dozen instructions
    low = static_cast<uint16_t>(low << 1);
    q = static_cast<uint16_t>(q << 1);
    if (r >= denom) {
      r -= denom;
      q |= 1;
    }
  }
  return q;
}

void Identity::read_key_record(uint8_t* out, uint16_t n) {
  for (uint16_t i = 0; i < n && i < device_key::kRecordSize; ++i)
    out[i] = pgm_read_byte(&btsm_device_key_record[i]);
}

uint16_t Identity::entropy_bits() {
  // Timer1 low bits at the moment of a host request: jitter of the BLE link timing.
  uint16_t t;
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { t = TCNT1; }
  return static_cast<uint16_t>(t ^ (static_cast<uint16_t>(ms_ticks) << 7));
}

void Board::initialize() {
  // SPI master, mode 3, f/4 = 4 MHz (the AD7794 takes SCLK up to 5 MHz: 100 ns high/low minimum).
  // transfer() busy-waits 8 SCLK per byte, so this is 32 CPU cycles per byte instead of 128 at
  // f/16 -- and it is the clock the simavr harness models (spi_sck_divider = 4).
  // CS high before SPI is enabled.
  PORTB |= (1 << Pins::kAdcCs) | (1 << Pins::kMiso);  // CS idle high; pull-up on DOUT/RDY
  DDRB |= (1 << Pins::kAdcCs) | (1 << Pins::kMosi) | (1 << Pins::kSck);
  DDRB &= static_cast<uint8_t>(~(1 << Pins::kMiso));
  SPCR = (1 << SPE) | (1 << MSTR) | (1 << CPOL) | (1 << CPHA);
  SPSR = 0;
  // USART0 115200 8N1 with U2X: UBRR = 16 (+2.1 %).
  UCSR0A = (1 << U2X0);
  UBRR0 = 16;
  UCSR0C = (1 << UCSZ01) | (1 << UCSZ00);
  UCSR0B = (1 << RXEN0) | (1 << TXEN0) | (1 << RXCIE0);
  // Timer0: CTC, /64, OCR0A = 249 -> 1 kHz tick.
  TCCR0A = (1 << WGM01);
  TCCR0B = (1 << CS01) | (1 << CS00);
  OCR0A = 249;
  TIMSK0 = (1 << OCIE0A);
  // Timer1: normal mode, /64 -> 4 us per tick, overflow extends it to 32 bits.
  TCCR1A = 0;
  TCCR1B = (1 << CS11) | (1 << CS10);
  TIMSK1 = (1 << TOIE1);
  // Tach on INT0, falling edge, pull-up.
  DDRD &= static_cast<uint8_t>(~(1 << Pins::kTach));
  PORTD |= (1 << Pins::kTach);
  EICRA = (1 << ISC01);
  EIMSK = (1 << INT0);
  // Idle sleep mode (SM2..0 = 0) with sleep enabled for good: Power::idle() is one `sleep`.
  SMCR = (1 << SE);
  sei();
}

}  // namespace bluno
}  // namespace btsm
