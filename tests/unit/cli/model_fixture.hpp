#pragma once
// Model and recording files for the CLI tests: the spindle4 preset with its published values
// (Lo, Hu & Chang 2018, Tables 2/3) as a model JSON, and small synthetic recordings.
#include "host/thermal/network.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <functional>
#include <string>

namespace btsm::test {

// The model JSON `btsm fit` would write, with the preset's nominal values; `edit` may change
// parameter values before it is dumped.
inline std::string spindle4_model_json(const std::function<void(nlohmann::json& params)>& edit = {}) {
  const thermal::Network net = thermal::preset_network("spindle4");
  const Eigen::VectorXd p = thermal::default_parameters(net);
  nlohmann::json j;
  j["format"] = "btsm-thermal-model-1";
  j["network"] = thermal::network_to_json(net);
  for (int i = 0; i < net.param_count(); ++i) j["parameters"][net.params[static_cast<std::size_t>(i)].name] = p[i];
  if (edit) edit(j["parameters"]);
  // The channel map `fit` writes from module recordings (probe 5 on the shaft end): reduce takes
  // it; without one the preset's T4 (the shaft, as in the reference data) left the module with no
  // ambient channel, a model reduce now refuses.
  j["channel_map"] = nlohmann::json::array();
  const char* nodes[5] = {"rear_bearing", "housing", "front_bearing", "ambient", "shaft"};
  for (int ch = 1; ch <= 5; ++ch)
    j["channel_map"].push_back({{"channel", ch}, {"column", "T" + std::to_string(ch)}, {"module_role", nodes[ch - 1]},
                                {"node", nodes[ch - 1]}});
  return j.dump(2);
}

// A warm-up at 6000 rpm then cooling, rows every 10 s, T1..T4 rising exponentially towards
// 10/6/8/4 K; `cell` may replace the text of one cell (row, column index) or blank columns.
inline std::string recording_csv(int rows, const std::function<std::string(int row, int col, const std::string& text)>& cell = {}) {
  std::string s = "# source: test\ntime_s,speed_rpm,ambient_c,T1,T2,T3,T4\n";
  const double rise[4] = {10, 6, 8, 4};
  for (int k = 0; k < rows; ++k) {
    const double t = 10.0 * k;
    const bool on = k < rows / 2;
    char buf[64];
    std::string line;
    for (int c = 0; c < 7; ++c) {
      std::string text;
      if (c == 0) std::snprintf(buf, sizeof buf, "%g", t), text = buf;
      else if (c == 1) text = on ? "6000" : "0";
      else if (c == 2) text = "20.000";
      else {
        const double x = rise[c - 3] * (1.0 - std::exp(-t / 3000.0));
        std::snprintf(buf, sizeof buf, "%.4f", 20.0 + x);
        text = buf;
      }
      if (cell) text = cell(k, c, text);
      line += (c ? "," : "") + text;
    }
    s += line + "\n";
  }
  return s;
}

}  // namespace btsm::test
