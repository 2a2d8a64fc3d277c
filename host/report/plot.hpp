#pragma once
// Figures: panels stacked vertically, written as PNG (every sample drawn) and SVG (decimated until
// it fits FigureOptions::svg_max_bytes), drawn by one cairo routine in one style, so every plot the
// tool writes reads the same way:
//   - one colour per node (Series::key) in every panel of a figure, and in every figure whose
//     FigureOptions::key_order is the same (pass the network's node names); the module's channel
//     role names (rear_bearing, housing, ...) always have the same colour;
//   - measured data as small light dots, model curves as thin lines on top, an alternative model
//     dashed, so neither hides the other;
//   - the legend in a strip between the title and the plot box, wrapped to the canvas width (it
//     is never cut off and never covers data);
//   - x axes that end at the data; panels with the same x label share their x range;
//   - vertical markers (a chosen value, an event) drawn and labelled inside the plot box;
//   - shaded spans of the x axis (a declared event such as a lid open) under the data, with a
//     legend entry each;
//   - a linear x axis whose data begin just after 0 (a recording's first sample a few seconds in)
//     starts at 0, so the time the reader counts from carries its tick.
// plot_style.hpp has the helpers that build such series and panels (measured, model, speed panel,
// axis labels with units); plot_layout.hpp exposes where everything lands, for tests.
#include <cstddef>
#include <string>
#include <vector>

namespace btsm::report {

struct Series {
  // Legend text. For a node's series (key set) it says which kind of curve this is ("measured",
  // "model", "with effect"); the node's name comes from the key. Without a key it is the whole entry.
  std::string label;
  std::vector<double> x, y;  // NaN in y breaks the line (missing samples stay missing)
  enum class Style { Line, Points, Step, Dashed } style = Style::Line;
  // The node (or quantity) this series belongs to: it picks the colour, the same in every panel.
  // Empty = the label is the key.
  std::string key{};
};

// A vertical line across a panel at x, labelled at its top (a chosen parameter, an event).
struct Marker {
  double x = 0;
  std::string label;
};

// A shaded stretch [x0, x1] of the x axis across the whole panel height (the stretches a declared
// event column is 1: a lid open, a pump on), drawn under the data. Spans with the same label share
// one colour and one legend entry (the label, e.g. "lid_open = 1").
struct Span {
  double x0 = 0, x1 = 0;
  std::string label;
};

struct Plot {
  std::string title, x_label, y_label;  // labels carry their unit: "time (h)", "temperature (°C)"
  std::vector<Series> series;
  bool log_y = false;  // non-positive values are skipped on a log axis
  std::vector<Marker> markers{};
  double height_weight = 1.0;  // panel height as a multiple of FigureOptions::panel_height
  bool log_x = false;
  std::vector<Span> spans{};
};

struct FigureOptions {
  int width = 1000;                     // px
  int panel_height = 300;               // px, of a panel with height_weight 1
  std::vector<std::string> key_order;   // keys coloured in this order (a network's node names)
  std::size_t svg_max_bytes = 1000000;  // the SVG is decimated (coarser each try) until it fits
};

// Writes <stem>.png and <stem>.svg; throws std::runtime_error naming the file if it cannot.
void save_figure(const std::vector<Plot>& panels, const std::string& stem, const FigureOptions& options = {});

// Shorthands of save_figure with the default options but for the sizes.
void save_plot(const Plot& p, const std::string& stem, int width = 1000, int height = 420);
void save_panels(const std::vector<Plot>& panels, const std::string& stem, int width = 1000,
                 int panel_height = 300);

}  // namespace btsm::report
