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
    if (app.idle_budget_ms() > 0) board.power.idle();
  }
}
