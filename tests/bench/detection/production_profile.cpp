#include "tests/bench/detection/production_profile.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <stdexcept>

namespace btsm::bench {

const char* moment_kind_name(MomentKind k) {
  switch (k) {
    case MomentKind::ColdStart: return "cold start";
    case MomentKind::Restart: return "restart";
    case MomentKind::StepUp: return "step up";
    case MomentKind::StepDown: return "step down";
    case MomentKind::Steady: return "steady";
  }
  return "?";
}

double ProductionProfile::duration_s() const {
  double s = 0;
  for (const auto& g : segments) s += g.duration_s;
  return s;
}

std::string ProductionProfile::describe() const {
  std::map<MomentKind, int> n;
  for (const auto& m : moments) ++n[m.kind];
  double lo = 1e9, hi = 0, running = 0;
  for (const auto& g : segments)
    if (g.rpm > 0) lo = std::min(lo, g.rpm), hi = std::max(hi, g.rpm), running += g.duration_s;
  return fmt::format("{:.0f} h ({:.1f} h running at {:.0f}-{:.0f} rpm), {} cold starts, {} restarts after short stops, "
                     "{} steps up, {} steps down",
                     duration_s() / 3600, running / 3600, lo, hi, n[MomentKind::ColdStart], n[MomentKind::Restart],
                     n[MomentKind::StepUp], n[MomentKind::StepDown]);
}

ProductionProfile make_production_profile(const ProductionProfileOptions& o) {
  if (!(o.hours > 0) || !(o.shift_h > 0) || !(o.min_segment_min > 0) || o.max_segment_min < o.min_segment_min ||
      !(o.stop_every_min_h > 0) || o.stop_every_max_h < o.stop_every_min_h || !(o.stop_min > 0) ||
      !(o.rpm_step > 0) || !(o.rpm_min > 0) || o.rpm_max < o.rpm_min + o.rpm_step)
    throw std::invalid_argument("production profile: inconsistent options");
  std::mt19937 rng(o.seed);
  // Uniform draws from the generator's raw output (its distributions are not portable).
  auto uniform = [&rng](double lo, double hi) { return lo + (hi - lo) * (double(rng()) / 4294967296.0); };
  const int levels = int(std::lround((o.rpm_max - o.rpm_min) / o.rpm_step));
  auto any_speed = [&] { return o.rpm_min + o.rpm_step * std::min(levels, int(uniform(0, levels + 1))); };

  ProductionProfile p;
  const double total = o.hours * 3600;
  double t = 0;
  while (t < total - 1) {
    // One day: the shift, then the night stop.
    const double shift_end = std::min(total, t + o.shift_h * 3600);
    double rpm = any_speed();
    double next_stop = t + uniform(o.stop_every_min_h, o.stop_every_max_h) * 3600;
    MomentKind start = MomentKind::ColdStart;
    while (t < shift_end - 1) {
      const double len = std::min(shift_end - t, uniform(o.min_segment_min, o.max_segment_min) * 60);
      p.segments.push_back({len, rpm});
      p.moments.push_back({start, t + (start == MomentKind::ColdStart ? 15 * 60 : start == MomentKind::Restart ? 10 * 60 : 5 * 60), rpm});
      if (len >= 3600) p.moments.push_back({MomentKind::Steady, t + 45 * 60, rpm});
      t += len;
      if (t >= shift_end - 1) break;
      if (t >= next_stop) {
        const double stop = std::min(shift_end - t, o.stop_min * 60);
        p.segments.push_back({stop, 0});
        t += stop;
        next_stop = t + uniform(o.stop_every_min_h, o.stop_every_max_h) * 3600;
        rpm = any_speed();
        start = MomentKind::Restart;
        continue;
      }
      bool up = uniform(0, 1) < 0.5;
      if (rpm + o.rpm_step > o.rpm_max + 1) up = false;
      if (rpm - o.rpm_step < o.rpm_min - 1) up = true;
      rpm += up ? o.rpm_step : -o.rpm_step;
      start = up ? MomentKind::StepUp : MomentKind::StepDown;
    }
    if (t < total - 1) {
      const double night = std::min(total - t, (24 - o.shift_h) * 3600);
      p.segments.push_back({night, 0});
      t += night;
    }
  }
  // A moment after the profile's end, or one that falls into a stop, is no moment of running.
  auto rpm_at = [&p](double at) {
    double s = 0;
    for (const auto& g : p.segments) {
      if (at < s + g.duration_s) return g.rpm;
      s += g.duration_s;
    }
    return 0.0;
  };
  p.moments.erase(std::remove_if(p.moments.begin(), p.moments.end(),
                                 [&](const ProfileMoment& m) { return m.t_s >= total || rpm_at(m.t_s) <= 0; }),
                  p.moments.end());
  for (auto& m : p.moments) m.rpm = rpm_at(m.t_s);
  std::sort(p.moments.begin(), p.moments.end(), [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
  return p;
}

std::vector<ProfileMoment> pick_moments(const ProductionProfile& p, const std::vector<MomentKind>& kinds, int per_kind) {
  std::vector<ProfileMoment> out;
  for (MomentKind k : kinds) {
    std::vector<ProfileMoment> all;
    for (const auto& m : p.moments)
      if (m.kind == k) all.push_back(m);
    const int n = std::min<int>(per_kind, int(all.size()));
    for (int i = 0; i < n; ++i) {
      const size_t idx = n == 1 ? 0 : size_t(std::lround(double(i) * double(all.size() - 1) / double(n - 1)));
      out.push_back(all[idx]);
    }
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
  return out;
}

}  // namespace btsm::bench
