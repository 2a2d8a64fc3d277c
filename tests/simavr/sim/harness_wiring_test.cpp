// Wiring checks of the simavr harness with a small probe program (firmware/wiring_probe.c):
// SPI bytes and chip select reach the device, DOUT/RDY reaches the MISO pin, tach pulses reach
// INT0, UART both ways, EEPROM survives power cycles and runs, sleeping is fast-forwarded.
#include "boards/sim/simavr/simavr_harness.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace btsm::sim {
namespace {

const char* kProbeElf = BTSM_WIRING_PROBE_ELF;

// A device that answers each byte with its bitwise complement and records the framing.
class FakeDevice : public SpiPeripheral {
 public:
  void set_cs(bool low) override {
    cs_low = low;
    log.push_back(low ? "cs-low" : "cs-high");
    if (low) since_select = 0.0;
    else last_select_s = since_select;
  }
  uint8_t transfer(uint8_t mosi) override {
    if (!cs_low) ADD_FAILURE() << "byte clocked while CS high";
    log.push_back("byte");
    received.push_back(mosi);
    return uint8_t(~mosi);
  }
  // DOUT/RDY falls `ready_after_s` after selection (like a conversion finishing).
  bool dout_low() override { return cs_low && since_select >= ready_after_s; }
  void advance(double s) override { since_select += s; now += s; }
  double time_to_next_event() override {
    return cs_low && since_select < ready_after_s ? ready_after_s - since_select : INFINITY;
  }
  void power_on_reset() override { resets++; }

  bool cs_low = false;
  double since_select = 0.0, now = 0.0, ready_after_s = 0.010, last_select_s = 0.0;
  int resets = 0;
  std::vector<std::string> log;
  std::vector<uint8_t> received;
};

class HarnessWiring : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kProbeElf)) GTEST_SKIP() << "probe image not built: " << kProbeElf;
    make();
  }
  void make(const std::string& eeprom_path = "", bool spi_real_timing = true) {
    HarnessOptions o;
    o.elf_path = kProbeElf;
    o.eeprom_path = eeprom_path;
    o.spi_real_timing = spi_real_timing;
    h = std::make_unique<SimavrHarness>(o, &dev);
    h->on_uart_tx = [this](uint8_t b) { rx.push_back(b); };
    ASSERT_TRUE(expect({'B'}, 2));
  }
  // Runs until `n` bytes arrived (at most 0.5 s of simulated time), checks the first ones.
  bool expect(const std::vector<uint8_t>& head, size_t n) {
    const double deadline = h->time_s() + 0.5;
    while (rx.size() < n && h->time_s() < deadline)
      if (!h->run_until(h->time_s() + 0.001)) return false;
    if (rx.size() < n) return false;
    for (size_t i = 0; i < head.size(); ++i)
      if (rx[i] != head[i]) return false;
    reply.assign(rx.begin(), rx.begin() + long(n));
    rx.erase(rx.begin(), rx.begin() + long(n));
    return true;
  }
  void send(const std::vector<uint8_t>& b) { h->uart_send(b.data(), b.size()); }

  FakeDevice dev;
  std::unique_ptr<SimavrHarness> h;
  std::vector<uint8_t> rx, reply;
};

TEST_F(HarnessWiring, SpiBytesReachTheDeviceOnlyWhileSelected) {
  send({'S', 3, 0x40, 0x12, 0xAB});
  ASSERT_TRUE(expect({'S', 3}, 5));
  EXPECT_EQ(reply[2], 0xBF);
  EXPECT_EQ(reply[3], 0xED);
  EXPECT_EQ(reply[4], 0x54);
  EXPECT_EQ(dev.received, (std::vector<uint8_t>{0x40, 0x12, 0xAB}));
  const std::vector<std::string> want{"cs-low", "byte", "byte", "byte", "cs-high"};
  EXPECT_EQ(dev.log, want);
  EXPECT_EQ(h->stats().spi_bytes, 3u);
}

