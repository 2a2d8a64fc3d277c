#pragma once
// The style every figure of the tool shares: colours per node, axis labels with their units, and
// builders for the usual series and panels. A new plot gets the style by building its series
// with these helpers and saving with save_figure() (plot.hpp):
//
//   Plot temps{"Rear bearing: measured vs model", kTimeAxis, kTemperatureAxis, {}};
//   temps.series.push_back(measured("rear_bearing", t_h, meas));
//   temps.series.push_back(model("rear_bearing", t_h, pred));
//   FigureOptions o;
//   o.key_order = node_names;  // the network's node names: colours match every other figure
//   save_figure({temps, residual_panel, speed_panel(t_h, rpm)}, dir + "/my_plot", o);
#include "host/report/plot.hpp"

#include <map>
#include <string>
#include <vector>

namespace btsm::report {

// Axis labels: the quantity, then its unit in parentheses.
inline constexpr const char* kTimeAxis = "time (h)";
inline constexpr const char* kTemperatureAxis = "temperature (°C)";
inline constexpr const char* kResidualAxis = "measured − model (K)";
inline constexpr const char* kSpeedAxis = "speed (rpm)";
inline constexpr const char* kHeatAxis = "heat (W)";

struct Rgb {
  double r = 0, g = 0, b = 0;
  bool operator==(const Rgb& o) const { return r == o.r && g == o.g && b == o.b; }
};

// Colour of each key of a figure: the module's channel role names have fixed colours; the other
// keys take the free palette colours in `key_order` order, then in order of appearance.
std::map<std::string, Rgb> assign_colours(const std::vector<Plot>& panels, const std::vector<std::string>& key_order);
// The fixed colour of a channel role name (rear_bearing, ...) or of "speed"; false if none.
bool fixed_colour(const std::string& key, Rgb& out);
// Measured dots are drawn in this lighter tint of the node's colour, so the model line on top stays visible.
Rgb measured_tint(Rgb c);

// "rear_bearing" -> "rear bearing": what a legend shows for a key.
std::string display_name(const std::string& key);

// Seconds -> hours, for time axes.
std::vector<double> hours(const std::vector<double>& time_s);

// A node's measured samples (light dots), its model prediction (thin line), an alternative model
// (dashed), and a single trace per node (residual, heat; label empty: the legend shows the node).
Series measured(const std::string& node, std::vector<double> x, std::vector<double> y, std::string label = "measured");
Series model(const std::string& node, std::vector<double> x, std::vector<double> y, std::string label = "model");
Series alternative(const std::string& node, std::vector<double> x, std::vector<double> y, std::string label);
Series trace(const std::string& node, std::vector<double> x, std::vector<double> y,
             Series::Style style = Series::Style::Line);

// The spindle speed over time, a short panel under the temperatures.
Plot speed_panel(const std::vector<double>& t_h, const std::vector<double>& rpm, std::string title = "Spindle speed");

}  // namespace btsm::report
