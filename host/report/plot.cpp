#include "host/report/plot.hpp"

#include "host/report/axis_ticks.hpp"

#include <cairo-svg.h>
#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace btsm::report {
namespace {

struct Rgb { double r, g, b; };
// Colour-blind-safe palette (Okabe–Ito), in the order series are drawn.
constexpr Rgb kPalette[] = {{0.00, 0.45, 0.70}, {0.84, 0.37, 0.00}, {0.00, 0.62, 0.45},
                            {0.80, 0.47, 0.65}, {0.34, 0.71, 0.91}, {0.90, 0.62, 0.00},
                            {0.00, 0.00, 0.00}, {0.94, 0.89, 0.26}};

struct Box { double x, y, w, h; };

bool usable(double y, bool log_y) { return std::isfinite(y) && (!log_y || y > 0); }

void text(cairo_t* cr, double x, double y, const std::string& s, double size, double align_x,
          double align_y, bool vertical = false) {
  cairo_save(cr);
  cairo_set_font_size(cr, size);
  cairo_text_extents_t ext;
  cairo_text_extents(cr, s.c_str(), &ext);
  cairo_translate(cr, x, y);
  if (vertical) cairo_rotate(cr, -M_PI / 2);
  cairo_move_to(cr, -ext.x_advance * align_x, ext.height * align_y);
  cairo_show_text(cr, s.c_str());
  cairo_restore(cr);
}

void draw_plot(cairo_t* cr, const Plot& p, Box area) {
  // Data ranges.
  double xlo = std::numeric_limits<double>::infinity(), xhi = -xlo, ylo = xlo, yhi = -xlo;
  for (const auto& s : p.series)
    for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (!std::isfinite(s.x[i]) || !usable(s.y[i], p.log_y)) continue;
      xlo = std::min(xlo, s.x[i]), xhi = std::max(xhi, s.x[i]);
      ylo = std::min(ylo, s.y[i]), yhi = std::max(yhi, s.y[i]);
    }
  const AxisTicks xt = linear_ticks(xlo, xhi, 8);
  const AxisTicks yt = p.log_y ? log_ticks(ylo, yhi) : linear_ticks(ylo, yhi, 6);

  const Box plot{area.x + 78, area.y + 34, area.w - 78 - 170, area.h - 34 - 52};
  auto px = [&](double x) { return plot.x + (x - xt.lo) / (xt.hi - xt.lo) * plot.w; };
  auto py = [&](double y) {
    const double f = p.log_y ? (std::log10(y) - std::log10(yt.lo)) / (std::log10(yt.hi) - std::log10(yt.lo))
                             : (y - yt.lo) / (yt.hi - yt.lo);
    return plot.y + plot.h * (1 - f);
  };

  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_source_rgb(cr, 0, 0, 0);
  text(cr, plot.x + plot.w / 2, area.y + 20, p.title, 15, 0.5, 0);

