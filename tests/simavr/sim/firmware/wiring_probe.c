/* Wiring probe: a tiny ATmega328P program that exercises exactly the pins and peripherals the
 * simavr harness wires up (SPI + chip select PB2, DOUT/RDY on MISO PB4, INT0 tach on PD2, UART0,
 * EEPROM, SLEEP), driven by one-letter commands over the UART. The harness tests use it to prove
 * the wiring independently of the BTSM firmware image.
 *
 * Commands (host -> probe)            Reply (probe -> host)
 *   'S' n b1..bn  SPI transfer, CS    'S' n r1..rn   (CS low around the n bytes)
 *   'C' / 'c'     CS low / CS high    'C' / 'c'
 *   'M'           read MISO pin       'M' level(0/1)
 *   'T'           tach pulse count    'T' lo hi
 *   'E' a v       EEPROM write        'E'
 *   'R' a         EEPROM read         'R' v
 * At boot it sends 'B' and the reset cause (MCUSR). Between commands it sleeps (idle). */
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <stdint.h>

static volatile uint8_t rx_buf[64];
static volatile uint8_t rx_head, rx_tail;
static volatile uint16_t tach_pulses;

ISR(USART_RX_vect) { rx_buf[rx_head++ & 63] = UDR0; }
ISR(INT0_vect) { tach_pulses++; }

static uint8_t get_byte(void) {
  for (;;) {
    cli();
    if (rx_head != rx_tail) {
      uint8_t b = rx_buf[rx_tail++ & 63];
      sei();
      return b;
    }
    sleep_enable();
    sei();
    sleep_cpu();
    sleep_disable();
  }
}

static void put_byte(uint8_t b) {
  while (!(UCSR0A & (1 << UDRE0))) {
  }
  UDR0 = b;
}

static uint8_t spi(uint8_t b) {
  SPDR = b;
  while (!(SPSR & (1 << SPIF))) {
  }
  return SPDR;
}

int main(void) {
  uint8_t cause = MCUSR;
  MCUSR = 0;
  /* UART 115200 8N1 at 16 MHz with U2X: UBRR = 16. */
  UCSR0A = 1 << U2X0;
  UBRR0H = 0;
  UBRR0L = 16;
  UCSR0C = (1 << UCSZ01) | (1 << UCSZ00);
  UCSR0B = (1 << RXEN0) | (1 << TXEN0) | (1 << RXCIE0);
  /* SPI master, mode 3, fosc/4; CS (PB2) high output, MOSI/SCK outputs. */
  PORTB |= 1 << PB2;
  DDRB |= (1 << PB2) | (1 << PB3) | (1 << PB5);
  SPCR = (1 << SPE) | (1 << MSTR) | (1 << CPOL) | (1 << CPHA);
  /* INT0 on rising edges. */
  EICRA = (1 << ISC01) | (1 << ISC00);
  EIMSK = 1 << INT0;
  set_sleep_mode(SLEEP_MODE_IDLE);
  sei();
  put_byte('B');
  put_byte(cause);
  for (;;) {
    uint8_t cmd = get_byte();
    if (cmd == 'S') {
      uint8_t n = get_byte(), i, out[16];
      if (n > 16) n = 16;
      for (i = 0; i < n; ++i) out[i] = get_byte();
      PORTB &= ~(1 << PB2);
      for (i = 0; i < n; ++i) out[i] = spi(out[i]);
      PORTB |= 1 << PB2;
      put_byte('S');
      put_byte(n);
      for (i = 0; i < n; ++i) put_byte(out[i]);
    } else if (cmd == 'C') {
      PORTB &= ~(1 << PB2);
      put_byte('C');
    } else if (cmd == 'c') {
      PORTB |= 1 << PB2;
      put_byte('c');
    } else if (cmd == 'M') {
      put_byte('M');
      put_byte((PINB >> PB4) & 1);
    } else if (cmd == 'T') {
      uint16_t p;
      cli();
      p = tach_pulses;
      sei();
      put_byte('T');
      put_byte((uint8_t)p);
      put_byte((uint8_t)(p >> 8));
    } else if (cmd == 'E') {
      uint8_t a = get_byte(), v = get_byte();
      eeprom_write_byte((uint8_t*)(uint16_t)a, v);
      put_byte('E');
    } else if (cmd == 'R') {
      uint8_t a = get_byte();
      put_byte('R');
      put_byte(eeprom_read_byte((const uint8_t*)(uint16_t)a));
    } else {
      put_byte('?');
    }
  }
}
