// The common plot style (host/report/plot_style.hpp, plot_layout.hpp): legends inside the canvas,
// one colour per node across panels and figures, x axes ending at the data, markers drawn, SVG
// within its size bound while the PNG keeps every sample.
#include "host/report/decimate.hpp"
#include "host/report/plot_layout.hpp"
#include "host/report/plot_style.hpp"

#include <cairo.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

namespace fs = std::filesystem;
using namespace btsm::report;

namespace {

std::vector<double> ramp(size_t n, double lo, double hi) {
  std::vector<double> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = lo + (hi - lo) * static_cast<double>(i) / static_cast<double>(n - 1);
  return v;
}

std::vector<double> noisy_wave(size_t n, double offset, unsigned seed) {
  std::mt19937 g(seed);
  std::normal_distribution<double> noise(0, 0.05);
  std::vector<double> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = offset + std::sin(static_cast<double>(i) * 5e-4) + noise(g);
  return v;
}

Rect canvas(const FigureLayout& L) { return Rect{0, 0, static_cast<double>(L.width), static_cast<double>(L.height)}; }

}  // namespace

TEST(PlotStyle, LegendStaysInsideTheCanvasAndOffTheData) {
  // Many long labels: the old legend column right of the plot ran off the canvas.
  Plot p{"A figure with more legend entries than one row holds", kTimeAxis, kTemperatureAxis, {}};
  const auto t = ramp(50, 0, 26.2);
  for (int k = 0; k < 9; ++k) {
    const std::string node = "a_node_with_a_rather_long_name_" + std::to_string(k);
    p.series.push_back(measured(node, t, noisy_wave(50, k, k)));
    p.series.push_back(model(node, t, noisy_wave(50, k, k + 100)));
  }
  p.series.push_back(alternative("x", t, t, std::string(300, 'w')));  // wider than the canvas alone
  for (int width : {480, 1000}) {
    FigureOptions o;
    o.width = width;
    const FigureLayout L = layout_figure({p, p}, o);
    for (const auto& panel : L.panels) {
      ASSERT_GE(panel.legend.size(), 10u);
      for (size_t i = 0; i < panel.legend.size(); ++i) {
        const auto& e = panel.legend[i];
        EXPECT_TRUE(canvas(L).contains(e.box)) << e.text << " at x " << e.box.x << " w " << e.box.w << " width " << width;
        EXPECT_TRUE(panel.area.contains(e.box)) << e.text;
        EXPECT_FALSE(e.box.overlaps(panel.plot)) << e.text << " covers the data";
        for (size_t j = 0; j < i; ++j) EXPECT_FALSE(e.box.overlaps(panel.legend[j].box)) << e.text;
      }
      EXPECT_TRUE(canvas(L).contains(panel.plot));
    }
  }
}

TEST(PlotStyle, OneColourPerNodeInEveryPanelAndFigure) {
  const auto t = ramp(10, 0, 1);
  Plot temps{"temps", kTimeAxis, kTemperatureAxis, {measured("column", t, t), model("column", t, t),
                                                    measured("head", t, t), model("head", t, t)}};
  // The residual panel lists the nodes in another order: colours must follow the node, not the position.
  Plot resid{"residuals", kTimeAxis, kResidualAxis, {trace("head", t, t), trace("column", t, t), trace("spindle", t, t)}};
  FigureOptions o;
  o.key_order = {"spindle", "head", "column"};
  const FigureLayout L = layout_figure({temps, resid}, o);
  EXPECT_EQ(L.colours.at("column"), L.colours.at("column"));
  EXPECT_FALSE(L.colours.at("column") == L.colours.at("head"));
  EXPECT_FALSE(L.colours.at("spindle") == L.colours.at("head"));
  // The same network's order gives the same colours in a figure that shows only one node.
  const FigureLayout single = layout_figure({Plot{"only column", kTimeAxis, kResidualAxis, {trace("column", t, t)}}}, o);
  EXPECT_EQ(single.colours.at("column"), L.colours.at("column"));
  // Legend entries of a node carry the node's colour in both panels.
  auto entry_colour = [](const PanelLayout& pl, const std::string& text) {
    for (const auto& e : pl.legend)
      if (e.text == text) return e.colour;
    ADD_FAILURE() << "no legend entry " << text;
    return Rgb{};
  };
  EXPECT_EQ(entry_colour(L.panels[0], "head"), entry_colour(L.panels[1], "head"));
  // Channel role names keep their colour whatever else a figure holds.
  const auto a = assign_colours({Plot{"", "", "", {trace("rear_bearing", t, t), trace("housing", t, t)}}}, {});
  const auto b = assign_colours({Plot{"", "", "", {trace("shaft", t, t), trace("rear_bearing", t, t)}}}, {"shaft", "zzz"});
  EXPECT_EQ(a.at("rear_bearing"), b.at("rear_bearing"));
  Rgb fixed;
  ASSERT_TRUE(fixed_colour("rear_bearing", fixed));
  EXPECT_EQ(fixed, a.at("rear_bearing"));
}

