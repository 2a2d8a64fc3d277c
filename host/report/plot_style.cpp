#include "host/report/plot_style.hpp"

#include <algorithm>
#include <set>

namespace btsm::report {
namespace {

// Colour-blind-safe palette (Okabe–Ito without black and yellow, then four darker tones) for
// keys; black and grey stay for markers and the speed.
constexpr Rgb kPalette[] = {{0.00, 0.45, 0.70}, {0.84, 0.37, 0.00}, {0.00, 0.62, 0.45}, {0.80, 0.47, 0.65},
                            {0.34, 0.71, 0.91}, {0.90, 0.62, 0.00}, {0.42, 0.24, 0.60}, {0.55, 0.34, 0.16},
                            {0.47, 0.53, 0.13}, {0.10, 0.40, 0.45}};
constexpr int kPaletteSize = sizeof kPalette / sizeof kPalette[0];

// The module's channel roles (common/wire_messages.hpp) keep one colour in every figure, so a
// spindle's rear bearing looks the same in the validation, the residual report and production.
struct FixedColour {
  const char* key;
  int palette_index;
};
constexpr FixedColour kRoleColours[] = {{"front_bearing", 0}, {"rear_bearing", 1}, {"housing", 2}, {"shaft", 3},
                                        {"ambient", 4},       {"motor", 5},        {"coolant", 6}, {"spare", 7}};
constexpr Rgb kSpeedColour{0.35, 0.35, 0.35};

const std::string& key_of(const Series& s) { return s.key.empty() ? s.label : s.key; }

}  // namespace

bool fixed_colour(const std::string& key, Rgb& out) {
  if (key == "speed") {
    out = kSpeedColour;
    return true;
  }
  for (const auto& f : kRoleColours)
    if (key == f.key) {
      out = kPalette[f.palette_index];
      return true;
    }
  return false;
}

std::map<std::string, Rgb> assign_colours(const std::vector<Plot>& panels, const std::vector<std::string>& key_order) {
  std::vector<std::string> keys;  // key_order first, then the figure's keys as they appear
  std::set<std::string> seen;
  auto add = [&](const std::string& k) {
    if (seen.insert(k).second) keys.push_back(k);
  };
  for (const auto& k : key_order) add(k);
  for (const auto& p : panels)
    for (const auto& s : p.series) add(key_of(s));
  std::map<std::string, Rgb> out;
  std::set<int> used;
  for (const auto& k : keys) {
    Rgb c;
    if (!fixed_colour(k, c)) continue;
    out[k] = c;
    for (int i = 0; i < kPaletteSize; ++i)
      if (kPalette[i] == c) used.insert(i);
  }
  int next = 0, wrapped = 0;
  for (const auto& k : keys) {
    if (out.count(k)) continue;
    // Free colours first; once all are taken, reuse them in order (more keys than colours).
    while (next < kPaletteSize && used.count(next)) ++next;
    if (next >= kPaletteSize) {
      out[k] = kPalette[wrapped++ % kPaletteSize];
      continue;
    }
    used.insert(next);
    out[k] = kPalette[next];
  }
  return out;
}

Rgb measured_tint(Rgb c) {
  const double keep = 0.45;  // 45 % colour, 55 % white
  return {keep * c.r + (1 - keep), keep * c.g + (1 - keep), keep * c.b + (1 - keep)};
}

std::string display_name(const std::string& key) {
  std::string s = key;
  std::replace(s.begin(), s.end(), '_', ' ');
  return s;
}

std::vector<double> hours(const std::vector<double>& time_s) {
  std::vector<double> h(time_s.size());
  for (size_t i = 0; i < time_s.size(); ++i) h[i] = time_s[i] / 3600.0;
  return h;
}

Series measured(const std::string& node, std::vector<double> x, std::vector<double> y, std::string label) {
  return Series{std::move(label), std::move(x), std::move(y), Series::Style::Points, node};
}

Series model(const std::string& node, std::vector<double> x, std::vector<double> y, std::string label) {
  return Series{std::move(label), std::move(x), std::move(y), Series::Style::Line, node};
}

Series alternative(const std::string& node, std::vector<double> x, std::vector<double> y, std::string label) {
  return Series{std::move(label), std::move(x), std::move(y), Series::Style::Dashed, node};
}

Series trace(const std::string& node, std::vector<double> x, std::vector<double> y, Series::Style style) {
  return Series{"", std::move(x), std::move(y), style, node};
}

Plot speed_panel(const std::vector<double>& t_h, const std::vector<double>& rpm, std::string title) {
  Plot p{std::move(title), kTimeAxis, kSpeedAxis, {}};
  p.series.push_back(Series{"", t_h, rpm, Series::Style::Step, "speed"});
  p.height_weight = 0.6;
  return p;
}

}  // namespace btsm::report
