#include "host/sim/suite/procedure.hpp"

#include <cmath>
#include <random>

namespace btsm::sim::suite {

double ProcedureRun::duration_s() const {
  double s = 0;
  for (const auto& g : segments) s += g.duration_s;
  return s;
}

SpeedProfile Procedure::speed() const {
  SpeedProfile p;
  double t = 0;
  for (const auto& r : runs) {
    if (r.start_s > t) p.append({r.start_s - t, 0.0});
    for (const auto& g : r.segments) p.append(g);
    t = r.start_s + r.duration_s();
  }
  // The module keeps sampling a little past the last row: stand still, do not end the profile.
  p.append({24 * 3600.0, 0.0});
  return p;
}

Procedure make_procedure(const ProcedureOptions& opts, unsigned rng_seed) {
  constexpr double h = 3600.0;
  std::mt19937 rng(rng_seed);
  std::uniform_real_distribution<double> jitter(-opts.speed_jitter_rpm, opts.speed_jitter_rpm);
  const auto speed = [&](double nominal) { return std::round(nominal + jitter(rng)); };
  const bool full = opts.size == ProcedureSize::Full;
  const std::vector<double> warm_speeds = full ? std::vector<double>{4000, 5000, 6000, 7000, 8000}
                                                : std::vector<double>{4000, 6000, 8000};
  const double warm = full ? 6 * h : 4 * h, cool = full ? 4 * h : 3 * h;
  const double step = full ? 2 * h : 1.5 * h, step_cool = 3 * h;

  Procedure p;
  double t = opts.lead_in_s;
  const auto add = [&](ProcedureRun r) {
    r.start_s = t;
    t += r.duration_s() + opts.idle_gap_s;
    p.runs.push_back(r);
  };
  for (double nominal : warm_speeds) {
    const double rpm = speed(nominal);
    add({"warmup_" + std::to_string(int(rpm)) + "rpm", {{warm, rpm}, {cool, 0}}, true});
  }
  const double s1 = speed(3000), s2 = speed(5000), s3 = speed(7000);
  add({"stepwise_" + std::to_string(int(s1)) + "_" + std::to_string(int(s2)) + "_" + std::to_string(int(s3)),
       {{step, s1}, {step, s2}, {step, s3}, {step_cool, 0}}, false});
  p.total_s = t - opts.idle_gap_s;
  return p;
}

}  // namespace btsm::sim::suite
