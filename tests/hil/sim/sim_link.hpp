#pragma once
// Test helper: a SimModule driven synchronously as a host link (send / step / capture), with the
// plant's truth recorded at every step for comparison with the SAMPLE frames.
#include "common/channels.hpp"
#include "host/sim/runner/sim_module.hpp"
#include "wire_capture.hpp"

#include <array>
#include <string>
#include <vector>

namespace btsm::test {

struct SimLink {
  explicit SimLink(sim::SimModuleOptions o) : m(std::move(o)) { record_truth(); }
  void send(const std::vector<uint8_t>& b) { m.host_send(b); }
  void step(double s) {
    m.run_for(s);
    cap.feed(m.host_receive());
    record_truth();
  }
  Capture& capture() { return cap; }
  void record_truth() {
    const auto r = m.truth();
    truth_t.push_back(r.time_s);
    std::array<double, 5> v{};
    for (int i = 0; i < 5; ++i) v[size_t(i)] = r.probe_c[i];
    truth_c.push_back(v);
  }
  // Linear interpolation of the recorded truth at t (s).
  double truth_at(double t, int ch) const {
    size_t i = 1;
    while (i < truth_t.size() && truth_t[i] < t) ++i;
    if (i >= truth_t.size()) return truth_c.back()[size_t(ch)];
    const double t0 = truth_t[i - 1], t1 = truth_t[i];
    const double w = t1 > t0 ? (t - t0) / (t1 - t0) : 0.0;
    return truth_c[i - 1][size_t(ch)] * (1 - w) + truth_c[i][size_t(ch)] * w;
  }

  sim::SimModule m;
  Capture cap;
  std::vector<double> truth_t;
  std::vector<std::array<double, kChannels>> truth_c;
};

// Test name of a fault case from its spec ("open:ch2@30" -> "open_ch2"): the fault without its
// time, in the characters GoogleTest allows.
inline std::string fault_case_name(const std::string& spec) {
  std::string n = spec.substr(0, spec.find('@'));
  for (auto& c : n)
    if (c == ':') c = '_';
  return n;
}

}  // namespace btsm::test
