#pragma once
// Speed and ambient profiles of the simulated spindle.
//
// Speed: piecewise-constant segments "duration@rpm", e.g. "6h@6000,4h@0,2h@3000" (6 h at
// 6000 rpm, then 4 h stopped, then 2 h at 3000 rpm). After the last segment the last speed holds.
// Durations take a unit suffix: s (default), m or min, h. Segments may also come from a file: one or
// more segments per line separated by commas or white space, '#' starts a comment.
//
// Ambient: a constant ("20") or a start value followed by ramps "20,2h@22,4h@22,2h@20": start at
// 20 degC, ramp linearly to 22 degC over 2 h, hold 4 h, ramp back to 20 degC over 2 h; after the
// end the last value holds.
//
// Parse errors throw std::invalid_argument naming the offending item and its position.
#include <cstddef>
#include <string>
#include <vector>

namespace btsm::sim {

struct SpeedSegment {
  double duration_s = 0.0;  // s, > 0
  double rpm = 0.0;         // rpm, >= 0
};

// Longest duration accepted, the time a recording may hold (thermal/recording.hpp kMaxRecordedTimeS):
// beyond it the run never ends and its time stamps lose their seconds.
inline constexpr double kMaxDurationS = 1.0e9;
// The shortest speed segment: below a plant step (0.25 s) and the module's sample period a segment
// changes nothing but the run's length.
inline constexpr double kMinSegmentS = 0.1;
// Parses "90", "90s", "15m", "15min", "1.5h" into seconds (at most kMaxDurationS). `what` names
// the item in errors.
double parse_duration_s(const std::string& text, const std::string& what);

// A speed profile file holds a few hundred segments at most; 1 MiB is far beyond any real one.
inline constexpr std::size_t kMaxProfileFileBytes = std::size_t{1} << 20;

class SpeedProfile {
 public:
  SpeedProfile() = default;
  explicit SpeedProfile(std::vector<SpeedSegment> segments);

  static SpeedProfile parse(const std::string& spec);       // "6h@6000,4h@0"
  // Same syntax, several lines ('#' starts a comment); at most kMaxProfileFileBytes.
  static SpeedProfile load_file(const std::string& path);

  void append(const SpeedSegment& seg);                      // queue a segment at the end
  // Replaces everything from time t on with `segs` (the part before t is kept, cut at t).
  void replace_from(double t_s, const std::vector<SpeedSegment>& segs);

  double rpm_at(double t_s) const;           // speed in force at t (right-continuous)
  double next_change_after(double t_s) const;  // next segment boundary > t, or +inf
  double total_duration_s() const;
  const std::vector<SpeedSegment>& segments() const { return segments_; }
  std::string to_string() const;

 private:
  std::vector<SpeedSegment> segments_;
};

class AmbientProfile {
 public:
  AmbientProfile() = default;
  explicit AmbientProfile(double constant_c) : start_c_(constant_c) {}
  static AmbientProfile parse(const std::string& spec);

  double celsius_at(double t_s) const;
  double start_c() const { return start_c_; }

 private:
  struct Ramp {
    double duration_s;
    double target_c;
  };
  double start_c_ = 20.0;
  std::vector<Ramp> ramps_;
};

}  // namespace btsm::sim
