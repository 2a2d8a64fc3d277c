#include "host/report/thermal_figures.hpp"

#include "host/report/plot_style.hpp"
#include "host/thermal/declared_columns.hpp"

#include <fmt/core.h>

#include <cmath>

namespace btsm::report {

FigureOptions network_figure_options(const thermal::Network& net) {
  FigureOptions o;
  for (const auto& n : net.nodes) o.key_order.push_back(n.name);
  return o;
}

Plot recording_speed_panel(const thermal::Recording& rec) {
  // A recording whose speed_rpm column carries another input (a heater's power) says what it is
  // in "# speed_rpm_quantity: NAME (UNIT)"; the panel is labelled with that, never as a speed.
  const std::string quantity = rec.meta_value("speed_rpm_quantity");
  const std::string declared = rec.meta_value("speed_rpm");
  if (quantity.empty() && declared.empty()) return speed_panel(hours(rec.time_s), rec.speed_rpm);
  if (quantity.empty()) {
    // Declared in words only: the words as the title (wrapped by the layout), no unit claimed.
    Plot p = speed_panel(hours(rec.time_s), rec.speed_rpm, "speed_rpm column: " + declared);
    p.y_label = "speed_rpm column";
    return p;
  }
  const std::string name = quantity.substr(0, quantity.find(" ("));
  Plot p = speed_panel(hours(rec.time_s), rec.speed_rpm, name + " (recorded in the speed_rpm column)");
  p.y_label = quantity;
  p.height_weight = 0.75;  // room for "NAME (UNIT)" along the axis (the layout shortens a label longer than the plot)
  return p;
}

std::vector<Span> event_spans(const thermal::Recording& rec) {
  std::vector<Span> out;
  for (const auto& column : thermal::event_columns(rec)) {
    const int c = rec.channel_index(column);
    if (c < 0) continue;
    const std::size_t n = rec.rows();
    for (std::size_t k = 0; k < n;) {
      if (rec.temp_c(static_cast<Eigen::Index>(k), c) != 1.0) {
        ++k;
        continue;
      }
      std::size_t end = k;
      while (end < n && rec.temp_c(static_cast<Eigen::Index>(end), c) == 1.0) ++end;
      const double t1 = end < n ? rec.time_s[end] : rec.time_s[n - 1];
      out.push_back(Span{rec.time_s[k] / 3600.0, t1 / 3600.0, column + " = 1"});
      k = end;
    }
  }
  return out;
}

void add_event_spans(std::vector<Plot>& panels, const thermal::Recording& rec) {
  const std::vector<Span> spans = event_spans(rec);
  if (spans.empty()) return;
  for (auto& p : panels)
    if (p.x_label == kTimeAxis) p.spans.insert(p.spans.end(), spans.begin(), spans.end());
}

std::vector<Plot> validation_figure(const thermal::Network& net, const thermal::Recording& rec,
                                    const thermal::RecordingValidation& v, const std::string& title) {
  const std::vector<double> t_h = hours(rec.time_s);
  Plot temps{title + ": measured vs model", kTimeAxis, kTemperatureAxis, {}};
  Plot resid{"Residual (measured − model)", kTimeAxis, kResidualAxis, {}};
  for (const auto& m : net.measurements) {
    const int col = rec.channel_index(m.column);
    if (col < 0) continue;
    const std::string& node = net.nodes[static_cast<size_t>(m.node)].name;
    std::vector<double> meas(rec.rows()), pred(rec.rows()), res(rec.rows());
    for (size_t k = 0; k < rec.rows(); ++k) {
      meas[k] = rec.temp_c(static_cast<Eigen::Index>(k), col);
      pred[k] = v.predicted_c(static_cast<Eigen::Index>(k), m.node);
      res[k] = meas[k] - pred[k];  // NaN where the sample is missing
    }
    temps.series.push_back(measured(node, t_h, meas));
    temps.series.push_back(model(node, t_h, pred));
    resid.series.push_back(trace(node, t_h, res));
  }
  std::vector<Plot> panels{temps, resid, recording_speed_panel(rec)};
  add_event_spans(panels, rec);
  return panels;
}

namespace {

// The node a measured row of the problem selects (its largest weight).
std::string measured_node(const thermal::Network& net, const thermal::InverseProblem& p, int row,
                          const std::string& column) {
  Eigen::Index best = 0;
  p.measure_map.row(row).cwiseAbs().maxCoeff(&best);
  return best < static_cast<Eigen::Index>(net.nodes.size()) ? net.nodes[static_cast<size_t>(best)].name : column;
}

}  // namespace

std::vector<Plot> heat_figure(const thermal::Network& net, const thermal::Recording& rec,
                              const thermal::InverseProblem& p, const thermal::HeatInverseResult& r,
                              const std::vector<std::string>& columns, const std::string& method) {
  std::vector<Plot> panels;
  Plot src{fmt::format("Estimated heat per source node ({}, α chosen by {})", method, r.rule), kTimeAxis, kHeatAxis, {}};
  for (size_t j = 0; j < p.source_nodes.size(); ++j) {
    std::vector<double> t, q;
    for (Eigen::Index i = 0; i < r.heat_w.rows(); ++i) {
      t.push_back(r.piece_start_s[static_cast<size_t>(i)] / 3600.0);
      q.push_back(r.heat_w(i, static_cast<Eigen::Index>(j)));
    }
    // The last piece holds until the end of the recording.
    if (!t.empty() && !rec.time_s.empty()) t.push_back(rec.time_s.back() / 3600.0), q.push_back(q.back());
    src.series.push_back(trace(net.nodes[static_cast<size_t>(p.source_nodes[j])].name, t, q, Series::Style::Step));
  }
  panels.push_back(src);

  const std::vector<double> t_h = hours(rec.time_s);
  Plot temps{"Measured vs fitted temperatures", kTimeAxis, kTemperatureAxis, {}};
  Plot res{"Residual (measured − fitted)", kTimeAxis, "measured − fitted (K)", {}};
  for (Eigen::Index c = 0; c < p.measured.cols(); ++c) {
    const std::string node = measured_node(net, p, static_cast<int>(c), columns[static_cast<size_t>(c)]);
    const Eigen::VectorXd fitted = r.fitted_c * p.measure_map.row(c).transpose();
    std::vector<double> meas(rec.rows()), fit(rec.rows()), e(rec.rows());
    for (size_t k = 0; k < rec.rows(); ++k) {
      meas[k] = p.measured(static_cast<Eigen::Index>(k), c);
      fit[k] = fitted(static_cast<Eigen::Index>(k));
      e[k] = meas[k] - fit[k];
    }
    temps.series.push_back(measured(node, t_h, meas));
    temps.series.push_back(model(node, t_h, fit, "fitted"));
    res.series.push_back(trace(node, t_h, e));
  }
  panels.push_back(temps);
  panels.push_back(res);
  panels.push_back(recording_speed_panel(rec));
  add_event_spans(panels, rec);

  if (!r.scan.empty()) {
    Plot scan{"GCV over the regularisation parameter α", "α (K²/W²)", "GCV (K²)", {}};
    scan.log_x = scan.log_y = true;
    std::vector<double> a, g;
    for (const auto& s : r.scan) a.push_back(s.alpha), g.push_back(s.gcv);
    scan.series.push_back(Series{"GCV", a, g, Series::Style::Line});
    scan.markers.push_back(Marker{r.alpha, fmt::format("chosen α = {:.3g} ({})", r.alpha, r.rule)});
    scan.height_weight = 0.8;
    panels.push_back(scan);
  }
  return panels;
}

}  // namespace btsm::report
