#include "host/sim/plant/profile.hpp"

#include "host/io/input_file.hpp"
#include "host/io/decimal_number.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace btsm::sim {
namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

// Strict number parse: the whole text must be a finite number.
double parse_number(const std::string& text, const std::string& what) {
  const std::string t = trim(text);
  if (t.empty()) throw std::invalid_argument(what + ": empty number");
  const auto v = io::decimal_number(t);
  if (!v) throw std::invalid_argument(what + ": '" + t + "' is not a number");
  return *v;
}

// Splits on commas and white space. White space around '@' belongs to the segment ("1m @ 6000" is
// 1m@6000, not three items). A comma with nothing before or after it is an empty item, refused
// as in every number list ("1m@6000,,1m@0" is a typo, not two segments); a line of a profile file
// may end in a comma (the list goes on on the next line).
std::vector<std::string> split_items(const std::string& text, const std::string& what, bool trailing_comma_ok = false) {
  std::string s;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    const bool blank = c == ' ' || c == '\t';
    if (blank && !s.empty() && s.back() == '@') continue;  // after '@'
    if (blank) {
      const auto next = text.find_first_not_of(" \t", i);
      if (next != std::string::npos && text[next] == '@') continue;  // before '@'
    }
    s += c;
  }
  std::vector<std::string> out;
  std::string cur;
  bool comma_open = true;  // a comma needs an item before it: the start counts as one
  const auto empty_item = [&] {
    throw std::invalid_argument(what + " '" + text + "': an empty item (a doubled, leading or trailing comma)");
  };
  for (char c : s) {
    if (c == ',' || c == ' ' || c == '\t' || c == '\n' || c == '\r') {
      if (!cur.empty()) {
        out.push_back(cur);
        comma_open = false;
      }
      cur.clear();
      if (c == ',') {
        if (comma_open) empty_item();
        comma_open = true;
      }
    } else {
      cur += c;
    }
  }
  if (!cur.empty()) {
    out.push_back(cur);
    comma_open = false;
  }
  if (comma_open && !out.empty() && !trailing_comma_ok) empty_item();
  return out;
}

SpeedSegment parse_segment(const std::string& item, const std::string& where) {
  const auto at = item.find('@');
  if (at == std::string::npos)
    throw std::invalid_argument(where + ": '" + item + "' must be DURATION@RPM, e.g. 2h@6000");
  SpeedSegment seg;
  seg.duration_s = parse_duration_s(item.substr(0, at), where + " duration");
  std::string rpm = item.substr(at + 1);
  if (rpm.size() > 3 && rpm.compare(rpm.size() - 3, 3, "rpm") == 0) rpm.resize(rpm.size() - 3);
  seg.rpm = parse_number(rpm, where + " speed");
  if (seg.duration_s <= 0.0) throw std::invalid_argument(where + ": duration must be > 0");
  // "1e-9s@6000" ran for 0 s and said so with exit 0: nothing steps or samples that briefly
  if (seg.duration_s < kMinSegmentS)
    throw std::invalid_argument(where + ": '" + item + "' lasts less than " + std::to_string(static_cast<int>(kMinSegmentS * 1000)) +
                                " ms, shorter than anything the plant steps or the module samples");
  if (seg.rpm < 0.0 || seg.rpm > 65534.0)
    throw std::invalid_argument(where + ": speed must be within 0..65534 rpm");
  return seg;
}

}  // namespace

double parse_duration_s(const std::string& text, const std::string& what) {
  std::string t = trim(text);
  double scale = 1.0;
  auto ends_with = [&](const char* suf) {
    const std::string s(suf);
    return t.size() > s.size() && t.compare(t.size() - s.size(), s.size(), s) == 0;
  };
  if (ends_with("min")) {
    scale = 60.0;
    t.resize(t.size() - 3);
  } else if (ends_with("ms")) {
    scale = 1e-3;
    t.resize(t.size() - 2);
  } else if (ends_with("h")) {
    scale = 3600.0;
    t.resize(t.size() - 1);
  } else if (ends_with("m")) {
    scale = 60.0;
    t.resize(t.size() - 1);
  } else if (ends_with("s")) {
    t.resize(t.size() - 1);
  }
  double v = 0;
  try {
    v = parse_number(t, what) * scale;
  } catch (const std::invalid_argument&) {  // quoted as written: '1mm' was reported as '1m'
    throw std::invalid_argument(what + ": '" + text + "' is not a duration (a number, optionally with s, ms, m, min or h)");
  }
  if (v < 0.0) throw std::invalid_argument(what + ": '" + text + "' is negative");
  if (!(v <= kMaxDurationS))
    throw std::invalid_argument(what + ": '" + text + "' is longer than the " + std::to_string(static_cast<long long>(kMaxDurationS)) +
                                " s (31 years) a simulated run or a recording may last");
  return v;
}

SpeedProfile::SpeedProfile(std::vector<SpeedSegment> segments) {
  for (const auto& s : segments) append(s);
}

SpeedProfile SpeedProfile::parse(const std::string& spec) {
  const auto items = split_items(spec, "speed profile");
  if (items.empty()) throw std::invalid_argument("speed profile: empty (expected e.g. 6h@6000,4h@0)");
  SpeedProfile p;
  for (size_t i = 0; i < items.size(); ++i)
    p.segments_.push_back(parse_segment(items[i], "speed profile item " + std::to_string(i + 1)));
  return p;
}

