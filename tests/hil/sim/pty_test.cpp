// The simulated module behind a pty: a host opens the symlink like a serial port; with
// wait_for_host the simulation pauses while nobody listens and never loses data when the host
// reads slowly; host -> module bytes arrive (GET_INFO is answered).
#include "host/sim/runner/sim_module.hpp"
#include "wire_capture.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <fcntl.h>
#include <poll.h>
#include <thread>
#include <unistd.h>

namespace btsm::test {
namespace {

using namespace std::chrono_literals;

TEST(SimModulePty, WaitsForTheHostAndLosesNothing) {
  const std::string link = testing::TempDir() + "/btsm-sim-pty-" + std::to_string(getpid());
  sim::SimModuleOptions o;
  o.pty_path = link;
  o.plant.speed = sim::SpeedProfile::parse("10m@6000");
  o.duration_s = 3600;  // ~80 KB of frames: far more than the ~16 KB pty buffer
  sim::SimModule m(o);
  char target[256] = {};
  ASSERT_GT(readlink(link.c_str(), target, sizeof target - 1), 0);
  EXPECT_EQ(std::string(target), m.pty_slave());
  m.start();
  std::this_thread::sleep_for(300ms);
  EXPECT_LT(m.sim_time_s(), 0.1) << "must not run while no host has the pty open";

  const int fd = open(link.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK);
  ASSERT_GE(fd, 0);
  Capture cap;
  const uint8_t seq = 3;
  const auto get_info = frame(uint8_t(wire::MsgType::GetInfo), seq, nullptr, 0);
  ASSERT_EQ(write(fd, get_info.data(), get_info.size()), ssize_t(get_info.size()));
  // Read slowly (small reads with pauses) until the run ends: back-pressure must hold the sim.
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (std::chrono::steady_clock::now() < deadline) {
    pollfd p{fd, POLLIN, 0};
    poll(&p, 1, 20);
    uint8_t buf[256];
    const ssize_t n = read(fd, buf, sizeof buf);
    if (n > 0) cap.feed(std::vector<uint8_t>(buf, buf + n));
    if (!m.running() && n <= 0) break;
    std::this_thread::sleep_for(1ms);
  }
  close(fd);
  m.wait();
  EXPECT_EQ(m.error(), "");
  EXPECT_NEAR(m.sim_time_s(), 3600.0, 0.1);
  ASSERT_FALSE(cap.samples.empty());
  ASSERT_EQ(cap.infos.size(), 1u) << "GET_INFO written to the pty must be answered";
  for (size_t i = 0; i < cap.samples.size(); ++i) EXPECT_EQ(cap.samples[i].sample_index, i) << "gap";
  EXPECT_EQ(cap.samples.size(), 720u);
  EXPECT_EQ(m.stats().bytes_dropped, 0u);
  EXPECT_EQ(cap.decoder.counters().bad_crc, 0u);
}

TEST(SimModulePty, RefusesToReplaceARegularFile) {
  const std::string path = testing::TempDir() + "/btsm-not-a-link-" + std::to_string(getpid());
  { std::FILE* f = std::fopen(path.c_str(), "w"); std::fclose(f); }
  sim::SimModuleOptions o;
  o.pty_path = path;
  EXPECT_THROW(sim::SimModule m(o), std::runtime_error);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace btsm::test
