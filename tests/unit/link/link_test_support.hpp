#pragma once
// Test plumbing: a pty pair whose slave path the host opens like a serial port, a temp dir, and
// a fault-injecting proxy between the host's pty and the fake module.
#include <atomic>
#include <cstdint>
#include <random>
#include <string>
#include <thread>

namespace btsm::test {

// openpty with the slave set raw at once (so nothing is echoed or translated before the host
// opens it) and kept open by the fixture (so the master never sees a hang-up between opens).
struct PtyPair {
  int master = -1, slave = -1;
  std::string path;
  PtyPair();
  ~PtyPair();
  int release_master();  // hands the master fd to someone else
  void close_master();
};

struct TempDir {
  std::string path;
  TempDir();
  ~TempDir();
};

struct FaultPlan {
  double drop_prob = 0;   // per byte
  double flip_prob = 0;   // per byte: one random bit flipped
  uint32_t seed = 1;
  bool host_to_module = true;
  bool module_to_host = true;
  long disconnect_after_host_bytes = -1;  // close the host side after this many host->module bytes
};

// Forwards bytes between host_fd and module_fd, damaging them per FaultPlan. Owns both fds.
class FaultProxy {
 public:
  FaultProxy(int host_fd, int module_fd, FaultPlan plan);
  ~FaultProxy();
  uint64_t dropped() const { return dropped_; }
  uint64_t flipped() const { return flipped_; }
  bool disconnected() const { return disconnected_; }

 private:
  void run();
  int host_fd_, module_fd_;
  FaultPlan plan_;
  std::mt19937 rng_;
  std::atomic<bool> running_{true};
  std::atomic<uint64_t> dropped_{0}, flipped_{0};
  std::atomic<bool> disconnected_{false};
  long host_bytes_ = 0;
  std::thread thread_;
};

}  // namespace btsm::test
