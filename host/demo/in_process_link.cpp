#include "host/demo/in_process_link.hpp"

#include <algorithm>
#include <stdexcept>
#include <vector>

namespace btsm::demo {

InProcessLink::InProcessLink(sim::SimModule& module, double step_s) : module_(module), step_s_(step_s) {
  if (!(step_s > 0.0)) throw std::invalid_argument("in-process link: step must be > 0 s");
}

void InProcessLink::write(std::span<const uint8_t> bytes) {
  module_.host_send(std::vector<uint8_t>(bytes.begin(), bytes.end()));
}

size_t InProcessLink::read(std::span<uint8_t> out, link::Millis timeout) {
  const double end_s = module_.sim_time_s() + timeout.count() * 1e-3;
  for (;;) {
    const std::vector<uint8_t> got = module_.host_receive();
    pending_.insert(pending_.end(), got.begin(), got.end());
    if (!pending_.empty() || module_.sim_time_s() >= end_s - 1e-9) break;
    // Whole steps only: the host's timeouts are wall-clock deadlines, and a partial step would put
    // the simulation's I/O and plant-update boundaries where the host's clock happened to be --
    // a different measurement history on a busier machine.
    const double before = module_.sim_time_s();
    module_.run_for(step_s_);
    if (module_.sim_time_s() <= before) break;  // the module's run is over: nothing more will come
  }
  const size_t n = std::min(out.size(), pending_.size());
  std::copy_n(pending_.begin(), n, out.begin());
  pending_.erase(pending_.begin(), pending_.begin() + static_cast<long>(n));
  return n;
}

}  // namespace btsm::demo