TEST(PlotStyle, NodeNamesInTheLegendAndKindsSeparately) {
  const auto t = ramp(10, 0, 1);
  Plot p{"", kTimeAxis, kTemperatureAxis, {measured("rear_bearing", t, t), model("rear_bearing", t, t)}};
  const FigureLayout L = layout_figure({p}, {});
  std::vector<std::string> texts;
  for (const auto& e : L.panels[0].legend) texts.push_back(e.text);
  EXPECT_EQ(texts, (std::vector<std::string>{"rear bearing", "measured", "model"}));
}

TEST(PlotStyle, TimeAxisEndsAtTheDataAndStackedPanelsLineUp) {
  const auto t = ramp(100, 0, 26.2);
  Plot temps{"t", kTimeAxis, kTemperatureAxis, {model("a", t, t)}};
  Plot speed = speed_panel(ramp(10, 0, 25.0), ramp(10, 0, 6000));
  const FigureLayout L = layout_figure({temps, speed}, {});
  for (const auto& pl : L.panels) {
    EXPECT_DOUBLE_EQ(pl.x_ticks.lo, 0.0);
    EXPECT_DOUBLE_EQ(pl.x_ticks.hi, 26.2);  // not rounded out to 30
    EXPECT_LE(pl.x_ticks.values.back(), 26.2);
    EXPECT_DOUBLE_EQ(pl.plot.x, L.panels[0].plot.x);
    EXPECT_DOUBLE_EQ(pl.plot.w, L.panels[0].plot.w);
  }
  EXPECT_LT(L.panels[1].area.h, L.panels[0].area.h);  // the speed panel is the short one
  EXPECT_EQ(speed.y_label, std::string("speed (rpm)"));
}

TEST(PlotStyle, ATimeAxisWhoseDataBeginJustAfterZeroStartsAtAZeroTick) {
  // A recording's first sample 5 s in, a production run watched from its start: the axis used to
  // begin at 0.0014 h with its first tick at 0.5.
  const auto t = ramp(3600, 5.0 / 3600, 5.0);
  const FigureLayout L = layout_figure({Plot{"t", kTimeAxis, kTemperatureAxis, {model("a", t, t)}}}, {});
  const AxisTicks& x = L.panels[0].x_ticks;
  EXPECT_DOUBLE_EQ(x.lo, 0.0);
  ASSERT_FALSE(x.values.empty());
  EXPECT_DOUBLE_EQ(x.values.front(), 0.0);
  EXPECT_EQ(x.labels.front().find_first_not_of("0."), std::string::npos) << x.labels.front();
  EXPECT_DOUBLE_EQ(x.hi, 5.0);  // still ends at the data
  // Data that begin well into the axis (a check part cut from 2.8 h on) keep their own start.
  const auto late = ramp(100, 2.8, 5.4);
  const FigureLayout M = layout_figure({Plot{"t", kTimeAxis, kTemperatureAxis, {model("a", late, late)}}}, {});
  EXPECT_DOUBLE_EQ(M.panels[0].x_ticks.lo, 2.8);
}

