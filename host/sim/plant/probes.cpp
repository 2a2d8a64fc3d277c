#include "host/sim/plant/probes.hpp"

#include "common/rtd.hpp"

#include <stdexcept>
#include <string>

namespace btsm::sim {

double pt1000_ohm(double t_c) {
  const auto r = btsm::rtd_resistance(btsm::iec60751<double>(1000.0), t_c);
  if (!r.ok())
    throw std::out_of_range("probe temperature " + std::to_string(t_c) + " degC: " +
                            btsm::rtd_status_name(r.status));
  return r.value;
}

void apply_to_front_end(const SpindlePlant& plant, AnalogFrontEnd& fe) {
  for (int ch = 1; ch <= kChannels && ch <= AnalogFrontEnd::kProbes; ++ch) {
    const int i = ch - 1;
    fe.probe_ohm[i] = pt1000_ohm(plant.probe_temp_c(ch));
    switch (plant.probe_condition(ch)) {
      case ProbeCondition::Ok: fe.probe_fault[i] = ProbeFault::kNone; break;
      case ProbeCondition::Open:
      case ProbeCondition::Absent: fe.probe_fault[i] = ProbeFault::kOpenSense; break;
      case ProbeCondition::OpenChain: fe.probe_fault[i] = ProbeFault::kOpenElement; break;
      case ProbeCondition::Shorted: fe.probe_fault[i] = ProbeFault::kShort; break;
    }
  }
  fe.chip_missing = plant.adc_missing();
  fe.reference_lost = plant.reference_lost();
}

}  // namespace btsm::sim
