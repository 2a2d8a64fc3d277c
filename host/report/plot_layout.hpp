#pragma once
// Where every part of a figure lands (plot.hpp): computed once and used by the renderer, and by
// tests that check the legend stays inside the canvas, the x axis ends at the data, markers show.
#include "host/report/axis_ticks.hpp"
#include "host/report/plot.hpp"
#include "host/report/plot_style.hpp"

#include <map>
#include <string>
#include <vector>

namespace btsm::report {

struct Rect {
  double x = 0, y = 0, w = 0, h = 0;
  bool contains(const Rect& r) const;  // r lies within this rectangle (edges included)
  bool overlaps(const Rect& r) const;  // the interiors intersect
};

struct LegendEntry {
  Rect box;          // swatch and text
  std::string text;  // shortened with an ellipsis if it would not fit the canvas width
  Rgb colour;
  Series::Style style = Series::Style::Line;
  bool shaded = false;  // a span's entry: a filled swatch in the span's colour
};

struct PanelLayout {
  Rect area;              // the panel's share of the canvas
  Rect plot;              // the axes box
  std::string title;      // the title lines joined by '\n' (see title_lines)
  // A long title wraps at spaces onto up to kMaxTitleLines lines centred on the canvas; the last
  // is shortened with an ellipsis if the rest still would not fit. Each line's box lies inside
  // the canvas.
  std::vector<std::string> title_lines;
  std::vector<Rect> title_boxes;
  double title_y = 0;     // baseline of the first title line
  std::string y_label;    // in the common unit style, shortened with an ellipsis if longer than the plot is high
  std::string x_label;    // in the common unit style
  std::vector<LegendEntry> legend;
  AxisTicks x_ticks, y_ticks;  // x_ticks.lo/hi = the data range of the panel's x group
  std::vector<double> marker_px;  // x pixel of each marker inside the plot box (NaN if outside)
  // Box of each marker's label inside the plot box, beside its line: the first of the places
  // (top, bottom, middle; right, then left of the line) where it covers no drawn data, else the
  // one covering the least (empty box when the marker is outside or has no label).
  std::vector<Rect> marker_label_box;
  // Each span of the plot (same order) clipped to the plot box, full height; empty (w = 0) when it
  // lies outside the x range. Its colour: span_colour[i].
  std::vector<Rect> span_boxes;
  std::vector<Rgb> span_colour;
};

struct FigureLayout {
  int width = 0, height = 0;
  std::vector<PanelLayout> panels;
  std::map<std::string, Rgb> colours;  // per key

  double px(const Plot& p, const PanelLayout& l, double x) const;  // data -> canvas
  double py(const Plot& p, const PanelLayout& l, double y) const;
};

// A linear x axis whose data begin at x0 > 0 with x0 <= kZeroSnap x (the data's span) starts at 0.
inline constexpr double kZeroSnap = 0.02;
// A linear y axis spans at most this multiple of its data's range when up to two more ticks get it there.
inline constexpr double kMaxYRangeOverData = 1.4;
// Span fill opacity: light enough that dots and lines on top keep their colour.
inline constexpr double kSpanAlpha = 0.22;

// Font sizes (px) every figure uses.
// Inner margin of the y range inside the plot frame (px).
inline constexpr double kYInset = 5;
inline constexpr int kMaxTitleLines = 2;
inline constexpr double kTitleLine = 20;  // px between title baselines
inline constexpr double kTitleFont = 16, kLegendFont = 13, kTickFont = 12, kAxisLabelFont = 13, kMarkerFont = 12;

FigureLayout layout_figure(const std::vector<Plot>& panels, const FigureOptions& options);

// How many drawn segments and points of the panel's series (as the renderer draws them: lines,
// steps with their vertical risers, dots) touch box r, in canvas px.
int data_touching(const Plot& p, const PanelLayout& l, const FigureLayout& L, const Rect& r);

// Labels in the common unit style whoever wrote them: "degC" -> "°C", and on an axis a unit in
// brackets "[K]" -> "(K)".
std::string unit_style(std::string label, bool axis = true);

}  // namespace btsm::report