TEST(PlotStyle, AShortSpeedPanelsAxisEndsNearItsTopSpeed) {
  // Speeds up to 6000 rpm were drawn on a 0-10000 axis (two ticks' worth of a short panel).
  const Plot speed = speed_panel(ramp(10, 0, 5.0), {0, 6000, 6000, 6000, 3000, 3000, 0, 0, 5000, 5000});
  const FigureLayout L = layout_figure({speed}, {});
  const AxisTicks& y = L.panels[0].y_ticks;
  EXPECT_DOUBLE_EQ(y.lo, 0.0);
  EXPECT_LE(y.hi, 1.4 * 6000);
  EXPECT_GE(y.values.size(), 3u);
  for (size_t k = 1; k < y.values.size(); ++k)  // labels stay apart in the short panel
    EXPECT_GE(L.py(speed, L.panels[0], y.values[k - 1]) - L.py(speed, L.panels[0], y.values[k]), kTickFont + 2);
}

TEST(PlotStyle, SpansAreShadedUnderTheDataWithOneLegendEntryPerLabel) {
  const auto t = ramp(200, 0, 10);
  Plot p{"t", kTimeAxis, kTemperatureAxis, {model("a", t, t)}};
  p.spans = {{1.0, 2.0, "lid_open = 1"}, {6.0, 6.5, "lid_open = 1"}, {9.5, 12.0, "pump_on = 1"}, {20, 21, "pump_on = 1"}};
  const FigureLayout L = layout_figure({p}, {});
  const PanelLayout& l = L.panels[0];
  ASSERT_EQ(l.span_boxes.size(), 4u);
  EXPECT_NEAR(l.span_boxes[0].x, L.px(p, l, 1.0), 1e-9);
  EXPECT_NEAR(l.span_boxes[0].x + l.span_boxes[0].w, L.px(p, l, 2.0), 1e-9);
  EXPECT_DOUBLE_EQ(l.span_boxes[0].h, l.plot.h);
  EXPECT_TRUE(l.plot.contains(l.span_boxes[2]));  // clipped at the axis end (10)
  EXPECT_EQ(l.span_boxes[3].w, 0.0);              // outside the x range: not drawn
  EXPECT_FALSE(l.span_colour[0] == l.span_colour[2]);
  int lid = 0, pump = 0;
  for (const auto& e : l.legend) {
    if (!e.shaded) continue;
    lid += e.text == "lid_open = 1";
    pump += e.text == "pump_on = 1";
  }
  EXPECT_EQ(lid, 1);
  EXPECT_EQ(pump, 1);
  // Drawn: a pixel inside the span is tinted blue, one outside it is not.
  const fs::path dir = fs::temp_directory_path() / "btsm_span_plot";
  fs::create_directories(dir);
  Plot bare{"t", kTimeAxis, kTemperatureAxis, {Series{"flat", {0, 10}, {0, 0}, Series::Style::Line, "a"}}};
  bare.spans = {{1.0, 2.0, "lid_open = 1"}};
  save_plot(bare, (dir / "span").string(), 1000, 420);
  FigureOptions o;
  o.panel_height = 420;
  const FigureLayout B = layout_figure({bare}, o);
  cairo_surface_t* png = cairo_image_surface_create_from_png((dir / "span.png").string().c_str());
  ASSERT_EQ(cairo_surface_status(png), CAIRO_STATUS_SUCCESS);
  auto blueness = [&](double x, double y) {  // blue minus red of the pixel, 0..255
    const unsigned char* d = cairo_image_surface_get_data(png);
    const int stride = cairo_image_surface_get_stride(png);
    const auto px = reinterpret_cast<const uint32_t*>(d + stride * static_cast<int>(y))[static_cast<int>(x)];
    return static_cast<int>(px & 0xff) - static_cast<int>((px >> 16) & 0xff);
  };
  const PanelLayout& b = B.panels[0];
  const double y = b.plot.y + 0.3 * b.plot.h;
  EXPECT_GT(blueness(B.px(bare, b, 1.5), y), 12);
  EXPECT_LT(std::abs(blueness(B.px(bare, b, 4.5), y)), 3);
  cairo_surface_destroy(png);
  fs::remove_all(dir);
}

