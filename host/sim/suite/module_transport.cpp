#include "host/sim/suite/module_transport.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace btsm::sim::suite {

ModuleTransport::ModuleTransport(SimModule& module, double step_s, double max_idle_s)
    : module_(module), step_s_(step_s), max_idle_s_(max_idle_s) {
  if (!(step_s > 0.0) || !(max_idle_s >= step_s)) throw std::invalid_argument("ModuleTransport: need 0 < step_s <= max_idle_s");
}

void ModuleTransport::write(std::span<const uint8_t> bytes) { module_.host_send({bytes.begin(), bytes.end()}); }

size_t ModuleTransport::read(std::span<uint8_t> out, link::Millis) {
  // The wall-clock timeout means nothing here: the module is only as far as the host lets it
  // run. Advance until it says something, up to max_idle_s of simulated time.
  for (double idle = 0; pending_pos_ >= pending_.size() && idle < max_idle_s_; idle += step_s_) {
    module_.run_for(step_s_);
    if (keep_truth_) {
      const TruthRow r = module_.truth();
      TruthSample s;
      s.time_s = r.time_s;
      std::copy(std::begin(r.probe_c), std::end(r.probe_c), s.probe_c.begin());
      truth_.push_back(s);
    }
    pending_ = module_.host_receive();
    pending_pos_ = 0;
  }
  const size_t n = std::min(out.size(), pending_.size() - pending_pos_);
  std::copy_n(pending_.begin() + long(pending_pos_), n, out.begin());
  pending_pos_ += n;
  return n;
}

double truth_at(const std::vector<TruthSample>& truth, double t_s, int ch) {
  if (truth.empty()) throw std::invalid_argument("truth_at: no truth kept");
  const auto it = std::lower_bound(truth.begin(), truth.end(), t_s,
                                   [](const TruthSample& s, double t) { return s.time_s < t; });
  if (it == truth.begin()) return truth.front().probe_c[size_t(ch - 1)];
  if (it == truth.end()) return truth.back().probe_c[size_t(ch - 1)];
  const auto& b = *it;
  const auto& a = *(it - 1);
  const double w = b.time_s > a.time_s ? (t_s - a.time_s) / (b.time_s - a.time_s) : 0.0;
  return a.probe_c[size_t(ch - 1)] * (1 - w) + b.probe_c[size_t(ch - 1)] * w;
}

}  // namespace btsm::sim::suite
