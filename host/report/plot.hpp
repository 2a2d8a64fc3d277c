#pragma once
// Line plots written as PNG (for the HTML report and a quick look) and SVG (for papers), drawn by
// one cairo routine so the two files always show the same thing.
#include <string>
#include <vector>

namespace btsm::report {

struct Series {
  std::string label;
  std::vector<double> x, y;  // NaN in y breaks the line (missing samples stay missing)
  enum class Style { Line, Points, Step } style = Style::Line;
};

struct Plot {
  std::string title, x_label, y_label;
  std::vector<Series> series;
  bool log_y = false;  // non-positive values are skipped on a log axis
};

// Writes <stem>.png and <stem>.svg; throws std::runtime_error naming the file if it cannot.
void save_plot(const Plot& p, const std::string& stem, int width = 960, int height = 540);

// Panels are stacked vertically and share only the width (each has its own axes).
void save_panels(const std::vector<Plot>& panels, const std::string& stem, int width = 960,
                 int panel_height = 300);

}  // namespace btsm::report
