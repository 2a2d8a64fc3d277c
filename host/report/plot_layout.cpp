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
  // Found by bisection over the character boundaries: popping one character at a time measured
  // the whole rest each time, and a 200 kB metadata line took minutes (probe 5).
  // `cut_before`: s is already the head of a longer text, so it ends in an ellipsis in any case.
  std::string fit(const std::string& s_in, double size, double max_w, bool cut_before = false) {
    const std::string s = capped(s_in);
    if (!cut_before && s.size() == s_in.size() && width(s, size) <= max_w) return s;
    std::vector<size_t> ends;  // byte length of each prefix of whole characters
    for (size_t i = 1; i <= s.size(); ++i)
      if (i == s.size() || (static_cast<unsigned char>(s[i]) & 0xC0) != 0x80) ends.push_back(i);
    size_t lo = 0, hi = ends.size();  // prefixes ends[0..lo) fit; find the longest
    while (lo < hi) {
      const size_t mid = (lo + hi + 1) / 2;
      if (width(s.substr(0, ends[mid - 1]) + "…", size) <= max_w) lo = mid;
      else hi = mid - 1;
    }
    return lo == 0 ? std::string("…") : s.substr(0, ends[lo - 1]) + "…";
  }
  // No figure shows more than a few hundred characters on a line: longer text is cut (at a
  // character boundary) before it is measured, so the cost does not grow with the input.
  static std::string capped(const std::string& s) {
    constexpr size_t kMaxBytes = 2048;
    if (s.size() <= kMaxBytes) return s;
    size_t end = kMaxBytes;
    while (end > 0 && (static_cast<unsigned char>(s[end]) & 0xC0) == 0x80) --end;
    return s.substr(0, end);
  }
  // Words greedily onto lines of at most max_w, at most max_lines; a word wider than a line is
  // cut; the last line gets an ellipsis when text is left over.
  std::vector<std::string> wrap(const std::string& s, double size, double max_w, int max_lines) {
    std::vector<std::string> lines;
    std::string rest = capped(s);
    const bool was_cut = rest.size() < s.size();
    while (!rest.empty() && static_cast<int>(lines.size()) < max_lines - 1 && width(rest, size) > max_w) {
      size_t cut = std::string::npos;
      for (size_t sp = rest.find(' '); sp != std::string::npos; sp = rest.find(' ', sp + 1)) {
        if (width(rest.substr(0, sp), size) > max_w) break;
        cut = sp;
      }
      if (cut == std::string::npos || cut == 0) break;  // no space to break at: ellipsis below
      lines.push_back(rest.substr(0, cut));
      rest = rest.substr(rest.find_first_not_of(' ', cut) == std::string::npos ? rest.size() : rest.find_first_not_of(' ', cut));
    }
    if (!rest.empty() || lines.empty()) lines.push_back(fit(rest, size, max_w, was_cut));
    return lines;
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

// Span colours by label, in order of first appearance over the figure: light fills that differ
// from each other and from the node colours' lines drawn on top.
std::map<std::string, Rgb> assign_span_colours(const std::vector<Plot>& panels) {
  static const Rgb kSpanPalette[] = {{0.45, 0.50, 0.85}, {0.95, 0.65, 0.15}, {0.40, 0.75, 0.45}, {0.80, 0.40, 0.75}};
  std::map<std::string, Rgb> out;
  for (const auto& p : panels)
    for (const auto& s : p.spans)
      if (!out.count(s.label)) {
        const size_t n = out.size();
        out[s.label] = kSpanPalette[n % (sizeof kSpanPalette / sizeof kSpanPalette[0])];
      }
  return out;
}

// The legend entries of one panel: one per node (colour), then one per kind of curve when a
// panel shows several kinds (measured / model / ...), drawn in grey; a lone entry is left out
// (the title says it). Then one per span label: what the shading means is never left to guess.
std::vector<LegendEntry> legend_entries(const Plot& p, const std::map<std::string, Rgb>& colours,
                                        const std::map<std::string, Rgb>& span_colours) {
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
  std::set<std::string> spans_done;
  for (const auto& sp : p.spans) {
    if (sp.label.empty() || !spans_done.insert(sp.label).second) continue;
    LegendEntry e;
    e.text = sp.label;
    e.colour = span_colours.at(sp.label);
    e.shaded = true;
    out.push_back(e);
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

namespace {

// Does segment a-b touch box r (Liang-Barsky clipping)?
bool segment_touches(double ax, double ay, double bx, double by, const Rect& r) {
  double t0 = 0, t1 = 1;
  const double dx = bx - ax, dy = by - ay;
  const double pq[4][2] = {{-dx, ax - r.x}, {dx, r.x + r.w - ax}, {-dy, ay - r.y}, {dy, r.y + r.h - ay}};
  for (const auto& e : pq) {
    if (e[0] == 0) {
      if (e[1] < 0) return false;
      continue;
    }
    const double t = e[1] / e[0];
    if (e[0] < 0) t0 = std::max(t0, t);
    else t1 = std::min(t1, t);
    if (t0 > t1) return false;
  }
  return true;
}

// The label box of a marker at pixel x: the first candidate place that covers no data and no
// earlier label, else the one covering the least.
Rect place_marker_label(const Plot& p, const PanelLayout& l, const FigureLayout& L, double x, double text_w,
                        const std::vector<Rect>& taken) {
  const double w = text_w + 4, h = kMarkerFont + 4, pad = 4;
  const Rect& b = l.plot;
  std::vector<double> ys;
  for (int k = 0; k < 3; ++k) ys.push_back(b.y + pad + 14 * k);
  for (int k = 0; k < 3; ++k) ys.push_back(b.y + b.h - pad - h - 14 * k);
  ys.push_back(b.y + (b.h - h) / 2);
  Rect best;
  int best_cover = std::numeric_limits<int>::max();
  for (double y : ys)
    for (double tx : {x + 4 - 2, x - 4 - text_w - 2}) {
      const Rect r{tx, y, w, h};
      if (!b.contains(r)) continue;
      int cover = data_touching(p, l, L, r);
      for (const Rect& t : taken) cover += t.overlaps(r) ? 1000 : 0;
      if (cover < best_cover) best = r, best_cover = cover;
      if (cover == 0) return best;
    }
  return best;
}

}  // namespace

int data_touching(const Plot& p, const PanelLayout& l, const FigureLayout& L, const Rect& r) {
  // The drawn width of lines and dots reaches a few px beyond the data points.
  const Rect g{r.x - 3, r.y - 3, r.w + 6, r.h + 6};
  int hits = 0;
  for (const auto& s : p.series) {
    const size_t n = std::min(s.x.size(), s.y.size());
    bool have_last = false;
    double lx = 0, ly = 0;
    for (size_t i = 0; i < n; ++i) {
      if (!usable(s.x[i], p.log_x) || !usable(s.y[i], p.log_y)) {
        have_last = false;
        continue;
      }
      const double X = L.px(p, l, s.x[i]), Y = L.py(p, l, s.y[i]);
      if (s.style == Series::Style::Points) hits += segment_touches(X, Y, X, Y, g) ? 1 : 0;
      else if (have_last && s.style == Series::Style::Step)
        hits += (segment_touches(lx, ly, X, ly, g) || segment_touches(X, ly, X, Y, g)) ? 1 : 0;
      else if (have_last) hits += segment_touches(lx, ly, X, Y, g) ? 1 : 0;
      else hits += segment_touches(X, Y, X, Y, g) ? 1 : 0;
      have_last = true, lx = X, ly = Y;
    }
  }
  return hits;
}

FigureLayout layout_figure(const std::vector<Plot>& panels, const FigureOptions& o) {
  FigureLayout L;
  L.width = o.width;
  L.colours = assign_colours(panels, o.key_order);
  const std::map<std::string, Rgb> span_colours = assign_span_colours(panels);
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
    Range g = x_group[group_of(i)];
    // Data that begin just after 0 (a recording's first sample 5 s in, a run watched from its
    // start) are read from 0: the axis starts there and 0 gets its tick.
    if (!p.log_x && g.lo > 0 && g.hi > g.lo && g.lo <= kZeroSnap * (g.hi - g.lo)) g.lo = 0;
    l.x_ticks = p.log_x ? log_ticks(g.lo, g.hi) : linear_ticks_within(g.lo, g.hi, 8);
    if (!p.log_x && integer_x(p)) drop_fractional_ticks(l.x_ticks);  // an index axis has no tick 1.5
    // About one y tick per 45 px of the plot box (its height before the legend is known).
    const double plot_h = o.panel_height * std::max(0.1, p.height_weight) - 100;
    const int y_count = std::clamp(static_cast<int>(plot_h / 45), 2, 6);
    l.y_ticks = p.log_y ? log_ticks(yr[i].lo, yr[i].hi, y_count + 1) : linear_ticks(yr[i].lo, yr[i].hi, y_count);
    // Few ticks round the range out far (speeds up to 6000 rpm on a 0-10000 axis: 40 % of a short
    // panel empty); up to two more ticks while that is so.
    for (int more = 1; !p.log_y && more <= 2 && yr[i].hi > yr[i].lo &&
                       l.y_ticks.hi - l.y_ticks.lo > kMaxYRangeOverData * (yr[i].hi - yr[i].lo);
         ++more)
      l.y_ticks = linear_ticks(yr[i].lo, yr[i].hi, y_count + more);
    for (const auto& lab : l.y_ticks.labels) left = std::max(left, tm.width(lab, kTickFont));
  }
  left += 8 + 10 + kAxisLabelFont + 10;  // tick gap, tick labels, axis label, margin
  const double right = kRightMargin;

  double y0 = 0;
  for (size_t i = 0; i < panels.size(); ++i) {
    const Plot& p = panels[i];
    PanelLayout& l = L.panels[i];
    double h = std::max(140.0, std::round(o.panel_height * std::max(0.1, p.height_weight)));
    l.title_lines = tm.wrap(unit_style(p.title, false), kTitleFont, o.width - 20.0, kMaxTitleLines);
    l.title.clear();
    for (size_t k = 0; k < l.title_lines.size(); ++k) {
      l.title += (k ? "\n" : "") + l.title_lines[k];
      const double w = tm.width(l.title_lines[k], kTitleFont);
      // centred; the box spans the ascent above the baseline and the descent below it
      l.title_boxes.push_back(Rect{(o.width - w) / 2, y0 + 8 + k * kTitleLine, w, kTitleFont * 1.2});
    }
    const double title_extra = kTitleLine * static_cast<double>(l.title_lines.size() - 1);
    l.x_label = tm.fit(unit_style(p.x_label), kAxisLabelFont, o.width - 20.0);
    l.title_y = y0 + 8 + kTitleFont;

    // Legend strip: entries flow left to right under the title and wrap at the canvas width.
    double lx = left, ly = y0 + 8 + kTitleFont + 10 + title_extra;
    const double max_x = o.width - right;
    for (LegendEntry e : legend_entries(p, L.colours, span_colours)) {
      const double room = max_x - left - kSwatch - kSwatchGap;
      e.text = tm.fit(e.text, kLegendFont, room);
      const double w = kSwatch + kSwatchGap + tm.width(e.text, kLegendFont);
      if (lx > left && lx + w > max_x) lx = left, ly += kLegendRow;
      e.box = Rect{lx, ly, w, kLegendRow - 3};
      l.legend.push_back(e);
      lx += w + kEntryGap;
    }
    const double top = l.legend.empty() ? y0 + 8 + kTitleFont + 10 + title_extra : ly + kLegendRow + 4;
    const double bottom_margin = 10 + kTickFont + 10 + kAxisLabelFont + 8;  // tick labels and x label
    h = std::max(h, top - y0 + 60 + bottom_margin);  // a long legend makes the panel taller, never the plot tiny
    l.area = Rect{0, y0, static_cast<double>(o.width), h};
    l.plot = Rect{left, top, o.width - left - right, y0 + h - bottom_margin - top};
    l.y_label = tm.fit(unit_style(p.y_label), kAxisLabelFont, l.plot.h);  // it runs along the plot's height
    for (const auto& sp : p.spans) {
      const double a = std::max(std::min(sp.x0, sp.x1), l.x_ticks.lo), b = std::min(std::max(sp.x0, sp.x1), l.x_ticks.hi);
      const bool shown = usable(a, p.log_x) && usable(b, p.log_x) && b > a;
      const double xa = shown ? L.px(p, l, a) : 0, xb = shown ? L.px(p, l, b) : 0;
      l.span_boxes.push_back(shown ? Rect{xa, l.plot.y, xb - xa, l.plot.h} : Rect{});
      l.span_colour.push_back(span_colours.at(sp.label));
    }
    for (const auto& m : p.markers) {
      const double x = usable(m.x, p.log_x) ? L.px(p, l, m.x) : NAN;
      l.marker_px.push_back(x);
      l.marker_label_box.push_back(std::isfinite(x) && !m.label.empty()
                                       ? place_marker_label(p, l, L, x, tm.width(m.label, kMarkerFont), l.marker_label_box)
                                       : Rect{});
    }
    y0 += h;
  }
  L.height = static_cast<int>(std::ceil(y0));
  return L;
}

}  // namespace btsm::report
