// The common/ kernels with an AVR-only form (inline assembly, union reads of 64-bit products in
// common/model_step.hpp) run on the simulated ATmega328P (firmware/numeric_probe.cpp, built with the
// firmware's compiler and flags) and are compared with the exact integer result on the host, operand
// by operand:
// random operands over the whole range plus the edge cases (zero, +-1, the int32 limits, the
// fraction's ends and the rounding tie). A wrong carry or register in the assembly shows here;
// the host build never compiles it. Likewise the integer sample path (the Pt1000 table inverse,
// the fixed-point kernels and the Kalman filter's setup and gains), whose C++ could compute
// differently where int is 16 bits: bit for bit against the host build.
#include "boards/sim/simavr/simavr_harness.hpp"
#include "common/fixed_point.hpp"
#include "common/kalman.hpp"
#include "common/model_step.hpp"
#include "common/rtd.hpp"

#include <gtest/gtest.h>

#include <array>
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

  // One channel's model step on the target: the new state and the prediction.
  // c, th: channel 0's coupling on its carrier (channel 1, whose state is th); c = 0 = no carrier.
  std::pair<int32_t, int32_t> avr_step(int32_t a, int32_t b, int32_t t, int32_t amb, bool running, int32_t c = 0,
                                       int32_t th = 0) {
    std::vector<uint8_t> cmd{'S'};
    put32(cmd, uint32_t(a));
    put32(cmd, uint32_t(b));
    put32(cmd, uint32_t(t));
    put32(cmd, uint32_t(amb));
    cmd.push_back(running ? 1 : 0);
    put32(cmd, uint32_t(c));
    put32(cmd, uint32_t(th));
    const auto r = exchange(cmd, 8);
    return r.empty() ? std::make_pair(0, 0) : std::make_pair(int32_t(get32(r.data())), int32_t(get32(r.data() + 4)));
  }

  std::unique_ptr<SimavrHarness> h;
  std::vector<uint8_t> rx;
};

TEST_F(AvrNumeric, Pt1000TableInverseIsTheHostsBitForBit) {
  std::mt19937 rng(13);
  std::vector<uint32_t> rs = {0, 1, detail_rtd::kPt1000FixedMinQ16 - 1, detail_rtd::kPt1000FixedMinQ16,
                              detail_rtd::kPt1000FixedMaxQ16, detail_rtd::kPt1000FixedMaxQ16 + 1, 1000u << 16,
                              (1024u << 16) - 1, 1024u << 16, 2048u << 16, 0xFFFFFFFFu};
  for (int i = 0; i < 1500; ++i) rs.push_back(detail_rtd::kPt1000FixedMinQ16 + rng() % (260u << 20));
  for (uint32_t r : rs) {
    std::vector<uint8_t> cmd{'T'};
    put32(cmd, r);
    const auto got = exchange(cmd, 5);
    ASSERT_EQ(got.size(), 5u);
    const Pt1000FixedResult want = pt1000_temperature_q(r);
    ASSERT_EQ(uint8_t(want.status), got[4]) << r;
    ASSERT_EQ(uint32_t(want.t), get32(got.data())) << r;
  }
}

TEST_F(AvrNumeric, FixedPointKernelsAreTheHostsBitForBit) {
  std::mt19937 rng(17);
  std::vector<std::pair<uint32_t, uint32_t>> cases = {{0, 0}, {0xFFFFFFFFu, 0xFFFFFFFFu}, {0x80000000u, 1},
                                                      {0x7FFFFFFFu, 1}, {0x80000000u, 3}, {1, 0xFFFFFFFFu},
                                                      {0x00FF00FFu, 0xFF00FF00u}, {0x12345678u, 0x9ABCDEF0u}};
  for (int i = 0; i < 1500; ++i) {
    uint32_t a = rng() >> (rng() % 32), b = rng() >> (rng() % 32);
    if (i % 2 && a > b) std::swap(a, b);
    cases.push_back({a, b});
  }
  for (const auto& [a, b] : cases) {
    std::vector<uint8_t> cmd{'F'};
    put32(cmd, a);
    put32(cmd, b);
    const auto got = exchange(cmd, 12);
    ASSERT_EQ(got.size(), 12u);
    ASSERT_EQ(get32(got.data()), a < b ? fx::frac_q32(a, b) : 0u) << a << " " << b;
    ASSERT_EQ(get32(got.data() + 4), a && b ? fx::sqrt_mul(a, b) : 0u) << a << " " << b;
    // The assembly against the exact rounded high word.
    ASSERT_EQ(get32(got.data() + 8), uint32_t((uint64_t(a) * b + 0x80000000u) >> 32)) << std::hex << a << " * " << b;
  }
}

