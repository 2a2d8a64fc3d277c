// The common/ kernels with an AVR-only form (inline assembly in common/reduced_model.hpp) run on
// the simulated ATmega328P (firmware/numeric_probe.cpp, built with the firmware's compiler and
// flags) and are compared with the exact integer result on the host, operand by operand:
// random operands over the whole range plus the edge cases (zero, +-1, the int32 limits, the
// fraction's ends and the rounding tie). A wrong carry or register in the assembly shows here;
// the host build never compiles it.
#include "boards/sim/simavr/simavr_harness.hpp"
#include "common/reduced_model.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <random>
#include <vector>

namespace btsm::sim {
namespace {

const char* kProbeElf = BTSM_NUMERIC_PROBE_ELF;

// p0 + round((p1 - p0) f / 2^16), halves away from zero, in exact 64-bit arithmetic.
int32_t lerp_reference(int32_t p0, int32_t p1, uint16_t f) {
  const int64_t prod = (int64_t(p1) - int64_t(p0)) * int64_t(f);
  const int64_t mag = prod < 0 ? -prod : prod;
  const int64_t rounded = (mag + 0x8000) >> 16;
  return int32_t(int64_t(p0) + (prod < 0 ? -rounded : rounded));
}

class AvrNumeric : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kProbeElf)) GTEST_SKIP() << "probe image not built: " << kProbeElf;
    HarnessOptions o;
    o.elf_path = kProbeElf;
    h = std::make_unique<SimavrHarness>(o, nullptr);
    h->on_uart_tx = [this](uint8_t b) { rx.push_back(b); };
    ASSERT_TRUE(reply(1));
    ASSERT_EQ(rx[0], 'B');
  }
  // Runs until n reply bytes arrived (at most 50 ms of simulated time).
  bool reply(size_t n) {
    const double deadline = h->time_s() + 0.05;
    while (rx.size() < n && h->time_s() < deadline)
      if (!h->run_until(h->time_s() + 0.0002)) return false;
    return rx.size() >= n;
  }
  static void put32(std::vector<uint8_t>& b, uint32_t v) {
    for (int i = 0; i < 4; ++i) b.push_back(uint8_t(v >> (8 * i)));
  }
  static void put16(std::vector<uint8_t>& b, uint16_t v) {
    b.push_back(uint8_t(v));
    b.push_back(uint8_t(v >> 8));
  }
  static uint32_t get32(const uint8_t* p) { return p[0] | p[1] << 8 | p[2] << 16 | uint32_t(p[3]) << 24; }

  // Sends one command (its letter, then the operands) and returns the reply's operand bytes
  // (empty when the probe did not answer with the same letter and n bytes).
  std::vector<uint8_t> exchange(const std::vector<uint8_t>& cmd, size_t n) {
    rx.clear();
    h->uart_send(cmd.data(), cmd.size());
    EXPECT_TRUE(reply(1 + n)) << "no reply to " << char(cmd[0]);
    if (rx.size() < 1 + n || rx[0] != cmd[0]) return {};
    return std::vector<uint8_t>(rx.begin() + 1, rx.begin() + long(1 + n));
  }
  int32_t avr_lerp(int32_t p0, int32_t p1, uint16_t f) {
    std::vector<uint8_t> cmd{'L'};
    put32(cmd, uint32_t(p0));
    put32(cmd, uint32_t(p1));
    put16(cmd, f);
    const auto r = exchange(cmd, 4);
    return r.empty() ? 0 : int32_t(get32(r.data()));
  }
  void avr_mul(uint32_t d, uint16_t f, uint32_t& high, uint16_t& low) {
    std::vector<uint8_t> cmd{'M'};
    put32(cmd, d);
    put16(cmd, f);
    const auto r = exchange(cmd, 6);
    high = r.empty() ? 0 : get32(r.data());
    low = r.empty() ? 0 : uint16_t(r[4] | r[5] << 8);
  }

  std::unique_ptr<SimavrHarness> h;
  std::vector<uint8_t> rx;
};

TEST_F(AvrNumeric, WideMultiplyMatchesTheExactProduct) {
  std::mt19937 rng(7);
  std::vector<std::pair<uint32_t, uint16_t>> cases = {
      {0, 0}, {0xFFFFFFFFu, 0xFFFF}, {0xFFFFFFFFu, 1}, {1, 0xFFFF}, {0x80000000u, 0x8000},
      {0x00FF00FFu, 0xFF00}, {0xFF00FF00u, 0x00FF}, {0x12345678u, 0x9ABC}};
  for (int i = 0; i < 1500; ++i) cases.push_back({uint32_t(rng()), uint16_t(rng())});
  for (const auto& [d, f] : cases) {
    uint32_t high = 0;
    uint16_t low = 0;
    avr_mul(d, f, high, low);
    const uint64_t p = uint64_t(d) * f;
    ASSERT_EQ(high, uint32_t(p >> 16)) << std::hex << d << " * " << f;
    ASSERT_EQ(low, uint16_t(p)) << std::hex << d << " * " << f;
  }
}

TEST_F(AvrNumeric, InterpolationMatchesTheExactRoundingOnTheTarget) {
  std::mt19937 rng(11);
  const int32_t lim[] = {INT32_MIN, INT32_MIN + 1, -1, 0, 1, INT32_MAX - 1, INT32_MAX};
  const uint16_t fr[] = {0, 1, 0x7FFF, 0x8000, 0x8001, 0xFFFF};
  std::vector<std::tuple<int32_t, int32_t, uint16_t>> cases;
  for (int32_t a : lim)
    for (int32_t b : lim)
      for (uint16_t f : fr) cases.push_back({a, b, f});
  cases.push_back({0, 1, 0x8000});   // tie, upwards: away from zero
  cases.push_back({0, -1, 0x8000});  // tie, downwards
  cases.push_back({5, 3, 0x8000});
  for (int i = 0; i < 1500; ++i) {
    const int shift = int(rng() % 32);  // differences of every magnitude
    const int32_t p0 = int32_t(rng()) >> (rng() % 32);
    const int32_t p1 = int32_t(int64_t(p0) + (int64_t(int32_t(rng())) >> shift));
    cases.push_back({p0, p1, uint16_t(rng())});
  }
  for (const auto& [p0, p1, f] : cases) {
    const int32_t want = lerp_reference(p0, p1, f);
    ASSERT_EQ(detail_rm::lerp_q(p0, p1, f), want) << "host " << p0 << " " << p1 << " " << f;
    ASSERT_EQ(avr_lerp(p0, p1, f), want) << "avr " << p0 << " " << p1 << " " << f;
  }
}

}  // namespace
}  // namespace btsm::sim
