#include "host/demo/demo_plan.hpp"

namespace btsm::demo {

double PlannedRun::duration_s() const {
  double s = 0;
  for (const auto& seg : segments) s += seg.duration_s;
  return s;
}

DemoPlan make_demo_plan(bool quick) {
  constexpr double h = 3600.0;
  DemoPlan p;
  // Warm-ups from (near) ambient, each followed by natural cooling: the cooling phases identify
  // the conduction network without any input, the warm-ups the speed laws and heat sources.
  const double warm = quick ? 3 * h : 4 * h, cool = quick ? 2 * h : 3 * h;
  const std::vector<double> speeds = quick ? std::vector<double>{4000, 7000} : std::vector<double>{4000, 6000, 8000};
  for (double rpm : speeds)
    p.identification.push_back({"warmup_" + std::to_string(static_cast<int>(rpm)) + "rpm",
                                {{warm, rpm}, {cool, 0}}, true});
  // External validation: speeds the fit never saw, stepped without cooling in between.
  const double step = quick ? 1 * h : 1.5 * h;
  p.identification.push_back({"stepwise_3000_5000_7000", {{step, 3000}, {step, 5000}, {step, 7000}, {cool, 0}}, false});

  // Production: normal running at changing speeds, then the bearing fault.
  p.production = {{1.5 * h, 5000}, {1 * h, 7000}, {0.5 * h, 0}, {1 * h, 6000}, {2 * h, 4500}, {6 * h, 6500}};
  p.fault_after_s = quick ? 3 * h : 4 * h;
  p.fault_heat_w = 30.0;
  p.reduce_speeds_rpm = {3000, 4500, 6000, 7500, 9000};
  return p;
}

}  // namespace btsm::demo
