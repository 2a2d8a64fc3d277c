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
    // reacts to an event within one tick, as the poll-per-tick loop did.
    const uint32_t since = board.clock.millis();
    do {
      board.power.idle();
    } while (!board.power.wake_event() && board.clock.millis() - since < budget);
  }
}