TEST(PlotStyle, MarkerLandsAtItsValueInsideThePlot) {
  Plot gcv{"GCV", "α (K²/W²)", "GCV (K²)", {Series{"GCV", {1e-10, 1e-5, 1e3}, {1e-2, 1e-3, 1}, Series::Style::Line, "gcv"}}};
  gcv.log_x = gcv.log_y = true;
  gcv.markers.push_back({1e-5, "chosen α"});
  const FigureLayout L = layout_figure({gcv}, {});
  ASSERT_EQ(L.panels[0].marker_px.size(), 1u);
  const double x = L.panels[0].marker_px[0];
  const Rect& b = L.panels[0].plot;
  EXPECT_GT(x, b.x);
  EXPECT_LT(x, b.x + b.w);
  EXPECT_NEAR(x, L.px(gcv, L.panels[0], 1e-5), 1e-9);
  EXPECT_NEAR((x - b.x) / b.w, 5.0 / 13.0, 1e-9);  // decades 1e-10 .. 1e3
}

TEST(PlotStyle, LongTitleAndAxisLabelAreShortenedToFit) {
  Plot p{std::string(400, 'T'), kTimeAxis, std::string(100, 'Y'), {model("a", {0, 1}, {0, 1})}};
  FigureOptions o;
  o.width = 600;
  const FigureLayout L = layout_figure({p}, o);
  EXPECT_LT(L.panels[0].title.size(), 400u);
  EXPECT_NE(L.panels[0].title.find("…"), std::string::npos);
  EXPECT_LT(L.panels[0].y_label.size(), 100u);  // it runs along the plot's height, not into the next panel
  EXPECT_NE(L.panels[0].y_label.find("…"), std::string::npos);
  EXPECT_EQ(layout_figure({Plot{"t", "x", "short", {}}}, o).panels[0].y_label, "short");
}

TEST(Decimate, LineKeepsTheEnvelopeOfEveryBucketAndTheBreaks) {
  std::vector<double> x, y;
  for (int i = 0; i < 1000; ++i) x.push_back(i * 0.01), y.push_back(i % 7 == 3 ? 5.0 : (i % 11 == 0 ? -5.0 : 0.0));
  y[500] = NAN;
  const auto keep = decimate_line(x, y, 1.0);  // 10 buckets of 100 points
  EXPECT_LE(keep.size(), 4u * 11 + 1);
  bool has_break = false;
  for (size_t i : keep) has_break |= i == 500;
  EXPECT_TRUE(has_break);
  for (int b = 0; b < 10; ++b) {  // every bucket keeps its highest and lowest value
    double lo = 1e9, hi = -1e9;
    for (size_t i : keep)
      if (std::isfinite(y[i]) && static_cast<int>(std::floor(x[i])) == b) lo = std::min(lo, y[i]), hi = std::max(hi, y[i]);
    EXPECT_EQ(hi, 5.0) << b;
    EXPECT_EQ(lo, -5.0) << b;
  }
  EXPECT_EQ(decimate_line(x, y, 0).size(), x.size());  // 0 = every sample
}

TEST(Decimate, PointsOnePerCell) {
  const auto keep = decimate_points({0.1, 0.2, 0.9, 1.1, NAN}, {0.1, 0.3, 0.2, 0.1, 0}, 1.0);
  EXPECT_EQ(keep, (std::vector<size_t>{0, 3}));
}