  // Grid and tick labels.
  cairo_set_line_width(cr, 1);
  for (size_t i = 0; i < xt.values.size(); ++i) {
    const double x = px(xt.values[i]);
    cairo_set_source_rgb(cr, 0.88, 0.88, 0.88);
    cairo_move_to(cr, x, plot.y), cairo_line_to(cr, x, plot.y + plot.h), cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0.15, 0.15, 0.15);
    text(cr, x, plot.y + plot.h + 16, xt.labels[i], 11, 0.5, 0);
  }
  for (size_t i = 0; i < yt.values.size(); ++i) {
    const double y = py(yt.values[i]);
    cairo_set_source_rgb(cr, 0.88, 0.88, 0.88);
    cairo_move_to(cr, plot.x, y), cairo_line_to(cr, plot.x + plot.w, y), cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0.15, 0.15, 0.15);
    text(cr, plot.x - 6, y, yt.labels[i], 11, 1, 0.5);
  }
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_rectangle(cr, plot.x, plot.y, plot.w, plot.h), cairo_stroke(cr);
  text(cr, plot.x + plot.w / 2, plot.y + plot.h + 38, p.x_label, 12, 0.5, 0);
  text(cr, area.x + 16, plot.y + plot.h / 2, p.y_label, 12, 0.5, 0.5, true);

  // Series, clipped to the plot box.
  cairo_save(cr);
  cairo_rectangle(cr, plot.x, plot.y, plot.w, plot.h);
  cairo_clip(cr);
  for (size_t k = 0; k < p.series.size(); ++k) {
    const auto& s = p.series[k];
    const Rgb c = kPalette[k % (sizeof kPalette / sizeof kPalette[0])];
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_set_line_width(cr, 1.6);
    const size_t n = std::min(s.x.size(), s.y.size());
    if (s.style == Series::Style::Points) {
      for (size_t i = 0; i < n; ++i)
        if (std::isfinite(s.x[i]) && usable(s.y[i], p.log_y)) {
          cairo_arc(cr, px(s.x[i]), py(s.y[i]), 2.2, 0, 2 * M_PI);
          cairo_fill(cr);
        }
      continue;
    }
    bool pen_down = false;
    double last_y = 0;
    for (size_t i = 0; i < n; ++i) {
      if (!std::isfinite(s.x[i]) || !usable(s.y[i], p.log_y)) { pen_down = false; continue; }
      const double X = px(s.x[i]), Y = py(s.y[i]);
      if (!pen_down) cairo_move_to(cr, X, Y);
      else if (s.style == Series::Style::Step) cairo_line_to(cr, X, last_y), cairo_line_to(cr, X, Y);
      else cairo_line_to(cr, X, Y);
      pen_down = true;
      last_y = Y;
    }
    cairo_stroke(cr);
  }
  cairo_restore(cr);

  // Legend to the right of the plot.
  double ly = plot.y + 8;
  for (size_t k = 0; k < p.series.size(); ++k) {
    if (p.series[k].label.empty()) continue;
    const Rgb c = kPalette[k % (sizeof kPalette / sizeof kPalette[0])];
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_set_line_width(cr, 3);
    cairo_move_to(cr, plot.x + plot.w + 12, ly), cairo_line_to(cr, plot.x + plot.w + 34, ly);
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    text(cr, plot.x + plot.w + 40, ly, p.series[k].label, 11, 0, 0.5);
    ly += 18;
  }
}

void render(const std::vector<Plot>& panels, cairo_surface_t* surface, int width, int panel_height) {
  cairo_t* cr = cairo_create(surface);
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  for (size_t i = 0; i < panels.size(); ++i)
    draw_plot(cr, panels[i], Box{0, static_cast<double>(i) * panel_height, static_cast<double>(width),
                                 static_cast<double>(panel_height)});
  cairo_destroy(cr);
}

void check(cairo_surface_t* s, const std::string& path) {
  if (cairo_surface_status(s) != CAIRO_STATUS_SUCCESS)
    throw std::runtime_error("cannot write plot " + path + ": " +
                             cairo_status_to_string(cairo_surface_status(s)));
}

}  // namespace

void save_panels(const std::vector<Plot>& panels, const std::string& stem, int width, int panel_height) {
  if (panels.empty()) throw std::runtime_error("plot " + stem + ": nothing to draw");
  const int height = panel_height * static_cast<int>(panels.size());

  const std::string png = stem + ".png";
  cairo_surface_t* img = cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height);
  render(panels, img, width, panel_height);
  const cairo_status_t st = cairo_surface_write_to_png(img, png.c_str());
  cairo_surface_destroy(img);
  if (st != CAIRO_STATUS_SUCCESS)
    throw std::runtime_error("cannot write plot " + png + ": " + cairo_status_to_string(st));

  const std::string svg = stem + ".svg";
  cairo_surface_t* vec = cairo_svg_surface_create(svg.c_str(), width, height);
  check(vec, svg);
  render(panels, vec, width, panel_height);
  cairo_surface_finish(vec);
  check(vec, svg);
  cairo_surface_destroy(vec);
}

void save_plot(const Plot& p, const std::string& stem, int width, int height) {
  save_panels({p}, stem, width, height);
}

}  // namespace btsm::report
