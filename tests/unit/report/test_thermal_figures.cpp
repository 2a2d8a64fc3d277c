// The figures of a network and a recording (host/report/thermal_figures.hpp) as `validate`, `heat`
// and the demo draw them: node names, °C, a speed panel, the chosen alpha marked.
#include "host/report/plot_layout.hpp"
#include "host/report/thermal_figures.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace btsm;
using namespace btsm::report;

namespace {

thermal::Recording small_recording(const thermal::Network& net) {
  thermal::Recording rec;
  rec.source = "warmup.csv";
  for (const auto& m : net.measurements) rec.channels.push_back(m.column);
  const int n = 50;
  rec.temp_c = Eigen::MatrixXd::Constant(n, static_cast<Eigen::Index>(rec.channels.size()), 25.0);
  for (int k = 0; k < n; ++k) {
    rec.time_s.push_back(600.0 * k);
    rec.speed_rpm.push_back(k < 30 ? 6000 : 0);
    rec.ambient_c.push_back(20);
  }
  rec.temp_c(3, 0) = NAN;  // a missing sample stays missing
  return rec;
}

bool mentions_deg_c(const std::string& s) { return s.find("degC") != std::string::npos; }

void expect_common_style(const std::vector<Plot>& panels, const thermal::Network& net) {
  bool speed = false;
  for (const auto& p : panels) {
    EXPECT_FALSE(mentions_deg_c(p.y_label) || mentions_deg_c(p.x_label) || mentions_deg_c(p.title)) << p.title;
    for (const auto& s : p.series) {
      if (s.key == "speed") {
        speed = true;
        continue;
      }
      if (p.x_label != kTimeAxis) continue;
      EXPECT_GE(net.node_index(s.key), 0) << "series keyed by '" << s.key << "', not a node name";
    }
  }
  EXPECT_TRUE(speed) << "no speed panel";
}

}  // namespace

TEST(ThermalFigures, ValidationShowsNodesInDegreesAndTheSpeed) {
  const thermal::Network net = thermal::preset_network("spindle4");
  const thermal::Recording rec = small_recording(net);
  thermal::RecordingValidation v;
  v.predicted_c = Eigen::MatrixXd::Constant(static_cast<Eigen::Index>(rec.rows()), net.node_count(), 25.5);
  const auto panels = validation_figure(net, rec, v, "warmup.csv");
  ASSERT_EQ(panels.size(), 3u);
  EXPECT_EQ(panels[0].y_label, std::string(kTemperatureAxis));
  expect_common_style(panels, net);
  const FigureLayout L = layout_figure(panels, network_figure_options(net));
  EXPECT_DOUBLE_EQ(L.panels[0].x_ticks.hi, rec.time_s.back() / 3600.0);
  // Measured and predicted of one node share the colour; every node has its own.
  EXPECT_EQ(panels[0].series[0].key, panels[0].series[1].key);
  EXPECT_EQ(panels[0].series[0].style, Series::Style::Points);
  EXPECT_EQ(panels[0].series[1].style, Series::Style::Line);
}

TEST(ThermalFigures, HeatMarksTheChosenAlpha) {
  const thermal::Network net = thermal::preset_network("spindle4");
  const thermal::Recording rec = small_recording(net);
  thermal::InverseProblem p;
  p.measured = rec.temp_c;
  p.measure_map = Eigen::MatrixXd::Zero(rec.temp_c.cols(), net.node_count());
  for (size_t m = 0; m < net.measurements.size(); ++m)
    p.measure_map(static_cast<Eigen::Index>(m), net.measurements[m].node) = 1;
  p.source_nodes = {net.node_index("rear_bearing"), net.node_index("front_bearing")};
  thermal::HeatInverseResult r;
  r.piece_start_s = {0, 9000, 18000};
  r.heat_w = Eigen::MatrixXd::Constant(3, 2, 40.0);
  r.fitted_c = Eigen::MatrixXd::Constant(static_cast<Eigen::Index>(rec.rows()), net.node_count(), 25.2);
  r.alpha = 4.2e-8;
  r.rule = "gcv";
  for (double e = -12; e <= 2; e += 1) r.scan.push_back({std::pow(10.0, e), 1, 1, 1, 1 + std::fabs(e + 7.4)});
  std::vector<std::string> cols;
  for (const auto& m : net.measurements) cols.push_back(m.column);
  const auto panels = heat_figure(net, rec, p, r, cols, "tikhonov1");
  expect_common_style(panels, net);
  const Plot& gcv = panels.back();
  ASSERT_EQ(gcv.markers.size(), 1u);
  EXPECT_DOUBLE_EQ(gcv.markers[0].x, r.alpha);
  EXPECT_NE(gcv.markers[0].label.find("4.2e-08"), std::string::npos);
  EXPECT_TRUE(gcv.log_x);
  const FigureLayout L = layout_figure(panels, network_figure_options(net));
  const double x = L.panels.back().marker_px[0];
  EXPECT_GT(x, L.panels.back().plot.x);
  EXPECT_LT(x, L.panels.back().plot.x + L.panels.back().plot.w);
  // The heat of the last piece is drawn until the recording ends.
  EXPECT_DOUBLE_EQ(panels[0].series[0].x.back(), rec.time_s.back() / 3600.0);
}

