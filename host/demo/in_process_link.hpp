#pragma once
// A link::Transport straight into a SimModule driven synchronously (no pty, no thread): reading
// advances the simulation in whole steps until the module has sent something or the timeout,
// counted in SIMULATED time, has passed. The whole host toolchain (Session, record, flash_model)
// then runs in one thread against the simulated module, deterministically whatever the machine's
// load (as long as no wall-clock reply deadline of the session expires: the module answers within
// milliseconds of simulated time) -- and the process may fork() to continue one simulated history
// in several ways (tests/bench/detection).
#include "host/link/transport.hpp"
#include "host/sim/runner/sim_module.hpp"

#include <cstdint>
#include <deque>

namespace btsm::demo {

class InProcessLink : public link::Transport {
 public:
  // `step_s`: simulated time per run_for() while waiting for bytes (the module's I/O chunk).
  explicit InProcessLink(sim::SimModule& module, double step_s = 0.05);

  std::string describe() const override { return "in-process simulated module"; }
  void write(std::span<const uint8_t> bytes) override;
  // Waits up to `timeout` (rounded up to whole steps) of simulated time; 0 only when nothing
  // arrived in that time.
  size_t read(std::span<uint8_t> out, link::Millis timeout) override;
  void reopen() override { pending_.clear(); }

  sim::SimModule& module() { return module_; }

 private:
  sim::SimModule& module_;
  double step_s_;
  std::deque<uint8_t> pending_;
};

}  // namespace btsm::demo
