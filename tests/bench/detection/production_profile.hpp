#pragma once
// A varied production profile for the detection benchmark, and the moments of it where faults are
// injected. Drawn from a seed (std::mt19937, fully specified, so the same seed gives the same
// profile everywhere):
//   - days of `shift_h` hours of running followed by a night stop (the machine cools down; the
//     next day starts cold again) until `hours` are covered;
//   - running segments of `min_segment_min`..`max_segment_min` minutes, each a speed step of
//     +-`rpm_step` from the one before within `rpm_min`..`rpm_max` (direction drawn, turned
//     round at the limits);
//   - a stop of `stop_min` minutes every `stop_every_min_h`..`stop_every_max_h` hours of running,
//     after which the spindle restarts at a speed drawn from the whole range (multiples of the step).
// Moments (s from the start of the profile), by what just happened:
//   cold start   15 min after a start from cold (t = 0 and every morning)
//   restart      10 min after the end of a short stop
//   step up      5 min after a +step speed change
//   step down    5 min after a -step speed change
//   steady       45 min into a segment of at least an hour at one speed
#include "host/sim/plant/profile.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace btsm::bench {

enum class MomentKind { ColdStart, Restart, StepUp, StepDown, Steady };
const char* moment_kind_name(MomentKind k);

struct ProfileMoment {
  MomentKind kind = MomentKind::ColdStart;
  double t_s = 0;    // s from the start of the profile
  double rpm = 0;    // rpm in force at the moment
};

struct ProductionProfileOptions {
  uint32_t seed = 1;
  double hours = 48;             // h, total length (running, stops and night stops)
  double shift_h = 16;           // h of running (with short stops) per day
  double min_segment_min = 20;   // min, shortest running segment
  double max_segment_min = 90;   // min, longest running segment
  double stop_every_min_h = 3;   // h of running between short stops, at least
  double stop_every_max_h = 5;   // h, at most
  double stop_min = 30;          // min, length of a short stop
  double rpm_min = 4000;         // rpm
  double rpm_max = 8000;         // rpm
  double rpm_step = 500;         // rpm, every speed change
};

struct ProductionProfile {
  std::vector<sim::SpeedSegment> segments;
  std::vector<ProfileMoment> moments;  // every candidate, in time order
  double duration_s() const;
  // Counts of what the profile contains (steps up/down, short stops, cold starts, speed range).
  std::string describe() const;
};

ProductionProfile make_production_profile(const ProductionProfileOptions& o);

// Up to `per_kind` moments of each kind in `kinds`, spread over the profile (the first and last
// occurrence, then evenly between), in time order.
std::vector<ProfileMoment> pick_moments(const ProductionProfile& p, const std::vector<MomentKind>& kinds, int per_kind);

}  // namespace btsm::bench