SpeedProfile SpeedProfile::load_file(const std::string& path) {
  // Through the capped reader like every input: /dev/zero (or any file without line ends) made
  // getline grow one line without bound, and sim-module never started.
  std::istringstream in(io::read_input_file(path, kMaxProfileFileBytes, "speed profile file"));
  SpeedProfile p;
  std::string line;
  int lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    if (lineno == 1 && line.compare(0, 3, "\xEF\xBB\xBF") == 0) line.erase(0, 3);  // a UTF-8 BOM, as recordings allow
    const auto items = split_items(line, path + ":" + std::to_string(lineno), true);
    for (size_t i = 0; i < items.size(); ++i)
      p.segments_.push_back(parse_segment(
          items[i], path + ":" + std::to_string(lineno) + " item " + std::to_string(i + 1)));
  }
  if (p.segments_.empty()) throw std::invalid_argument("speed profile file " + path + ": no segments");
  return p;
}

void SpeedProfile::append(const SpeedSegment& seg) {
  if (!(seg.duration_s > 0.0) || !(seg.rpm >= 0.0) || !std::isfinite(seg.duration_s) ||
      !std::isfinite(seg.rpm))
    throw std::invalid_argument("speed segment: duration must be > 0 s and speed >= 0 rpm");
  if (seg.duration_s > kMaxDurationS)
    throw std::invalid_argument("speed segment: longer than the " + std::to_string(static_cast<long long>(kMaxDurationS)) +
                                " s (31 years) a simulated run may last");
  segments_.push_back(seg);
}

void SpeedProfile::replace_from(double t_s, const std::vector<SpeedSegment>& segs) {
  std::vector<SpeedSegment> kept;
  double t0 = 0.0;
  for (const auto& s : segments_) {
    if (t0 >= t_s) break;
    SpeedSegment k = s;
    if (t0 + s.duration_s > t_s) k.duration_s = t_s - t0;
    if (k.duration_s > 0.0) kept.push_back(k);
    t0 += s.duration_s;
  }
  // If the old profile ended before t, its last speed held until t: make that explicit.
  if (t0 < t_s && t_s > 0.0) kept.push_back({t_s - t0, segments_.empty() ? 0.0 : segments_.back().rpm});
  segments_ = kept;
  for (const auto& s : segs) append(s);
}

double SpeedProfile::rpm_at(double t_s) const {
  if (segments_.empty()) return 0.0;
  double t0 = 0.0;
  for (const auto& s : segments_) {
    if (t_s < t0 + s.duration_s) return s.rpm;
    t0 += s.duration_s;
  }
  return segments_.back().rpm;
}

double SpeedProfile::next_change_after(double t_s) const {
  double t0 = 0.0;
  for (const auto& s : segments_) {
    t0 += s.duration_s;
    if (t0 > t_s) return t0;
  }
  return std::numeric_limits<double>::infinity();
}

double SpeedProfile::total_duration_s() const {
  double t = 0.0;
  for (const auto& s : segments_) t += s.duration_s;
  return t;
}

std::string SpeedProfile::to_string() const {
  std::ostringstream os;
  for (size_t i = 0; i < segments_.size(); ++i) {
    if (i) os << ',';
    os << segments_[i].duration_s << "s@" << segments_[i].rpm;
  }
  return os.str();
}

AmbientProfile AmbientProfile::parse(const std::string& spec) {
  const auto items = split_items(spec, "ambient");
  if (items.empty()) throw std::invalid_argument("ambient: empty (expected e.g. 20 or 20,2h@22)");
  AmbientProfile a;
  a.start_c_ = parse_number(items[0], "ambient start value");
  for (size_t i = 1; i < items.size(); ++i) {
    const std::string where = "ambient item " + std::to_string(i + 1);
    const auto at = items[i].find('@');
    if (at == std::string::npos)
      throw std::invalid_argument(where + ": '" + items[i] + "' must be DURATION@DEGC");
    Ramp r{parse_duration_s(items[i].substr(0, at), where + " duration"),
           parse_number(items[i].substr(at + 1), where + " temperature")};
    if (r.duration_s <= 0.0) throw std::invalid_argument(where + ": duration must be > 0");
    a.ramps_.push_back(r);
  }
  if (a.start_c_ < -40.0 || a.start_c_ > 85.0) throw std::invalid_argument("ambient: start value outside -40..85 degC");
  for (std::size_t i = 0; i < a.ramps_.size(); ++i)  // a 500 degC room ran with exit 0
    if (a.ramps_[i].target_c < -40.0 || a.ramps_[i].target_c > 85.0)
      throw std::invalid_argument("ambient item " + std::to_string(i + 2) + ": target outside -40..85 degC");
  return a;
}

double AmbientProfile::celsius_at(double t_s) const {
  double t0 = 0.0, v0 = start_c_;
  for (const auto& r : ramps_) {
    if (t_s < t0 + r.duration_s) return v0 + (r.target_c - v0) * (t_s - t0) / r.duration_s;
    t0 += r.duration_s;
    v0 = r.target_c;
  }
  return v0;
}

}  // namespace btsm::sim
