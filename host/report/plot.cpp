#include "host/report/plot.hpp"

#include "host/io/output_file.hpp"
#include "host/report/decimate.hpp"
#include "host/report/plot_layout.hpp"

#include <cairo-svg.h>
#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace btsm::report {
namespace {

// How densely series are drawn: the decimation grid in canvas pixels. The PNG uses a quarter
// pixel, which changes no pixel of the picture but keeps a 100,000-sample series from costing
// seconds; the SVG starts at one pixel and gets coarser on each try until the file fits its bound.
struct Density {
  double line_bucket_px = 0;
  double point_cell_px = 0;
};

constexpr double kModelLineWidth = 1.3, kDotDiameter = 4.5;  // a dot band wider than the line on it
const Rgb kInk{0.10, 0.10, 0.10}, kGrid{0.88, 0.88, 0.88}, kTickInk{0.20, 0.20, 0.20};

bool usable(double v, bool log) { return std::isfinite(v) && (!log || v > 0); }

void set_colour(cairo_t* cr, Rgb c) { cairo_set_source_rgb(cr, c.r, c.g, c.b); }

void text(cairo_t* cr, double x, double y, const std::string& s, double size, double align_x, double align_y,
          bool vertical = false) {
  cairo_save(cr);
  cairo_set_font_size(cr, size);
  cairo_text_extents_t ext;
  cairo_text_extents(cr, s.c_str(), &ext);
  cairo_translate(cr, x, y);
  if (vertical) cairo_rotate(cr, -M_PI / 2);
  cairo_move_to(cr, -ext.x_advance * align_x, size * 0.72 * align_y);
  cairo_show_text(cr, s.c_str());
  cairo_restore(cr);
}

void apply_line_style(cairo_t* cr, Series::Style style) {
  cairo_set_line_width(cr, kModelLineWidth);
  cairo_set_line_cap(cr, CAIRO_LINE_CAP_BUTT);
  cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
  const double dash[] = {7, 4};
  if (style == Series::Style::Dashed) cairo_set_dash(cr, dash, 2, 0);
  else cairo_set_dash(cr, nullptr, 0, 0);
}

// Dots as zero-length round-capped segments in one path: the same look as circles, a tenth of the
// SVG size.
void draw_dots(cairo_t* cr, const std::vector<double>& X, const std::vector<double>& Y, const std::vector<size_t>& idx) {
  cairo_set_dash(cr, nullptr, 0, 0);
  cairo_set_line_width(cr, kDotDiameter);
  cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
  for (size_t i : idx) {
    cairo_move_to(cr, X[i], Y[i]);
    cairo_rel_line_to(cr, 0, 0);
  }
  cairo_stroke(cr);
}

void draw_series(cairo_t* cr, const FigureLayout& L, const Plot& p, const PanelLayout& l, const Series& s,
                 const Density& d) {
  const size_t n = std::min(s.x.size(), s.y.size());
  std::vector<double> X(n), Y(n);
  for (size_t i = 0; i < n; ++i) {
    const bool ok = usable(s.x[i], p.log_x) && usable(s.y[i], p.log_y);
    X[i] = ok ? L.px(p, l, s.x[i]) : NAN;
    Y[i] = ok ? L.py(p, l, s.y[i]) : NAN;
  }
  const Rgb c = L.colours.at(s.key.empty() ? s.label : s.key);
  if (s.style == Series::Style::Points) {
    set_colour(cr, measured_tint(c));
    draw_dots(cr, X, Y, decimate_points(X, Y, d.point_cell_px));
    return;
  }
  // Steps are few and their corners matter; they are thinned only when denser than the canvas.
  const bool thin = s.style != Series::Style::Step || n > 4 * static_cast<size_t>(L.width);
  const auto idx = decimate_line(X, Y, thin ? d.line_bucket_px : 0);
  set_colour(cr, c);
  apply_line_style(cr, s.style);
  bool pen_down = false;
  double last_y = 0;
  for (size_t i : idx) {
    if (!std::isfinite(X[i]) || !std::isfinite(Y[i])) {
      pen_down = false;
      continue;
    }
    if (!pen_down) cairo_move_to(cr, X[i], Y[i]);
    else if (s.style == Series::Style::Step) cairo_line_to(cr, X[i], last_y), cairo_line_to(cr, X[i], Y[i]);
    else cairo_line_to(cr, X[i], Y[i]);
    pen_down = true;
    last_y = Y[i];
  }
  cairo_stroke(cr);
}

void draw_axes(cairo_t* cr, const Plot& p, const PanelLayout& l) {
  const Rect& b = l.plot;
  auto fx = [&](double v) {
    const auto& t = l.x_ticks;
    const double f = p.log_x ? (std::log10(v) - std::log10(t.lo)) / (std::log10(t.hi) - std::log10(t.lo))
                             : (v - t.lo) / (t.hi - t.lo);
    return b.x + f * b.w;
  };
  auto fy = [&](double v) {
    const auto& t = l.y_ticks;
    const double f = p.log_y ? (std::log10(v) - std::log10(t.lo)) / (std::log10(t.hi) - std::log10(t.lo))
                             : (v - t.lo) / (t.hi - t.lo);
    return b.y + kYInset + (b.h - 2 * kYInset) * (1 - f);
  };
  cairo_set_dash(cr, nullptr, 0, 0);
  cairo_set_line_width(cr, 1);
  for (size_t i = 0; i < l.x_ticks.values.size(); ++i) {
    const double x = fx(l.x_ticks.values[i]);
    set_colour(cr, kGrid);
    cairo_move_to(cr, x, b.y), cairo_line_to(cr, x, b.y + b.h), cairo_stroke(cr);
    set_colour(cr, kTickInk);
    text(cr, x, b.y + b.h + 8 + kTickFont * 0.72, l.x_ticks.labels[i], kTickFont, 0.5, 0);
  }
  for (size_t i = 0; i < l.y_ticks.values.size(); ++i) {
    const double y = fy(l.y_ticks.values[i]);
    set_colour(cr, kGrid);
    cairo_move_to(cr, b.x, y), cairo_line_to(cr, b.x + b.w, y), cairo_stroke(cr);
    set_colour(cr, kTickInk);
    text(cr, b.x - 8, y, l.y_ticks.labels[i], kTickFont, 1, 0.5);
  }
  set_colour(cr, kInk);
  cairo_rectangle(cr, b.x, b.y, b.w, b.h), cairo_stroke(cr);
  text(cr, b.x + b.w / 2, b.y + b.h + 10 + kTickFont + 10 + kAxisLabelFont * 0.72, l.x_label, kAxisLabelFont, 0.5, 0);
  text(cr, l.area.x + 8 + kAxisLabelFont * 0.72, b.y + b.h / 2, l.y_label, kAxisLabelFont, 0.5, 0, true);
}

void draw_markers(cairo_t* cr, const Plot& p, const PanelLayout& l) {
  cairo_set_font_size(cr, kMarkerFont);
  for (size_t i = 0; i < p.markers.size(); ++i) {
    const double x = l.marker_px[i];
    if (!std::isfinite(x)) continue;
    set_colour(cr, kInk);
    cairo_set_line_width(cr, 1.2);
    const double dash[] = {4, 3};
    cairo_set_dash(cr, dash, 2, 0);
    cairo_move_to(cr, x, l.plot.y), cairo_line_to(cr, x, l.plot.y + l.plot.h), cairo_stroke(cr);
    cairo_set_dash(cr, nullptr, 0, 0);
    if (p.markers[i].label.empty()) continue;
    const Rect& box = l.marker_label_box[i];  // placed off the data by layout_figure
    cairo_set_source_rgba(cr, 1, 1, 1, 0.85);
    cairo_rectangle(cr, box.x, box.y, box.w, box.h), cairo_fill(cr);
    set_colour(cr, kInk);
    text(cr, box.x + 2, box.y + 2 + kMarkerFont * 0.5, p.markers[i].label, kMarkerFont, 0, 0.5);
  }
}

void draw_spans(cairo_t* cr, const PanelLayout& l) {
  for (size_t i = 0; i < l.span_boxes.size(); ++i) {
    const Rect& r = l.span_boxes[i];
    if (!(r.w > 0)) continue;
    const Rgb c = l.span_colour[i];
    cairo_set_source_rgba(cr, c.r, c.g, c.b, kSpanAlpha);
    cairo_rectangle(cr, r.x, r.y, r.w, r.h);
    cairo_fill(cr);
  }
}

void draw_legend(cairo_t* cr, const PanelLayout& l) {
  for (const auto& e : l.legend) {
    const double y = e.box.y + e.box.h / 2, x0 = e.box.x, x1 = e.box.x + 26;
    if (e.shaded) {
      cairo_set_source_rgba(cr, e.colour.r, e.colour.g, e.colour.b, kSpanAlpha);
      cairo_rectangle(cr, x0, e.box.y + 2, x1 - x0, e.box.h - 4);
      cairo_fill(cr);
    } else if (e.style == Series::Style::Points) {
      set_colour(cr, measured_tint(e.colour));
      draw_dots(cr, {x0 + 5, x0 + 13, x0 + 21}, {y, y, y}, {0, 1, 2});
    } else {
      set_colour(cr, e.colour);
      apply_line_style(cr, e.style);
      cairo_set_line_width(cr, 2.2);
      cairo_move_to(cr, x0, y), cairo_line_to(cr, x1, y), cairo_stroke(cr);
    }
    set_colour(cr, kInk);
    text(cr, x1 + 5, y, e.text, kLegendFont, 0, 0.5);
  }
}

void render(const std::vector<Plot>& panels, const FigureLayout& L, cairo_surface_t* surface, const Density& d) {
  cairo_t* cr = cairo_create(surface);
  cairo_font_options_t* fo = cairo_font_options_create();
  cairo_font_options_set_hint_metrics(fo, CAIRO_HINT_METRICS_OFF);  // as layout_figure measured
  cairo_set_font_options(cr, fo);
  cairo_font_options_destroy(fo);
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  for (size_t i = 0; i < panels.size(); ++i) {
    const Plot& p = panels[i];
    const PanelLayout& l = L.panels[i];
    set_colour(cr, kInk);
    for (size_t k = 0; k < l.title_lines.size(); ++k)
      text(cr, L.width / 2.0, l.title_y + kTitleLine * static_cast<double>(k), l.title_lines[k], kTitleFont, 0.5, 0);
    draw_axes(cr, p, l);
    cairo_save(cr);
    cairo_rectangle(cr, l.plot.x, l.plot.y, l.plot.w, l.plot.h);
    cairo_clip(cr);
    draw_spans(cr, l);  // under everything: the shading says when, the data on top what
    // Measured dots underneath, model curves on top of them.
    for (const auto& s : p.series)
      if (s.style == Series::Style::Points) draw_series(cr, L, p, l, s, d);
    for (const auto& s : p.series)
      if (s.style != Series::Style::Points) draw_series(cr, L, p, l, s, d);
    cairo_restore(cr);
    draw_markers(cr, p, l);
    draw_legend(cr, l);
  }
  cairo_destroy(cr);
}

cairo_status_t append_to_string(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

std::string render_svg(const std::vector<Plot>& panels, const FigureLayout& L, const Density& d,
                       const std::string& path) {
  std::string out;
  cairo_surface_t* vec = cairo_svg_surface_create_for_stream(append_to_string, &out, L.width, L.height);
  render(panels, L, vec, d);
  cairo_surface_finish(vec);
  const cairo_status_t st = cairo_surface_status(vec);
  cairo_surface_destroy(vec);
  if (st != CAIRO_STATUS_SUCCESS) throw std::runtime_error("cannot draw plot " + path + ": " + cairo_status_to_string(st));
  return out;
}

}  // namespace

void save_figure(const std::vector<Plot>& panels, const std::string& stem, const FigureOptions& o) {
  if (panels.empty()) throw std::runtime_error("plot " + stem + ": nothing to draw");
  const FigureLayout L = layout_figure(panels, o);

  // Both files go through the output helper (beside and renamed, never a named pipe: cairo's own
  // file writer and an ofstream blocked for ever on one, after the whole run).
  const std::string png = stem + ".png";
  cairo_surface_t* img = cairo_image_surface_create(CAIRO_FORMAT_RGB24, L.width, L.height);
  render(panels, L, img, Density{0.25, 0.25});
  std::string png_bytes;
  const cairo_status_t st = cairo_surface_write_to_png_stream(img, append_to_string, &png_bytes);
  cairo_surface_destroy(img);
  if (st != CAIRO_STATUS_SUCCESS) throw std::runtime_error("cannot draw plot " + png + ": " + cairo_status_to_string(st));
  io::write_output_file(png, png_bytes, "plot");

  // One canvas pixel per decimation cell looks identical to every sample; coarser only if the
  // file would still exceed its bound (many dense panels).
  const std::string svg = stem + ".svg";
  std::string bytes;
  for (double cell = 1; cell <= 16; cell *= 2) {
    bytes = render_svg(panels, L, Density{cell, cell}, svg);
    if (bytes.size() <= o.svg_max_bytes) break;
  }
  io::write_output_file(svg, bytes, "plot");
}

void save_plot(const Plot& p, const std::string& stem, int width, int height) {
  FigureOptions o;
  o.width = width;
  o.panel_height = height;
  save_figure({p}, stem, o);
}

void save_panels(const std::vector<Plot>& panels, const std::string& stem, int width, int panel_height) {
  FigureOptions o;
  o.width = width;
  o.panel_height = panel_height;
  save_figure(panels, stem, o);
}

}  // namespace btsm::report