TEST(PlotStyle, SvgStaysUnderItsBoundWhilePngHasEverySample) {
  // Three panels of five 20,000-sample series each, measured dots and model lines: the old
  // writer produced 6-11 MB SVGs from a quarter of that.
  const size_t n = 20000;
  const auto t = ramp(n, 0, 26.2);
  std::vector<Plot> panels;
  for (int k = 0; k < 3; ++k) {
    Plot p{"panel", kTimeAxis, kTemperatureAxis, {}};
    for (int s = 0; s < 5; ++s) {
      const std::string node = "node" + std::to_string(s);
      p.series.push_back(measured(node, t, noisy_wave(n, s, 10 * k + s)));
      p.series.push_back(model(node, t, noisy_wave(n, s, 1000 + 10 * k + s)));
    }
    panels.push_back(p);
  }
  const fs::path dir = fs::temp_directory_path() / "btsm_plot_style_test";
  fs::create_directories(dir);
  save_figure(panels, (dir / "big").string());
  EXPECT_LE(fs::file_size(dir / "big.svg"), 1000000u);
  EXPECT_GT(fs::file_size(dir / "big.svg"), 10000u);
  // A tighter bound is honoured too (coarser decimation).
  FigureOptions tight;
  tight.svg_max_bytes = 300000;
  save_figure(panels, (dir / "tight").string(), tight);
  EXPECT_LE(fs::file_size(dir / "tight.svg"), 300000u);
  // The PNG is drawn from every sample: the two PNGs are the same picture.
  EXPECT_EQ(fs::file_size(dir / "big.png"), fs::file_size(dir / "tight.png"));
  fs::remove_all(dir);
}

TEST(AxisTicks, WithinEndsExactlyAtTheData) {
  const AxisTicks t = linear_ticks_within(0.0, 26.2, 8);
  EXPECT_DOUBLE_EQ(t.lo, 0.0);
  EXPECT_DOUBLE_EQ(t.hi, 26.2);
  EXPECT_LE(t.values.back(), 26.2);
  EXPECT_GE(t.values.size(), 4u);
}

TEST(AxisTicks, ManyDecadesLabelOnlySome) {
  const AxisTicks t = log_ticks(1e-21, 10, 6);
  int labelled = 0;
  for (const auto& l : t.labels) labelled += !l.empty();
  EXPECT_LE(labelled, 6);
  EXPECT_EQ(t.values.size(), 23u);  // every decade keeps its grid line
}

TEST(PlotStyle, AnIndexAxisHasWholeNumberTicks) {
  const FigureLayout L = layout_figure({Plot{"HSV", "state index", "K/W", {Series{"a", {1, 2, 3, 4}, {1, 0.1, 0.01, 0.001}}}}}, {});
  ASSERT_GE(L.panels[0].x_ticks.values.size(), 2u);
  for (size_t i = 0; i < L.panels[0].x_ticks.values.size(); ++i) {
    EXPECT_DOUBLE_EQ(L.panels[0].x_ticks.values[i], std::round(L.panels[0].x_ticks.values[i]));
    EXPECT_EQ(L.panels[0].x_ticks.labels[i].find('.'), std::string::npos) << L.panels[0].x_ticks.labels[i];
  }
}

TEST(PlotStyle, UnitsInOneStyleWhoeverWroteTheLabel) {
  const FigureLayout L =
      layout_figure({Plot{"Probe at 25 degC", "time [h]", "temperature [degC]", {model("a", {0, 1}, {0, 1})}}}, {});
  EXPECT_EQ(L.panels[0].y_label, "temperature (°C)");
  EXPECT_EQ(L.panels[0].x_label, "time (h)");
  EXPECT_EQ(L.panels[0].title, "Probe at 25 °C");
  EXPECT_EQ(unit_style("measured − model (K)"), "measured − model (K)");
  EXPECT_EQ(unit_style("T[1] at 20 degC", false), "T[1] at 20 °C");  // a title keeps its brackets
}