TEST_F(HarnessWiring, SpiByteTakesTheRealClockTimeNotSimavrsFixed100us) {
  // 10 bytes under one chip select: with simavr 1.6's fixed 100 us per byte the select would
  // last >= 1 ms; at fosc/4 each byte is 32 cycles (2 us) plus the probe's loop overhead.
  send({'S', 10, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9});
  ASSERT_TRUE(expect({'S', 10}, 12));
  EXPECT_LT(dev.last_select_s, 100e-6) << "SPI completion was not moved to the real byte time";
  EXPECT_GT(dev.last_select_s, 10 * 2e-6);
}

TEST_F(HarnessWiring, WithoutTheFixSimavr16ChargesAFixed100usPerSpiByte) {
  make("", /*spi_real_timing=*/false);
  send({'S', 10, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9});
  ASSERT_TRUE(expect({'S', 10}, 12));
  EXPECT_GT(dev.last_select_s, 10 * 100e-6 * 0.99);
}

TEST_F(HarnessWiring, DoutRdyDrivesTheMisoPinWhileSelected) {
  send({'M'});
  ASSERT_TRUE(expect({'M'}, 2));
  EXPECT_EQ(reply[1], 1) << "MISO must idle high while CS is high";
  send({'C'});
  ASSERT_TRUE(expect({'C'}, 1));
  send({'M'});
  ASSERT_TRUE(expect({'M'}, 2));
  EXPECT_EQ(reply[1], 1) << "conversion not finished yet";
  h->run_until(h->time_s() + 0.02);
  send({'M'});
  ASSERT_TRUE(expect({'M'}, 2));
  EXPECT_EQ(reply[1], 0) << "RDY low must reach PB4";
  send({'c'});
  ASSERT_TRUE(expect({'c'}, 1));
  send({'M'});
  ASSERT_TRUE(expect({'M'}, 2));
  EXPECT_EQ(reply[1], 1);
}

TEST_F(HarnessWiring, TachPulsesReachInt0) {
  h->set_tach_hz(100.0);  // 6000 rpm at one pulse per revolution
  h->run_until(h->time_s() + 1.0);
  h->set_tach_hz(0.0);
  h->run_until(h->time_s() + 0.05);
  send({'T'});
  ASSERT_TRUE(expect({'T'}, 3));
  const int pulses = reply[1] | (reply[2] << 8);
  EXPECT_NEAR(pulses, 100, 1);
  EXPECT_EQ(uint64_t(pulses), h->stats().tach_pulses);
}

TEST_F(HarnessWiring, EepromSurvivesPowerCyclesAndRuns) {
  const std::string path = std::filesystem::temp_directory_path() / ("btsm_ee_" + std::to_string(getpid()) + ".bin");
  std::remove(path.c_str());
  make(path);
  send({'E', 5, 0x5A});
  ASSERT_TRUE(expect({'E'}, 1));
  h->power_cycle();
  EXPECT_EQ(dev.resets, 1);
  ASSERT_TRUE(expect({'B'}, 2));
  send({'R', 5});
  ASSERT_TRUE(expect({'R'}, 2));
  EXPECT_EQ(reply[1], 0x5A);
  h->save_eeprom();
  h.reset();
  make(path);  // a new run loads the image
  send({'R', 5});
  ASSERT_TRUE(expect({'R'}, 2));
  EXPECT_EQ(reply[1], 0x5A);
  std::remove(path.c_str());
}

TEST_F(HarnessWiring, SleepIsFastForwardedAndCounted) {
  h->run_until(h->time_s() + 10.0);  // the probe sleeps waiting for a command
  const auto s = h->stats();
  EXPECT_GT(double(s.sleep_cycles) / double(s.cycles), 0.99);
  EXPECT_NEAR(h->time_s(), 10.0, 0.01);
}

}  // namespace
}  // namespace btsm::sim