TEST(ThermalFigures, AnotherInputInTheSpeedColumnIsLabelledAsDeclared) {
  const auto net = thermal::preset_network("spindle4");
  thermal::Recording rec = small_recording(net);
  rec.meta.emplace_back("speed_rpm", "NOT a speed - heater power in W while heater_on, 0 while off");
  rec.meta.emplace_back("speed_rpm_quantity", "heater power (W)");
  const Plot p = recording_speed_panel(rec);
  EXPECT_EQ(p.y_label, "heater power (W)");
  EXPECT_EQ(p.title.rfind("heater power", 0), 0u) << p.title;
  EXPECT_EQ(p.y_label.find("speed"), std::string::npos);
  // The whole label is drawn: the panel is high enough for it.
  const FigureLayout L = layout_figure({p}, {});
  EXPECT_EQ(L.panels[0].y_label, "heater power (W)");
  // Words only: the words are the title, the axis claims no unit.
  rec.meta.pop_back();
  const Plot words = recording_speed_panel(rec);
  EXPECT_NE(words.title.find("heater power in W"), std::string::npos);
  EXPECT_EQ(words.y_label.find("(rpm)"), std::string::npos) << words.y_label;
  // A real spindle recording keeps its speed axis.
  EXPECT_EQ(recording_speed_panel(small_recording(net)).y_label, kSpeedAxis);
}

TEST(ThermalFigures, DeclaredEventsAreShadedOnEveryTimePanel) {
  // The incubator's lid openings (tests/data/incubator-dt): a declared 0/1 column. Its runs of 1s
  // are shaded on the measured, residual and input panels; the figures drew none before.
  const auto net = thermal::preset_network("spindle4");
  thermal::Recording rec = small_recording(net);
  rec.channels.push_back("lid_open");
  rec.temp_c.conservativeResize(Eigen::NoChange, rec.temp_c.cols() + 1);
  const Eigen::Index lid = rec.temp_c.cols() - 1;
  rec.temp_c.col(lid).setZero();
  for (int k = 10; k < 13; ++k) rec.temp_c(k, lid) = 1;  // 6000-7800 s
  rec.temp_c(49, lid) = 1;                             // open on the last row: up to the end
  rec.meta.emplace_back("event_columns", "lid_open");
  const std::vector<Span> spans = event_spans(rec);
  ASSERT_EQ(spans.size(), 2u);
  EXPECT_DOUBLE_EQ(spans[0].x0, 6000.0 / 3600);
  EXPECT_DOUBLE_EQ(spans[0].x1, 7800.0 / 3600);  // until the row after the last 1 (zero-order hold)
  EXPECT_EQ(spans[0].label, "lid_open = 1");
  EXPECT_DOUBLE_EQ(spans[1].x0, rec.time_s.back() / 3600);

  thermal::RecordingValidation v;
  v.predicted_c = Eigen::MatrixXd::Constant(static_cast<Eigen::Index>(rec.rows()), net.node_count(), 25.5);
  const auto panels = validation_figure(net, rec, v, "warmup.csv");
  for (const auto& p : panels) EXPECT_EQ(p.spans.size(), 2u) << p.title;
  const FigureLayout L = layout_figure(panels, network_figure_options(net));
  bool legend = false;
  for (const auto& e : L.panels[0].legend) legend |= e.shaded && e.text == "lid_open = 1";
  EXPECT_TRUE(legend);
  EXPECT_GT(L.panels[0].span_boxes[0].w, 0.0);
  // Undeclared, the same column is a plain column: nothing shaded.
  rec.meta.pop_back();
  EXPECT_TRUE(event_spans(rec).empty());
}