TEST(PlotStyle, LongTitlesWrapInsideTheCanvas) {
  // The incubator's declared input: one line of it ran off (was cut at) the right edge.
  const std::string declared =
      "speed_rpm column: NOT a speed - heater power in W while heater_on, ASSUMED 125.4 W (12.0 V x 10.45 A of the "
      "repository's 7-parameter model for this run, seven_parameters_model/best_parameters.py; not measured), 0 while off";
  Plot p{declared, kTimeAxis, kSpeedAxis, {model("a", {0, 1}, {0, 1}), model("b", {0, 1}, {1, 0})}};
  for (int width : {480, 800, 1000}) {
    FigureOptions o;
    o.width = width;
    const FigureLayout L = layout_figure({p, p}, o);
    for (const auto& panel : L.panels) {
      ASSERT_GE(panel.title_lines.size(), 2u) << "a title this long wraps at " << width;
      ASSERT_LE(panel.title_lines.size(), static_cast<size_t>(kMaxTitleLines));
      ASSERT_EQ(panel.title_boxes.size(), panel.title_lines.size());
      for (size_t k = 0; k < panel.title_boxes.size(); ++k) {
        const Rect& t = panel.title_boxes[k];
        EXPECT_TRUE(canvas(L).contains(t)) << "title line '" << panel.title_lines[k] << "' leaves the canvas at width " << width;
        EXPECT_TRUE(panel.area.contains(t)) << panel.title_lines[k];
        EXPECT_FALSE(t.overlaps(panel.plot)) << panel.title_lines[k];
        for (const auto& e : panel.legend) EXPECT_FALSE(t.overlaps(e.box)) << panel.title_lines[k] << " / " << e.text;
        if (k > 0) {
          EXPECT_FALSE(t.overlaps(panel.title_boxes[k - 1]));
        }
      }
    }
  }
  // Wide enough for two lines: nothing is lost, the lines are the title's words in order.
  FigureOptions wide;
  wide.width = 1000;
  const PanelLayout l = layout_figure({p}, wide).panels[0];
  ASSERT_EQ(l.title_lines.size(), 2u);
  EXPECT_EQ(l.title_lines[0] + " " + l.title_lines[1], declared);
  // A short title stays one line.
  EXPECT_EQ(layout_figure({Plot{"Spindle speed", kTimeAxis, kSpeedAxis, {}}}, wide).panels[0].title_lines.size(), 1u);
}

TEST(PlotStyle, MarkerLabelCoversNoData) {
  // The demo's alarm timeline: the diagnosis steps NORMAL -> WARN -> ALARM right after the fault
  // marker, at the top of the panel; the label "fault starts" used to sit on that step.
  std::vector<double> t, state;
  for (int k = 0; k <= 1200; ++k) {
    const double h = 0.01 * k;
    t.push_back(h);
    state.push_back(h < 4.12 ? 0 : h < 4.16 ? 1 : 2);
  }
  Plot diag{"Module diagnosis", kTimeAxis, "overall state", {Series{"overall state", t, state, Series::Style::Step}}};
  diag.height_weight = 0.7;
  diag.markers.push_back({4.0, "fault starts"});
  Plot temps{"Production", kTimeAxis, kTemperatureAxis, {model("rear_bearing", t, state)}};
  temps.markers.push_back({4.0, "fault starts"});
  temps.markers.push_back({4.05, "second marker"});
  const FigureLayout L = layout_figure({temps, diag}, {});
  for (size_t i = 0; i < 2; ++i) {
    const Plot& p = i == 0 ? temps : diag;
    const PanelLayout& l = L.panels[i];
    ASSERT_EQ(l.marker_label_box.size(), p.markers.size());
    for (size_t m = 0; m < p.markers.size(); ++m) {
      const Rect& box = l.marker_label_box[m];
      EXPECT_GT(box.w, 0);
      EXPECT_TRUE(l.plot.contains(box)) << p.markers[m].label;
      EXPECT_EQ(data_touching(p, l, L, box), 0) << p.markers[m].label << " covers data";
      for (size_t o = 0; o < m; ++o) EXPECT_FALSE(box.overlaps(l.marker_label_box[o])) << p.markers[m].label;
    }
  }
  // The test can fail: the old place (top, right of the line) covers the step.
  const PanelLayout& d = L.panels[1];
  const Rect old{d.marker_px[0] + 2, d.plot.y + 4, d.marker_label_box[0].w, d.marker_label_box[0].h};
  EXPECT_GT(data_touching(diag, d, L, old), 0);
}
