#pragma once
// Stack depth by painting (ATmega328P in simavr): fill free SRAM with a pattern, run, then find
// the lowest address the stack overwrote. The free region between the end of .bss and the stack
// pointer may be painted at any instruction boundary: nothing lives below SP.
#include <simavr/sim_avr.h>

namespace btsm::bench {

constexpr int kRamEnd = 0x8FF;       // last SRAM address (RAMEND)
constexpr uint8_t kPaint = 0xA5;

inline int stack_pointer(const avr_t* avr) { return avr->data[0x5D] | (avr->data[0x5E] << 8); }

// Paints [from, to).
inline void paint_sram(avr_t* avr, int from, int to) {
  for (int a = from; a < to; ++a) avr->data[a] = kPaint;
}

struct StackDepth {
  int deepest_write;  // lowest address the stack reached
  int max_use;        // bytes from RAMEND down to it
  int margin;         // bytes between the end of .bss and it, never touched
};

inline StackDepth stack_depth(const avr_t* avr, int bss_end) {
  int d = bss_end;
  while (d <= kRamEnd && avr->data[d] == kPaint) ++d;
  return {d, kRamEnd - d + 1, d - bss_end};
}

}  // namespace btsm::bench
