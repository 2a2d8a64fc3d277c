#pragma once
// A link::Transport to an in-process SimModule: the host side (session, recorder) talks to the
// simulated module exactly as over a serial port, while the simulation is advanced synchronously
// by the reads. Deterministic (no threads, no pty), so a recording depends only on the plant,
// the noise seed and the host code. Each read advances the module by whole `step_s` until bytes
// arrive; after every step the plant's true probe temperatures are kept, so the recordings can
// be scored against the truth at the sample instants.
#include "host/link/transport.hpp"
#include "host/sim/runner/sim_module.hpp"

#include <array>
#include <vector>

namespace btsm::sim::suite {

struct TruthSample {
  double time_s = 0;                       // plant time, s
  std::array<double, kChannels> probe_c{};  // what each probe truly reads (effects incl.), degC
};

class ModuleTransport : public link::Transport {
 public:
  // `step_s`: simulated time per advance; `max_idle_s`: simulated time a read waits for bytes
  // before it reports a timeout.
  explicit ModuleTransport(SimModule& module, double step_s = 1.0, double max_idle_s = 30.0);

  std::string describe() const override { return "in-process simulated module"; }
  void write(std::span<const uint8_t> bytes) override;
  size_t read(std::span<uint8_t> out, link::Millis timeout) override;
  void reopen() override {}

  // Truth kept since the last clear (one row per step).
  const std::vector<TruthSample>& truth() const { return truth_; }
  void clear_truth() { truth_.clear(); }
  void keep_truth(bool on) { keep_truth_ = on; }

 private:
  SimModule& module_;
  double step_s_, max_idle_s_;
  std::vector<uint8_t> pending_;
  size_t pending_pos_ = 0;
  std::vector<TruthSample> truth_;
  bool keep_truth_ = false;
};

// Linear interpolation of the kept truth at plant time t for channel ch (1..5).
double truth_at(const std::vector<TruthSample>& truth, double t_s, int ch);

}  // namespace btsm::sim::suite
