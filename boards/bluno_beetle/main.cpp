// ATmega328P entry point: board bring-up, then poll the firmware core and sleep in idle between
// polls (the 1 ms tick, the UART, the tach and nothing else wake the CPU).
#include <avr/io.h>

#include "boards/bluno_beetle/board.hpp"
#include "firmware/app.hpp"

namespace {
btsm::bluno::Board board;
btsm::App<btsm::bluno::Board> app(board);
}  // namespace

int main() {
  btsm::bluno::Board::initialize();
  app.init();
  for (;;) {
    app.poll();
    const uint32_t budget = app.idle_budget_ms();
    if (budget == 0) continue;
    // Sleep through the whole budget. The 1 ms tick still wakes the CPU, but poll() runs again
    // only when the budget is used up or an event needs it (a received byte, or DOUT/RDY of a
    // finished conversion): a full poll() on every tick cost ~500 cycles per ms, most of the CPU
    // load while waiting for conversions. Checking here costs a few dozen cycles per tick and
    // reacts to an event within one tick, as the poll-per-tick loop did. The time is counted in
    // the low byte of the tick count (one-byte reads, no interrupt lock, 8-bit arithmetic; the
    // loop wakes every tick, so it never misses 256 of them): the UART's transmit interrupt,
    // which ends a sleep once per byte of a frame, costs a byte compare instead of a 32-bit
    // millis() and comparison.
    uint16_t left = budget > 0xFFFFUL ? 0xFFFF : static_cast<uint16_t>(budget);
    uint8_t last = board.clock.ticks_low();
    for (;;) {
      board.power.idle();
      if (board.power.wake_event()) break;
      const uint8_t now = board.clock.ticks_low();
      const uint8_t passed = static_cast<uint8_t>(now - last);
      if (passed == 0) continue;  // not a tick (a UART byte): sleep on
      if (passed >= left) break;
      left = static_cast<uint16_t>(left - passed);
      last = now;
    }
  }
}
