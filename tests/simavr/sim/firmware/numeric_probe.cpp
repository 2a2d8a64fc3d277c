// Numeric probe: the common/ kernels that have an AVR-only form (inline assembly), run on the
// ATmega328P in simavr so tests/simavr/sim/avr_numeric_test.cpp can compare them with the host
// form on the same operands. Built with the firmware's compiler (avr-g++ 5.4, C++14).
//
// Commands over the UART (115200 8N1, little-endian operands), one reply per command:
//   'M' d:u32 f:u16          -> 'M' high:u32 low:u16   detail_rm::mul_u32_u16(d, f)
//   'L' p0:i32 p1:i32 f:u16  -> 'L' r:i32              detail_rm::lerp_q(p0, p1, f)
//   'T' r:u32                -> 'T' t:i32 status:u8    pt1000_temperature_q(r) (ohm x 2^16 -> 1/256 mK)
//   'F' a:u32 b:u32          -> 'F' q:u32 s:u32 h:u32  fx::frac_q32(a, b), fx::sqrt_mul(a, b),
//                                                      fx::mul_hi_round(a, b) (AVR assembly)
//   'K' q:u32 r:u32 dt:u32   -> 'K' ok:u8 one:u32 rho:u32 gain:u32 post:u32 gate:u32
//                                                      KalmanFixedSetup::configure (the firmware's
//                                                      filter setup from its configuration)
//   'G' p:u32                -> 'G' gain:u32 post:u32 gate:u32   gain_for(p) of the last 'K' setup
//   'S' a:i32 b:i32 t:i32 amb:i32 run:u8 c:i32 th:i32 -> 'S' t':i32 pred:i32   one channel of step_with()
//       (c != 0: channel 1, state th, is its carrier with coupling c)
// At boot it sends 'B'. Unknown command bytes are answered with '?'.
#include <avr/io.h>
#include <stdint.h>

#include "common/fixed_point.hpp"
#include "common/kalman.hpp"
#include "common/model_step.hpp"
#include "common/rtd.hpp"

namespace {

uint8_t get_byte() {
  while (!(UCSR0A & (1 << RXC0))) {
  }
  return UDR0;
}

void put_byte(uint8_t b) {
  while (!(UCSR0A & (1 << UDRE0))) {
  }
  UDR0 = b;
}

uint32_t get_u32() {
  uint32_t v = 0;
  for (uint8_t i = 0; i < 4; ++i) v |= static_cast<uint32_t>(get_byte()) << (8 * i);
  return v;
}

uint16_t get_u16() {
  const uint16_t lo = get_byte();
  return static_cast<uint16_t>(lo | static_cast<uint16_t>(get_byte()) << 8);
}

void put_u32(uint32_t v) {
  for (uint8_t i = 0; i < 4; ++i) put_byte(static_cast<uint8_t>(v >> (8 * i)));
}

btsm::KalmanFixedSetup setup;

}  // namespace

int main() {
  // 115200 8N1 at 16 MHz with U2X: UBRR = 16.
  UCSR0A = 1 << U2X0;
  UBRR0H = 0;
  UBRR0L = 16;
  UCSR0B = (1 << RXEN0) | (1 << TXEN0);
  UCSR0C = (1 << UCSZ01) | (1 << UCSZ00);
  put_byte('B');
  for (;;) {
    const uint8_t cmd = get_byte();
    if (cmd == 'M') {
      const uint32_t d = get_u32();
      const uint16_t f = get_u16();
      uint32_t high = 0;
      uint16_t low = 0;
      btsm::detail_rm::mul_u32_u16(d, f, high, low);
      put_byte('M');
      put_u32(high);
      put_byte(static_cast<uint8_t>(low));
      put_byte(static_cast<uint8_t>(low >> 8));
    } else if (cmd == 'L') {
      const int32_t p0 = static_cast<int32_t>(get_u32());
      const int32_t p1 = static_cast<int32_t>(get_u32());
      const uint16_t f = get_u16();
      put_byte('L');
      put_u32(static_cast<uint32_t>(btsm::detail_rm::lerp_q(p0, p1, f)));
    } else if (cmd == 'T') {
      const btsm::Pt1000FixedResult t = btsm::pt1000_temperature_q(get_u32());
      put_byte('T');
      put_u32(static_cast<uint32_t>(t.t));
      put_byte(static_cast<uint8_t>(t.status));
    } else if (cmd == 'F') {
      const uint32_t a = get_u32();
      const uint32_t b = get_u32();
      put_byte('F');
      put_u32(a < b ? btsm::fx::frac_q32(a, b) : 0);
      put_u32(a != 0 && b != 0 ? btsm::fx::sqrt_mul(a, b) : 0);
      put_u32(btsm::fx::mul_hi_round(a, b));
    } else if (cmd == 'K') {
      btsm::KalmanFixedParams kp;
      kp.q_mk2_per_s = get_u32();
      kp.r_mk2 = get_u32();
      kp.dt_ms = get_u32();
      const bool ok = setup.configure(kp);
      put_byte('K');
      put_byte(ok ? 1 : 0);
      put_u32(setup.one());
      put_u32(setup.rho());
      put_u32(setup.steady_gain());
      put_u32(setup.steady_post());
      put_u32(setup.steady_gate());
    } else if (cmd == 'G') {
      btsm::KalmanFixedGainMemo m;
      setup.gain_for(get_u32(), m);
      put_byte('G');
      put_u32(m.gain);
      put_u32(m.p_post);
      put_u32(m.gate);
    } else if (cmd == 'S') {
      // Channel 0 of the model step (its union-read 64-bit product and rounding on the target).
      btsm::ModelBreakpoint p;
      for (uint8_t j = 0; j < btsm::kModelChannels; ++j) p.ch[j].a_q30 = p.ch[j].b = 0;
      p.ch[0].a_q30 = static_cast<int32_t>(get_u32());
      p.ch[0].b = static_cast<int32_t>(get_u32());
      btsm::ReducedModelState st;
      for (uint8_t j = 0; j < btsm::kModelChannels; ++j) st.t[j] = 0;
      st.t[0] = static_cast<int32_t>(get_u32());
      st.stopped_ms = 0;
      const int32_t amb = static_cast<int32_t>(get_u32());
      const bool running = get_byte() != 0;
      btsm::ChannelCoupling k;
      for (uint8_t j = 0; j < btsm::kModelChannels; ++j) k.carrier[j] = btsm::kModelNoCarrier, k.c_q30[j] = 0;
      k.c_q30[0] = static_cast<int32_t>(get_u32());
      st.t[1] = static_cast<int32_t>(get_u32());  // channel 1 carries channel 0 when c != 0
      if (k.c_q30[0] != 0) k.carrier[0] = 2;
      int32_t pred[btsm::kModelChannels];
      btsm::step_with(p, k, running, btsm::kModelAmbientNone, 0x01, 5000, st, amb, pred);
      put_byte('S');
      put_u32(static_cast<uint32_t>(st.t[0]));
      put_u32(static_cast<uint32_t>(pred[0]));
    } else {
      put_byte('?');
    }
  }
}
