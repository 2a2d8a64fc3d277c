#include "host/report/plot_layout.hpp"

#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <set>

namespace btsm::report {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kRightMargin = 30;      // room for the last x tick label
constexpr double kSwatch = 26, kSwatchGap = 5, kEntryGap = 18, kLegendRow = 19;

bool usable(double v, bool log) { return std::isfinite(v) && (!log || v > 0); }

// Text widths as cairo draws them, with unhinted metrics so PNG and SVG lay out alike.
class TextMeasure {
 public:
  TextMeasure() : surface_(cairo_image_surface_create(CAIRO_FORMAT_RGB24, 1, 1)), cr_(cairo_create(surface_)) {
    cairo_select_font_face(cr_, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    cairo_font_options_t* fo = cairo_font_options_create();
    cairo_font_options_set_hint_metrics(fo, CAIRO_HINT_METRICS_OFF);
    cairo_set_font_options(cr_, fo);
    cairo_font_options_destroy(fo);
  }
  ~TextMeasure() {
    cairo_destroy(cr_);
    cairo_surface_destroy(surface_);
  }
  TextMeasure(const TextMeasure&) = delete;
  TextMeasure& operator=(const TextMeasure&) = delete;

  double width(const std::string& s, double size) {
    cairo_set_font_size(cr_, size);
    cairo_text_extents_t e;
    cairo_text_extents(cr_, s.c_str(), &e);
    return e.x_advance;
  }
  // The longest prefix (whole UTF-8 characters) that fits with an ellipsis, or s if it fits.
  std::string fit(const std::string& s, double size, double max_w) {
    if (width(s, size) <= max_w) return s;
    std::string cut = s;
    while (!cut.empty()) {
      do cut.pop_back();
      while (!cut.empty() && (static_cast<unsigned char>(cut.back()) & 0xC0) == 0x80);
      if (!cut.empty()) cut.pop_back();  // the lead byte of the character just emptied
      const std::string t = cut + "…";
      if (width(t, size) <= max_w) return t;
    }
    return "…";
  }

 private:
  cairo_surface_t* surface_;
  cairo_t* cr_;
};

const std::string& key_of(const Series& s) { return s.key.empty() ? s.label : s.key; }

bool integer_x(const Plot& p) {
  bool any = false;
  for (const auto& s : p.series)
    for (double x : s.x) {
      if (!std::isfinite(x)) continue;
      if (x != std::round(x)) return false;
      any = true;
    }
  return any;
}

void drop_fractional_ticks(AxisTicks& t) {
  AxisTicks kept = t;
  kept.values.clear(), kept.labels.clear();
  for (size_t i = 0; i < t.values.size(); ++i)
    if (std::fabs(t.values[i] - std::round(t.values[i])) < 1e-9) {
      kept.values.push_back(t.values[i]);
      kept.labels.push_back(std::to_string(std::lround(t.values[i])));  // "2", not "2.0"
    }
  t = kept;
}

struct Range {
  double lo = kInf, hi = -kInf;
  void add(double v) { lo = std::min(lo, v), hi = std::max(hi, v); }
};

// The legend entries of one panel: one per node (colour), then one per kind of curve when a
// panel shows several kinds (measured / model / ...), drawn in grey; a lone entry is left out
// (the title says it).
std::vector<LegendEntry> legend_entries(const Plot& p, const std::map<std::string, Rgb>& colours) {
  std::vector<LegendEntry> out;
  std::set<std::string> keys_done, kinds_done;
  std::vector<const Series*> kinds;
  bool several_kinds = false;
  for (const auto& s : p.series) {
    if (s.key.empty()) continue;
    if (kinds_done.insert(s.label).second) kinds.push_back(&s);
  }
  several_kinds = kinds.size() > 1;
  for (const auto& s : p.series) {
    const std::string& k = key_of(s);
    if (k.empty() || !keys_done.insert(k).second) continue;
    LegendEntry e;
    e.text = s.key.empty() ? s.label : display_name(s.key);
    e.colour = colours.at(k);
    e.style = s.key.empty() || !several_kinds ? s.style : Series::Style::Line;
    out.push_back(e);
  }
  if (several_kinds)
    for (const Series* s : kinds) {
      if (s->label.empty()) continue;
      LegendEntry e;
      e.text = s->label;
      e.colour = Rgb{0.30, 0.30, 0.30};
      e.style = s->style;
      out.push_back(e);
    }
  // A lone entry says nothing the title does not, unless it names the node a panel is about.
  if (out.size() == 1) {
    const bool node_entry = std::any_of(p.series.begin(), p.series.end(),
                                        [](const Series& s) { return !s.key.empty() && s.key != "speed"; });
    if (!node_entry) out.clear();
  }
  return out;
}

}  // namespace

std::string unit_style(std::string label, bool axis) {
  for (size_t at; (at = label.find("degC")) != std::string::npos;) label.replace(at, 4, "°C");
  if (axis) {
    std::replace(label.begin(), label.end(), '[', '(');
    std::replace(label.begin(), label.end(), ']', ')');
  }
  return label;
}

bool Rect::contains(const Rect& r) const {
  const double eps = 1e-9;
  return r.x >= x - eps && r.y >= y - eps && r.x + r.w <= x + w + eps && r.y + r.h <= y + h + eps;
}

bool Rect::overlaps(const Rect& r) const {
  return r.x < x + w && x < r.x + r.w && r.y < y + h && y < r.y + r.h;
}

double FigureLayout::px(const Plot& p, const PanelLayout& l, double x) const {
  const auto& t = l.x_ticks;
  const double f = p.log_x ? (std::log10(x) - std::log10(t.lo)) / (std::log10(t.hi) - std::log10(t.lo))
                           : (x - t.lo) / (t.hi - t.lo);
  return l.plot.x + f * l.plot.w;
}

double FigureLayout::py(const Plot& p, const PanelLayout& l, double y) const {
  const auto& t = l.y_ticks;
  const double f = p.log_y ? (std::log10(y) - std::log10(t.lo)) / (std::log10(t.hi) - std::log10(t.lo))
                           : (y - t.lo) / (t.hi - t.lo);
  // The y range sits kYInset px inside the frame, so a curve at the range's end (a speed of 0,
  // a state at its maximum) is not hidden by the frame line.
  return l.plot.y + kYInset + (l.plot.h - 2 * kYInset) * (1 - f);
}

FigureLayout layout_figure(const std::vector<Plot>& panels, const FigureOptions& o) {
  FigureLayout L;
  L.width = o.width;
  L.colours = assign_colours(panels, o.key_order);
  TextMeasure tm;

  // Data ranges; panels with the same x label share one x range, so stacked time axes line up.
  std::vector<Range> xr(panels.size()), yr(panels.size());
  std::map<std::string, Range> x_group;
  auto group_of = [&](size_t i) { return panels[i].x_label.empty() ? "#" + std::to_string(i) : panels[i].x_label; };
  for (size_t i = 0; i < panels.size(); ++i) {
    const Plot& p = panels[i];
    for (const auto& s : p.series)
      for (size_t k = 0; k < std::min(s.x.size(), s.y.size()); ++k)
        if (usable(s.x[k], p.log_x) && usable(s.y[k], p.log_y)) xr[i].add(s.x[k]), yr[i].add(s.y[k]);
    for (const auto& m : p.markers)
      if (usable(m.x, p.log_x)) xr[i].add(m.x);
    Range& g = x_group[group_of(i)];
    g.add(xr[i].lo), g.add(xr[i].hi);
  }

  L.panels.resize(panels.size());
  double left = 0;
  for (size_t i = 0; i < panels.size(); ++i) {
    const Plot& p = panels[i];
    PanelLayout& l = L.panels[i];
    const Range g = x_group[group_of(i)];
    l.x_ticks = p.log_x ? log_ticks(g.lo, g.hi) : linear_ticks_within(g.lo, g.hi, 8);
    if (!p.log_x && integer_x(p)) drop_fractional_ticks(l.x_ticks);  // an index axis has no tick 1.5
    // About one y tick per 45 px of the plot box (its height before the legend is known).
    const double plot_h = o.panel_height * std::max(0.1, p.height_weight) - 100;
    const int y_count = std::clamp(static_cast<int>(plot_h / 45), 2, 6);
    l.y_ticks = p.log_y ? log_ticks(yr[i].lo, yr[i].hi, y_count + 1) : linear_ticks(yr[i].lo, yr[i].hi, y_count);
    for (const auto& lab : l.y_ticks.labels) left = std::max(left, tm.width(lab, kTickFont));
  }
  left += 8 + 10 + kAxisLabelFont + 10;  // tick gap, tick labels, axis label, margin
  const double right = kRightMargin;

  double y0 = 0;
  for (size_t i = 0; i < panels.size(); ++i) {
    const Plot& p = panels[i];
    PanelLayout& l = L.panels[i];
    double h = std::max(140.0, std::round(o.panel_height * std::max(0.1, p.height_weight)));
    l.title = tm.fit(unit_style(p.title, false), kTitleFont, o.width - 20.0);
    l.x_label = tm.fit(unit_style(p.x_label), kAxisLabelFont, o.width - 20.0);
    l.title_y = y0 + 8 + kTitleFont;

    // Legend strip: entries flow left to right under the title and wrap at the canvas width.
    double lx = left, ly = y0 + 8 + kTitleFont + 10;
    const double max_x = o.width - right;
    for (LegendEntry e : legend_entries(p, L.colours)) {
      const double room = max_x - left - kSwatch - kSwatchGap;
      e.text = tm.fit(e.text, kLegendFont, room);
      const double w = kSwatch + kSwatchGap + tm.width(e.text, kLegendFont);
      if (lx > left && lx + w > max_x) lx = left, ly += kLegendRow;
      e.box = Rect{lx, ly, w, kLegendRow - 3};
      l.legend.push_back(e);
      lx += w + kEntryGap;
    }
    const double top = l.legend.empty() ? y0 + 8 + kTitleFont + 10 : ly + kLegendRow + 4;
    const double bottom_margin = 10 + kTickFont + 10 + kAxisLabelFont + 8;  // tick labels and x label
    h = std::max(h, top - y0 + 60 + bottom_margin);  // a long legend makes the panel taller, never the plot tiny
    l.area = Rect{0, y0, static_cast<double>(o.width), h};
    l.plot = Rect{left, top, o.width - left - right, y0 + h - bottom_margin - top};
    l.y_label = tm.fit(unit_style(p.y_label), kAxisLabelFont, l.plot.h);  // it runs along the plot's height
    for (const auto& m : p.markers)
      l.marker_px.push_back(usable(m.x, p.log_x) ? L.px(p, l, m.x) : NAN);
    y0 += h;
  }
  L.height = static_cast<int>(std::ceil(y0));
  return L;
}

}  // namespace btsm::report