// The filter's setup over the configuration range, and its gain computation for variances from
// the settle sequence, after rejections and random ones: the same integers on the AVR.
TEST_F(AvrNumeric, KalmanSetupAndGainsAreTheHostsBitForBit) {
  std::mt19937 rng(19);
  std::vector<std::array<uint32_t, 3>> cfgs = {{400, 2500, 5000}, {1, 1, 1000}, {100000000, 1, 600000},
                                               {1, 100000000, 1000}, {100, 100, 5000}, {0, 2500, 5000}};
  for (int i = 0; i < 40; ++i)
    cfgs.push_back({uint32_t(1 + rng() % 100000000), uint32_t(1 + rng() % 100000000), uint32_t(1000 + rng() % 599001)});
  for (const auto& c : cfgs) {
    std::vector<uint8_t> cmd{'K'};
    for (uint32_t v : c) put32(cmd, v);
    const auto got = exchange(cmd, 21);
    ASSERT_EQ(got.size(), 21u);
    KalmanFixedParams kp;
    kp.q_mk2_per_s = c[0];
    kp.r_mk2 = c[1];
    kp.dt_ms = c[2];
    KalmanFixedSetup k;
    ASSERT_EQ(k.configure(kp) ? 1 : 0, got[0]) << c[0] << " " << c[1] << " " << c[2];
    if (!got[0]) continue;
    ASSERT_EQ(get32(got.data() + 1), k.one());
    ASSERT_EQ(get32(got.data() + 5), k.rho());
    ASSERT_EQ(get32(got.data() + 9), k.steady_gain());
    ASSERT_EQ(get32(got.data() + 13), k.steady_post());
    ASSERT_EQ(get32(got.data() + 17), k.steady_gate());
    std::vector<uint32_t> ps = {k.one(), k.steady_post() + k.rho(), k.steady_post() + 3 * k.rho(), 1, 0x7FFFFFFF};
    for (int j = 0; j < 8; ++j) ps.push_back(1 + rng() % (2 * k.one()));
    for (uint32_t pv : ps) {
      std::vector<uint8_t> g{'G'};
      put32(g, pv);
      const auto gg = exchange(g, 12);
      ASSERT_EQ(gg.size(), 12u);
      KalmanFixedGainMemo m;
      k.gain_for(pv, m);
      ASSERT_EQ(get32(gg.data()), m.gain) << pv;
      ASSERT_EQ(get32(gg.data() + 4), m.p_post) << pv;
      ASSERT_EQ(get32(gg.data() + 8), m.gate) << pv;
    }
  }
}

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

// The model step on the target against the exact int64 form: T' = T_amb + round(a (T - T_amb)) +
// u b + round(c (T_h - T_amb)) (ties away from zero), clamped; prediction = T rounded to mK (ties up).
TEST_F(AvrNumeric, ModelStepMatchesTheExactFormOnTheTarget) {
  std::mt19937 rng(13);
  struct Case {
    int32_t a, b, t, amb;
    bool run;
    int32_t c = 0, th = 0;
  };
  std::vector<Case> cases = {{0, 0, 0, 0, false},
                             {(1 << 30) - 1, 0, (1 << 30) - 1, -1048575, true},
                             {(1 << 30) - 1, 1024000000, -(1 << 30) + 1, 1048575, true},
                             {1 << 29, 0, 1, 0, false},   // a (T - T_amb) = 1/2: tie, away from zero
                             {1 << 29, 0, -1, 0, false},  // -1/2
                             {1 << 29, 7, 3, 0, true}};
  for (int i = 0; i < 1500; ++i) {
    const int32_t a = int32_t(rng() % (1u << 30));
    const int32_t amb = int32_t(rng() % 2097151) - 1048575;
    const int32_t t = int32_t(int64_t(rng() % 2147483647u) - 1073741823);
    const double bound = 1.024e9 * ((1 << 30) - a) / double(1 << 30);
    const int32_t b = int32_t((double(rng() % 2000001) / 1e6 - 1.0) * bound);
    Case k{a, b, t, amb, (rng() & 1) != 0};
    if (i % 2) {  // with a carrier: any coupling in [0, 1), the carrier's state over the whole range
      k.c = int32_t(rng() % (1u << 30));
      k.th = int32_t(int64_t(rng() % 2147483647u) - 1073741823);
    }
    cases.push_back(k);
  }
  cases.push_back({(1 << 30) - 1, 1024000000, (1 << 30) - 1, -1048575, true, (1 << 30) - 1, (1 << 30) - 1});  // saturates high
  cases.push_back({(1 << 30) - 1, -1024000000, -(1 << 30) + 1, 1048575, true, (1 << 30) - 1, -(1 << 30) + 1});  // and low
  cases.push_back({0, 0, 0, 0, false, 1 << 29, 1});  // c (T_h - T_amb) = 1/2: tie
  for (const Case& c : cases) {
    const int64_t amb = int64_t(c.amb) * 1024;
    int64_t next = amb + fx::shift_right_round(int64_t(c.a) * (c.t - amb), 30, fx::Rounding::kNearestHalfAway);
    if (c.run) next += c.b;
    if (c.c != 0) next += fx::shift_right_round(int64_t(c.c) * (c.th - amb), 30, fx::Rounding::kNearestHalfAway);
    next = std::clamp<int64_t>(next, -kModelStateLimit, kModelStateLimit);
    const int32_t pred = int32_t(fx::shift_right_round(int64_t(c.t) + 512, 10, fx::Rounding::kFloor));
    const auto [t_avr, pred_avr] = avr_step(c.a, c.b, c.t, c.amb, c.run, c.c, c.th);
    ASSERT_EQ(t_avr, int32_t(next)) << c.a << " " << c.b << " " << c.t << " " << c.amb;
    ASSERT_EQ(pred_avr, pred) << c.t;
  }
}

}  // namespace
}  // namespace btsm::sim
