// btsm fit | validate | reduce
#include "cli_support.hpp"
#include "commands.hpp"

#include "common/model_blob.hpp"
#include "host/io/output_file.hpp"
#include "host/io/utf8_text.hpp"
#include "host/thermal/column_map.hpp"
#include "host/thermal/detector_calibration.hpp"
#include "host/thermal/fit.hpp"
#include "host/thermal/model_file.hpp"
#include "host/thermal/recording_metadata.hpp"
#include "host/thermal/reduce.hpp"
#include "host/thermal/speed_coverage.hpp"
#include "host/thermal/time_constant_text.hpp"
#include "host/thermal/validate.hpp"
#include "host/report/thermal_figures.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <set>
#include <sstream>

namespace btsm::cli {
namespace {

using namespace btsm::thermal;
using nlohmann::json;

std::vector<Recording> read_all(const std::vector<std::string>& files) {
  std::vector<Recording> recs;
  for (const auto& f : files) {
    std::cerr << "reading " << io::printable(f) << "\n";  // a file name a glob brought in may hold an ESC
    try {
      recs.push_back(read_recording_csv(f));
    } catch (const std::exception& e) {
      throw CommandError(kExitUsage, e.what());
    }
    for (const std::string& w : reading_warnings(recs.back())) std::cerr << "WARNING: " << io::printable(w) << "\n";
  }
  return recs;
}

// ------------------------------------------------------------------------------------- fit
struct FitArgs {
  std::vector<std::string> recordings;
  std::string preset, network, out, initial = "estimate";
  std::vector<std::string> columns;
  double sum_c = std::nan("");
  bool json_out = false, joint_only = false;
  int iterations = FitOptions{}.max_iterations;
};

void run_fit(const FitArgs& a) {
  {
    std::vector<std::string> inputs = a.recordings;
    if (!a.network.empty()) inputs.push_back(a.network);
    io::refuse_output_over_input(a.out, "--out", inputs);
    io::refuse_output_file_that_cannot_be_made(a.out, "--out", "model JSON");  // before the fit, not after
  }
  Network net;
  try {
    if (!a.preset.empty() == !a.network.empty()) throw CommandError(kExitUsage, "give exactly one of --preset or --network");
    net = a.preset.empty() ? load_network(a.network) : preset_network(a.preset);
  } catch (const CommandError&) {
    throw;
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  const auto recs = read_all(a.recordings);
  try {
    refuse_repeated_recordings(recs);
    const std::string said = map_measurements(net, recs, a.columns);
    if (!said.empty()) std::cerr << "fit: from the recordings' channel roles:" << said << given_columns(a.columns) << "\n";
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  FitOptions o;
  o.sum_capacitance_J_per_K = a.sum_c;
  o.initial_state = a.initial == "first" ? InitialState::FirstSamples : InitialState::Estimate;
  o.staged = !a.joint_only;
  o.max_iterations = a.iterations;
  o.progress = [](const std::string& s) { std::cerr << "fit: " << s << "\n"; };
  FitResult fit;
  try {
    fit = fit_network(net, recs, o);
  } catch (const std::invalid_argument& e) {
    throw CommandError(kExitUsage, e.what());
  }
  if (!fit.unusable.empty())
    throw CommandError(kExitFailure, "the fit gave no usable model, none written: " + fit.unusable);
  const json model = model_to_json(net, fit, recs);
  save_json(a.out, model);
  std::cerr << fmt::format("fit: {} ({}), rms {:.5f} K over {} residuals, {:.2f} s; wrote {}\n",
                           fit.converged ? "converged" : "NOT converged", fit.gauge, fit.rms_K, fit.residual_count,
                           fit.seconds, a.out);
  if (a.json_out) {
    print_json(model);
  } else {
    std::cout << fmt::format("{:<8} {:>14} {:>12} {:>8}  {:<10} {}\n", "name", "value", "1 sigma", "rel %", "unit", "status");
    for (const auto& e : fit.estimates) {
      // The notes are joined with "; " each: without the last one "(correlation ...; )" reads as a cut.
      std::string note = e.note;
      while (!note.empty() && (note.back() == ' ' || note.back() == ';')) note.pop_back();
      std::cout << fmt::format("{:<8} {:>14.6g} {:>12.3g} {:>8.3g}  {:<10} {}{}\n", e.name, e.value, e.sigma,
                               e.value != 0 ? 100 * e.sigma / std::abs(e.value) : 0.0, e.unit, identifiability_name(e.status),
                               note.empty() ? "" : "  (" + note + ")");
    }
    std::cout << "gauge: " << fit.gauge << "\n";
    for (const auto& w : fit.warnings) std::cout << "warning: " << w << "\n";
  }
  if (!fit.converged)
    throw CommandError(kExitFailure, fmt::format("the fit did not converge within {} iterations of its final stage (see "
                                                 "warnings; --iterations raises the limit)", a.iterations));
}

// ------------------------------------------------------------------------------------- validate
// The paper's A7 index, the opposite of the usual "normalised MSE" (0 = perfect): said wherever it is printed.
constexpr const char* kNmseConvention =
    "NMSE = 1 - sum(e^2) / sum((y - mean y)^2) (paper A7): 1 = perfect, 0 = no better than the mean, < 0 worse";

struct ValidateArgs {
  std::string model;
  std::vector<std::string> recordings;
  std::string plots;
  bool json_out = false;
  std::size_t initial_rows = 120;
};

// The plots' names in `dir` (without .png/.svg), one per recording: validate_<recording's stem>.
// Two recordings of one name in different folders (A/check.csv, B/check.csv) wrote one plot over
// the other (probe 5); the second gets "_2".
std::vector<std::string> plot_stems(const std::vector<std::string>& recordings, const std::string& dir) {
  std::vector<std::string> stems;
  std::set<std::string> used;
  for (const auto& r : recordings) {
    const std::string base = (std::filesystem::path(dir) / ("validate_" + std::filesystem::path(r).stem().string())).string();
    std::string stem = base;
    for (int n = 2; used.count(stem) > 0; ++n) stem = base + "_" + std::to_string(n);
    used.insert(stem);
    stems.push_back(stem);
  }
  return stems;
}

// Checked before the recordings are read: a --plots that cannot take the plots failed after the
// metrics (a raw "filesystem error" for a file given as --plots), and a plot name that is a named
// pipe blocked for ever.
void refuse_plots_dir_that_cannot_be_made(const ValidateArgs& a) {
  std::vector<io::OutputName> files;
  for (const auto& stem : plot_stems(a.recordings, a.plots))
    for (const char* ext : {".png", ".svg"}) files.push_back({std::filesystem::path(stem + ext).filename().string(), "plot"});
  io::refuse_output_dir_that_cannot_be_made(a.plots, "--plots", files);
}

void plot_validation(const Network& net, const Recording& rec, const RecordingValidation& v, const std::string& dir,
                     const std::string& stem) {
  namespace rp = btsm::report;
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw CommandError(kExitFailure, "cannot create --plots directory " + dir + ": " + ec.message());
  rp::save_figure(rp::validation_figure(net, rec, v, std::filesystem::path(rec.source).filename().string()), stem,
                  rp::network_figure_options(net));
  std::cerr << "validate: wrote " << stem << ".png/.svg\n";
}

json metrics_json(const ErrorMetrics& m) {
  auto num = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  return {{"nmse", num(m.nmse)}, {"rmse_K", num(m.rmse_K)}, {"max_abs_K", num(m.max_abs_K)}, {"samples", m.count}};
}

void run_validate(const ValidateArgs& a) {
  if (!a.plots.empty()) refuse_plots_dir_that_cannot_be_made(a);
  FittedModel model;
  try {
    model = load_model(a.model);
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  const auto recs = read_all(a.recordings);
  const Network& net = model.network;
  try {
    check_mapping_agrees_with_roles(net, model.channel_map, recs, {}, "refit the model with this recording, or correct its channel_roles line");
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  ValidateOptions o;
  o.initial_rows = a.initial_rows;
  json out;
  out["model"] = a.model;
  out["recordings"] = json::array();
  json nmse, rmse, maxabs;
  double worst_mape = 0;
  // The initial state comes from the first --initial-rows rows; a recording that is no longer
  // would be scored on the very rows its start was fitted to (NMSE ~1 on anything).
  for (const auto& rec : recs)
    if (rec.rows() <= a.initial_rows)
      throw CommandError(kExitUsage, fmt::format("{}: {} rows, not more than --initial-rows {}: the initial state would be "
                                                 "estimated from the rows it is scored on; give a longer recording or a "
                                                 "smaller --initial-rows",
                                                 rec.source, rec.rows(), a.initial_rows));
  for (const auto& rec : recs)
    if (4 * a.initial_rows > rec.rows())
      std::cerr << fmt::format("validate: WARNING: {}: the initial state comes from {} of its {} rows: most of the score is on "
                               "rows it was fitted to\n",
                               io::printable(rec.source), a.initial_rows, rec.rows());
  for (const auto& rec : recs)
    for (const auto& w : unsampled_measurement_warnings(net, rec, "its node is not scored"))
      std::cerr << "validate: WARNING: " << io::printable(w) << "\n";
  if (!a.json_out) std::cout << kNmseConvention << "\n";
  const std::vector<std::string> stems = plot_stems(a.recordings, a.plots);
  for (std::size_t i = 0; i < recs.size(); ++i) {
    const Recording& rec = recs[i];
    RecordingValidation v;
    try {
      v = validate_recording(net, model.params, rec, o);
    } catch (const std::invalid_argument& e) {
      throw CommandError(kExitUsage, e.what());
    }
    json rj;
    rj["file"] = rec.source;
    rj["initial_state_c"] = std::vector<double>(v.initial_state_c.data(), v.initial_state_c.data() + v.initial_state_c.size());
    std::cout << (a.json_out ? "" : fmt::format("{}\n  {:<6} {:>10} {:>10} {:>10} | {:>10} {:>10} | {:>10} {:>10}\n", rec.source, "column",
                                                "NMSE", "RMSE K", "max K", "op NMSE", "op max K", "cool NMSE", "cool max K"));
    for (std::size_t m = 0; m < net.measurements.size(); ++m) {
      const std::string col = net.measurements[m].column;
      rj["nodes"][col] = {{"all", metrics_json(v.all[m])}, {"operating", metrics_json(v.operating[m])}, {"cooling", metrics_json(v.cooling[m])}};
      auto worst = [](json& j, const std::string& k, double val, bool min) {
        if (!std::isfinite(val)) return;
        if (!j.contains(k) || (min ? val < j[k].get<double>() : val > j[k].get<double>())) j[k] = val;
      };
      worst(nmse, col, v.all[m].nmse, true);
      worst(rmse, col, v.all[m].rmse_K, false);
      worst(maxabs, col, v.all[m].max_abs_K, false);
      // A mode the recording does not contain (no cooling phase, say) has no figure: "--", not "nan".
      auto cell = [](double x, int decimals) { return std::isfinite(x) ? fmt::format("{:.{}f}", x, decimals) : std::string("--"); };
      if (!a.json_out)
        std::cout << fmt::format("  {:<6} {:>10} {:>10} {:>10} | {:>10} {:>10} | {:>10} {:>10}  {}\n", col, cell(v.all[m].nmse, 6),
                                 cell(v.all[m].rmse_K, 5), cell(v.all[m].max_abs_K, 5), cell(v.operating[m].nmse, 6),
                                 cell(v.operating[m].max_abs_K, 5), cell(v.cooling[m].nmse, 6), cell(v.cooling[m].max_abs_K, 5),
                                 net.nodes[static_cast<std::size_t>(net.measurements[m].node)].name);
    }
    rj["steady_states"] = json::array();
    for (const auto& sp : v.steady) {
      json sj{{"speed_rpm", sp.speed_rpm}, {"stop_time_s", sp.stop_time_s}, {"mape_percent", sp.mape_percent}};
      for (std::size_t m = 0; m < net.measurements.size(); ++m) {
        const auto mi = static_cast<Eigen::Index>(m);
        sj["nodes"][net.measurements[m].column] = {{"measured_rise_K", sp.measured_rise_K[mi]}, {"predicted_rise_K", sp.predicted_rise_K[mi]},
                                                   {"ape_percent", sp.ape_percent[mi]}};
      }
      worst_mape = std::max(worst_mape, sp.mape_percent);
      rj["steady_states"].push_back(sj);
      if (!a.json_out) std::cout << fmt::format("  steady state at {:.0f} rpm: MAPE {:.4f} %\n", sp.speed_rpm, sp.mape_percent);
    }
    if (v.steady.empty() && !a.json_out) {  // say why there is no MAPE rather than leave it out
      if (v.longest_phase_s > 0)
        std::cout << fmt::format("  steady state: -- (the longest run at one speed before a stop, {:.1f} h at {:.0f} rpm, lasts {:.1f} "
                                 "of the model's slowest time constants; a steady state needs {:g})\n",
                                 v.longest_phase_s / 3600, v.longest_phase_rpm, v.longest_phase_time_constants, o.settled_time_constants);
      else
        std::cout << "  steady state: -- (no run at one speed that ends in a stop)\n";
    }
    out["recordings"].push_back(rj);
    if (!a.plots.empty()) plot_validation(net, rec, v, a.plots, stems[i]);
  }
  out["nmse"] = nmse;
  out["rmse_K"] = rmse;
  out["max_abs_K"] = maxabs;
  out["steady_mape_max_percent"] = worst_mape;
  out["summary_note"] = "nmse/rmse_K/max_abs_K: worst value per node over the recordings";
  out["nmse_convention"] = kNmseConvention;
  if (a.json_out) print_json(out);
}

// ------------------------------------------------------------------------------------- reduce
struct ReduceArgs {
  std::string model, speeds, out, blob, channels, stop_phases = "600,2400";
  std::vector<std::string> calibrate;
  double dt = 5.0, cooling_ref = 0.0, design_heat_w = 10.0;
  ChannelDetector detector;
  DetectorRule rule;
  bool force = false, json_out = false, no_carriers = false;
};

// The channel map: from the fit's "channel_map" (what the recordings' channel roles and columns
// said), or `--channels` (five entries: node name, 'ambient' or 'none'), or -- for a model JSON
// without a map -- columns T1..T5 as channels 1..5 with the ambient on channel 4. Returns a line
// per channel for the console.
// The blob's refusal with the channel it is about and that channel's detector, so a user sees which
// value is beyond its field ("limit out of range" alone named nothing).
std::string blob_problem(const ScheduledReduction& r) {
  std::string text = model_status_name(r.quantize_status.status);
  const uint8_t ch = r.quantize_status.channel;
  if (ch < 5) {
    const ChannelDetector& d = r.model.detector[ch];
    text += fmt::format(" -- ch{}: drift {:.4g} K, lower drift {:.4g} K, WARN {:.4g} K min, ALARM {:.4g} K min, lower WARN {:.4g} K min, "
                        "limit {:.4g} degC, rise {:.4g} K/min",
                        ch + 1, d.drift_K, d.low_drift_K, d.warn_evidence_K_min, d.alarm_evidence_K_min, d.low_warn_evidence_K_min,
                        d.abs_limit_c, d.max_rise_K_per_min);
  } else if (r.quantize_status.breakpoint != 0xFF) {
    text += fmt::format(" -- breakpoint {}", r.quantize_status.breakpoint);
  }
  return text;
}

std::vector<std::string> channel_map(const Network& net, const json& model_json, const std::string& spec, ReduceOptions& o) {
  std::vector<std::string> recorded_role(5);
  o.ambient_channel = -1;
  o.channel_node.fill(-1);
  const bool have_map = model_json.contains("channel_map") && model_json.at("channel_map").is_array() &&
                        !model_json.at("channel_map").empty();
  if (have_map)
    for (const auto& e : model_json.at("channel_map")) {
      const int ch = e.value("channel", 0);
      if (ch < 1 || ch > 5) throw CommandError(kExitUsage, "model JSON: channel_map entry with channel " + std::to_string(ch));
      if (e.contains("module_role") && e.at("module_role").is_string()) recorded_role[static_cast<std::size_t>(ch - 1)] = e.at("module_role");
    }
  if (!spec.empty()) {
    std::stringstream ss(spec);
    std::string tok;
    int ch = 0;
    while (std::getline(ss, tok, ',')) {
      if (ch >= 5) throw CommandError(kExitUsage, "--channels: at most 5 entries");
      if (tok == "ambient") {
        if (o.ambient_channel >= 0) throw CommandError(kExitUsage, "--channels: only one ambient channel");
        o.ambient_channel = ch;
      } else if (tok != "none") {
        const int node = net.node_index(tok);
        if (node < 0) {
          std::string nodes;
          for (const auto& n : net.nodes) nodes += " " + n.name;
          throw CommandError(kExitUsage, "--channels: '" + tok + "' (channel " + std::to_string(ch + 1) +
                                             ") is not a node of the model, 'ambient' or 'none'; nodes:" + nodes);
        }
        for (int k = 0; k < ch; ++k)
          if (o.channel_node[static_cast<std::size_t>(k)] == node)
            throw CommandError(kExitUsage, "--channels: node '" + tok + "' on channel " + std::to_string(k + 1) + " and channel " +
                                               std::to_string(ch + 1) + ": one probe per node");
        o.channel_node[static_cast<std::size_t>(ch)] = node;
      }
      ++ch;
    }
    // "rear_bearing,housing" left ch3..ch5 silently unmodelled: say all five
    if (ch != 5 || (!spec.empty() && spec.back() == ','))
      throw CommandError(kExitUsage, "--channels '" + spec + "': give all five channels ch1..ch5 (a node, ambient or none each)");
  } else if (have_map) {
    // `btsm fit` writes one entry per channel and one ambient; a hand-edited map that says more
    // would be resolved by its last entry (two ambients made the spare probe the ambient).
    std::array<bool, 5> listed{};
    for (const auto& e : model_json.at("channel_map")) {
      const int ch = e.at("channel").get<int>() - 1;
      if (listed[static_cast<std::size_t>(ch)])
        throw CommandError(kExitUsage, "model JSON: channel_map lists channel " + std::to_string(ch + 1) + " twice");
      listed[static_cast<std::size_t>(ch)] = true;
      if (!e.contains("node") || !e.at("node").is_string()) continue;
      const std::string node = e.at("node");
      if (node == "ambient") {
        if (o.ambient_channel >= 0)
          throw CommandError(kExitUsage, "model JSON: channel_map names two ambient channels (" + std::to_string(o.ambient_channel + 1) +
                                             " and " + std::to_string(ch + 1) + "); say which with --channels");
        o.ambient_channel = ch;
      } else {
        const int n = net.node_index(node);
        if (n < 0) throw CommandError(kExitUsage, "model JSON: channel_map names node '" + node + "', not in the network");
        // Refused as --channels refuses it: the blob would check the second probe against this
        // node's model (a hand-edited ch5 = rear_bearing ALARMed on the spare probe's readings).
        for (int k = 0; k < 5; ++k)
          if (o.channel_node[static_cast<std::size_t>(k)] == n)
            throw CommandError(kExitUsage, "model JSON: channel_map puts node '" + node + "' on channel " + std::to_string(std::min(k, ch) + 1) +
                                               " and channel " + std::to_string(std::max(k, ch) + 1) +
                                               ": one probe per node; say which with --channels");
        o.channel_node[static_cast<std::size_t>(ch)] = n;
      }
    }
  } else {
    std::cerr << "reduce: the model JSON has no channel map (fitted before btsm recorded one): channels 1..5 = columns "
                 "T1..T5 as the network measures them, ambient on channel 4 -- check the lines below or say --channels\n";
    for (const auto& m : net.measurements)
      if (m.column.size() == 2 && m.column[0] == 'T' && m.column[1] >= '1' && m.column[1] <= '5')
        o.channel_node[static_cast<std::size_t>(m.column[1] - '1')] = m.node;
    if (o.channel_node[3] < 0) o.ambient_channel = 3;
  }
  std::vector<std::string> lines;
  for (int ch = 0; ch < 5; ++ch) {
    const auto c = static_cast<std::size_t>(ch);
    const int nd = o.channel_node[c];
    std::string what = nd >= 0 ? net.nodes[static_cast<std::size_t>(nd)].name : (ch == o.ambient_channel ? "ambient" : "(none)");
    std::string line = fmt::format("ch{} = T{} {}", ch + 1, ch + 1, what);
    if (!recorded_role[c].empty()) line += " (module role when recorded: " + recorded_role[c] + ")";
    if (nd >= 0 && role_for_node(net.nodes[static_cast<std::size_t>(nd)].name) == kModelRoleUnchecked)
      line += " (no module role has this name: the module cannot check the probe's place)";
    lines.push_back(line);
  }
  return lines;
}

void run_reduce(const ReduceArgs& a, const std::vector<std::string>& explicit_detector) {
  {
    // "./out/../out/r.json" as --blob wrote the blob over the reduced JSON (probe 5)
    if (io::same_output_file(a.blob, a.out)) throw CommandError(kExitUsage, "--blob and --out name the same file " + a.out);
    std::vector<std::string> inputs = a.calibrate;
    inputs.push_back(a.model);
    io::refuse_output_over_input(a.out, "--out", inputs);
    inputs.push_back(a.out);
    io::refuse_output_over_input(a.blob, "--blob", inputs);
    // before the reduction, not after it (and a bad --blob after --out had been replaced)
    io::refuse_output_file_that_cannot_be_made(a.out, "--out", "reduced model JSON");
    io::refuse_output_file_that_cannot_be_made(a.blob, "--blob", "model blob");
  }
  FittedModel model;
  try {
    model = load_model(a.model);
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  const Network& net = model.network;
  ReduceOptions o;
  o.progress = [](const std::string& s) { std::cerr << "reduce: " << s << "\n"; };
  o.speeds_rpm = number_list(a.speeds, "--speeds");
  // Checked before anything else is printed (the reduction checks them again).
  if (o.speeds_rpm.empty() || o.speeds_rpm.size() > kModelMaxBreakpoints - 1u)
    throw CommandError(kExitUsage, fmt::format("--speeds: 1 to {} running breakpoints", kModelMaxBreakpoints - 1));
  for (std::size_t i = 0; i < o.speeds_rpm.size(); ++i)
    if (!(o.speeds_rpm[i] > 0) || o.speeds_rpm[i] > 65534 || (i > 0 && !(o.speeds_rpm[i] > o.speeds_rpm[i - 1])))
      throw CommandError(kExitUsage, "--speeds: '" + a.speeds + "': each in 1..65534 rpm, strictly ascending");
  std::vector<std::string> map_lines;
  try {
    map_lines = channel_map(net, model.json, a.channels, o);
  } catch (const json::exception& e) {  // an entry of the wrong shape ("channel": "1", a bare number)
    throw CommandError(kExitUsage, a.model + ": channel_map: each entry must be an object with a number 'channel' "
                                             "and a string 'node' (" + std::string(e.what()) + ")");
  }
  const std::vector<double> ends = number_list(a.stop_phases, "--stop-phases");
  if (ends.size() > kModelEarlyStopPhases) throw CommandError(kExitUsage, "--stop-phases: at most 2 phase ends");
  o.stop_phase_end_s.fill(0.0);
  for (std::size_t k = 0; k < ends.size(); ++k) o.stop_phase_end_s[k] = ends[k];
  o.dt_s = a.dt;
  o.carriers = !a.no_carriers;
  o.cooling_reference_rpm = a.cooling_ref;
  o.detector = a.detector;
  o.design_heat_w = a.design_heat_w;
  if (!(a.design_heat_w > 0)) throw CommandError(kExitUsage, "--design-heat must be > 0 W");
  // The calibration recordings first: the duty cycle the detector covers runs up to their top speed.
  std::vector<Recording> calib;
  if (!a.calibrate.empty()) {
    calib = read_all(a.calibrate);
    // The bands are set from each channel's column: a recording whose roles put the probes elsewhere
    // than the model measures them calibrated each channel on another probe (validate and heat refuse it).
    if (a.channels.empty()) {
      try {
        check_mapping_agrees_with_roles(net, model.channel_map, calib, {}, "calibrate on recordings made with the probes where the model was fitted");
      } catch (const std::invalid_argument& e) {
        throw CommandError(kExitUsage, e.what());
      }
    }
    double top = 0;
    for (const auto& rec : calib)
      for (double v : rec.speed_rpm) top = std::max(top, v);
    o.duty_max_rpm = top;
  }
  const ChannelDetector& d = a.detector;
  if (!a.calibrate.empty() && !explicit_detector.empty())
    throw CommandError(kExitUsage, "--calibrate-bands sets " + explicit_detector.front() + " from the recordings: give one or the other");
  if (!(d.drift_K > 0) || !(d.low_drift_K > 0) || !(d.warn_evidence_K_min > 0) ||
      !(d.alarm_evidence_K_min > d.warn_evidence_K_min) || d.low_warn_evidence_K_min < 0)
    throw CommandError(kExitUsage,
                       "detector: need --drift > 0, --low-drift > 0, 0 < --warn-evidence < --alarm-evidence, --low-warn-evidence >= 0");
  std::cerr << "reduce: " << o.speeds_rpm.size() << " speeds, channel map:\n";
  for (const auto& l : map_lines) std::cerr << "  " << l << "\n";
  // Probe 5 (P1): this was a warning; the model then flashed, the module showed NORMAL on every
  // sample and a 30 W bearing fault never ALARMed. A model that predicts nothing is no model.
  if (o.ambient_channel < 0)
    throw CommandError(kExitUsage, std::string("no channel is the ambient (") +
                                       (a.channels.empty() ? "the model's channel_map" : "--channels '" + a.channels + "'") +
                                       "): the module predicts every channel relative to its ambient channel and would "
                                       "predict nothing, so no fault would ever be flagged; say which channel reads the room "
                                       "air with --channels ...,ambient,...");
  ScheduledReduction r;
  try {
    r = build_scheduled_model(net, model.params, o);
  } catch (const std::invalid_argument& e) {
    throw CommandError(kExitUsage, e.what());
  }
  if (!r.quantize_status.ok())
    throw CommandError(kExitFailure, std::string("the model does not fit the module's blob: ") + blob_problem(r));
  json calibration;
  if (!a.calibrate.empty()) {
    std::vector<const Recording*> ptrs;
    for (const auto& rec : calib) ptrs.push_back(&rec);
    std::array<std::string, kModelChannels> columns;
    for (int ch = 0; ch < 5; ++ch)
      if (o.channel_node[static_cast<std::size_t>(ch)] >= 0) columns[static_cast<std::size_t>(ch)] = "T" + std::to_string(ch + 1);
    DetectorCalibration cal;
    try {
      cal = calibrate_detector(r, ptrs, columns, a.rule);
    } catch (const std::invalid_argument& e) {
      throw CommandError(kExitUsage, e.what());
    }
    apply_calibration(cal, r.model);
    // The drifts also cover the model's steady error at every speed up to the calibration's top
    // (the speed-coverage rule below: within its share of the drift): with carriers the drifts
    // shrink to the transients' error, and a steady interpolation error between breakpoints may
    // be larger (evidence thresholds stay valid: a larger drift only lowers the worst evidence).
    {
      requantize(r);
      SpeedCoverageOptions co;
      co.top_rpm = o.duty_max_rpm;
      const SpeedCoverage cover = check_speed_coverage(net, model.params, r, co);
      for (int ch = 0; ch < 5; ++ch) {
        const auto c = static_cast<std::size_t>(ch);
        if (!cal.channels[c].diagnosed || cover.error_K[c].empty()) continue;
        double above = 0, below = 0;
        for (double e : cover.error_K[c]) above = std::max(above, e), below = std::max(below, -e);
        ChannelDetector& dd = r.model.detector[ch];
        const double up = std::ceil(above / cover.drift_fraction / 0.05) * 0.05, down = std::ceil(below / cover.drift_fraction / 0.05) * 0.05;
        std::string raised;  // only the side that moved
        if (up > dd.drift_K + 1e-6) raised += fmt::format("{:.2f} -> {:.2f} K above", dd.drift_K, up);
        if (down > dd.low_drift_K + 1e-6) raised += fmt::format("{}{:.2f} -> {:.2f} K below", raised.empty() ? "" : ", ", dd.low_drift_K, down);
        if (!raised.empty())
          std::cerr << fmt::format("reduce: ch{} drift raised to the steady error at every speed: {}\n", ch + 1, raised);
        dd.drift_K = std::max(dd.drift_K, up);
        dd.low_drift_K = std::max(dd.low_drift_K, down);
        cal.channels[c].detector.drift_K = dd.drift_K;
        cal.channels[c].detector.low_drift_K = dd.low_drift_K;
      }
    }
    requantize(r);
    if (!r.quantize_status.ok())
      throw CommandError(kExitFailure, std::string("the calibrated detector does not fit the blob: ") + blob_problem(r) +
                                           " (a calibration recording above the top breakpoint, or a --design-heat too small to "
                                           "rise above the model's own error, asks for bands beyond the blob's fields)");
    std::cerr << "reduce: detector calibrated on " << cal.recordings << " recordings (" << cal.rule << "):\n";
    calibration = {{"rule", cal.rule}, {"recordings", a.calibrate}, {"duty_cycle", r.duty.profile}, {"channels", json::array()}};
    for (int ch = 0; ch < 5; ++ch) {
      const ChannelCalibration& cc = cal.channels[static_cast<std::size_t>(ch)];
      if (!cc.diagnosed) continue;
      std::cerr << fmt::format("  ch{}: worst residual {:.2f} K above the model; drift {:.2f} K, worst evidence {:.2f} K min -> "
                               "WARN {:.2f}, ALARM {:.2f} K min ({:g} W more: ALARM after {}); {:.2f} K below; drift {:.2f} K, "
                               "worst {:.2f} -> WARN {:.2f} K min\n",
                               ch + 1, cc.worst_above_K, cc.detector.drift_K, cc.worst_high_K_min, cc.detector.warn_evidence_K_min,
                               cc.detector.alarm_evidence_K_min, r.design_fault.heat_w,
                               cc.design_alarm_min < 0 ? std::string("not within 2 h") : fmt::format("{:.1f} min", cc.design_alarm_min),
                               cc.worst_below_K, cc.detector.low_drift_K, cc.worst_low_K_min, cc.detector.low_warn_evidence_K_min);
      calibration["channels"].push_back({{"channel", ch + 1}, {"column", cc.column}, {"samples", cc.samples},
                                         {"worst_above_K", cc.worst_above_K}, {"worst_below_K", cc.worst_below_K},
                                         {"worst_upper_evidence_K_min", cc.worst_high_K_min},
                                         {"worst_lower_evidence_K_min", cc.worst_low_K_min},
                                         {"design_fault_alarm_min", cc.design_alarm_min}});
    }
  } else {
    // Hand-set thresholds: not below what the model's own error (against the full network, over
    // the reduction profile) would accumulate, unless forced.
    for (int ch = 0; ch < 5; ++ch) {
      const auto& res = r.deviation.residual_K[static_cast<std::size_t>(ch)];
      if (res.empty()) continue;
      const auto [hi, lo] = worst_evidence({res}, d.drift_K, d.low_drift_K, r.model.dt_ms);
      const bool low_bad = d.low_warn_evidence_K_min > 0 && lo >= d.low_warn_evidence_K_min;
      if (hi < d.warn_evidence_K_min && !low_bad) continue;
      const std::string msg = fmt::format(
          "ch{}: the model's own error against the full network (max {:.2f} K over the reduction profile) accumulates "
          "{:.2f} K min of evidence above and {:.2f} below the model with --drift {:.2f} / --low-drift {:.2f} K, at or over "
          "--warn-evidence {:.2f} / --low-warn-evidence {:.2f} K min: a healthy spindle would WARN. Calibrate on recordings "
          "of normal running (--calibrate-bands RECORDINGS...), raise the thresholds, or --force",
          ch + 1, r.deviation.quantized_vs_full_K[static_cast<std::size_t>(ch)], hi, lo, d.drift_K, d.low_drift_K,
          d.warn_evidence_K_min, d.low_warn_evidence_K_min);
      if (!a.force) throw CommandError(kExitFailure, msg);
      std::cerr << "reduce: WARNING (forced): " << msg << "\n";
    }
  }
  // Where in speed the module's model holds (the network knows every speed; the module only its
  // breakpoints): checked up to the top breakpoint or the calibration recordings' top speed.
  SpeedCoverageOptions co;
  co.top_rpm = o.duty_max_rpm;
  // Calibrated bands are the tool's own claim that the module diagnoses: there a drift raised over a
  // large steady error must not hide the fault it is there for, so the design fault's visibility
  // is part of the refusal. Hand-set bands are the user's experiment: the same check only warns.
  const bool calibrated = !a.calibrate.empty();
  co.design_heat_w = calibrated ? a.design_heat_w : 0.0;
  const SpeedCoverage cover = check_speed_coverage(net, model.params, r, co);
  SpeedCoverageOptions with_fault = co;
  with_fault.design_heat_w = a.design_heat_w;
  const SpeedCoverage fault_cover = calibrated ? cover : check_speed_coverage(net, model.params, r, with_fault);
  for (int ch = 0; ch < 5; ++ch)
    if (const double need = fault_cover.bands_hide_fault_K[static_cast<std::size_t>(ch)]; need > 0)
      std::cerr << fmt::format("reduce: WARNING: ch{}: its bands (drift {:.2f} K, ALARM {:.2f} K min) need a lasting {:.2f} K to ALARM "
                               "within {:g} min, more than {:g} W at its node raises it at some speeds: such a fault goes unseen "
                               "even where the model is exact (--calibrate-bands, or narrower bands)\n",
                               ch + 1, r.model.detector[ch].drift_K, r.model.detector[ch].alarm_evidence_K_min, need,
                               fault_cover.design_alarm_within_min, fault_cover.design_heat_w);
  if (!calibrated)
    for (const auto& l : describe_gaps(fault_cover))
      if (l.find("would not ALARM") != std::string::npos) std::cerr << "reduce: WARNING (hand-set bands): " << l << "\n";
  std::cerr << fmt::format("reduce: the module's model is valid (steady error within {:g} x the drift{}) for {:.0f}-{:.0f} rpm "
                           "of the {:.0f}-{:.0f} rpm checked\n",
                           cover.drift_fraction,
                           calibrated ? fmt::format(", {:g} W more at a node ALARMs within {:g} min", cover.design_heat_w,
                                                    cover.design_alarm_within_min)
                                      : std::string(),
                           cover.valid_from_rpm, cover.valid_to_rpm, 0.0, cover.speed_rpm.back());
  if (!cover.covers_all) {
    std::string lines;
    for (const auto& l : describe_gaps(cover)) lines += "\n  " + l;
    const std::string msg = fmt::format(
        "the module's model does not hold at speeds the spindle may run (a healthy spindle running there for long "
        "WARNs, then ALARMs; or a fault there goes unseen):{}\nAdd breakpoints in those ranges (--speeds, at most {}), e.g. one where the "
        "lowest gap ends; or --force if the spindle never runs there",
        lines, kModelMaxBreakpoints - 1);
    if (!a.force) throw CommandError(kExitFailure, msg);
    std::cerr << "reduce: WARNING (forced): " << msg << "\n";
  }
  json j = reduction_to_json(net, r, o);
  j["model"] = a.model;
  j["speed_coverage"] = speed_coverage_to_json(cover);
  if (!calibration.is_null()) j["detector_calibration"] = calibration;
  // The JSON and the blob are one result (the JSON holds the blob's bytes as blob_hex): both are
  // written, or neither (a failed --blob had already replaced the JSON).
  const std::string json_text = json_file_text(j);
  std::vector<io::OutputFile> outputs{{a.out, json_text, "JSON"}};
  if (!a.blob.empty())
    outputs.push_back({a.blob, std::string_view(reinterpret_cast<const char*>(r.blob.data()), r.blob.size()), "model blob"});
  io::write_output_files(outputs);
  std::cerr << "reduce: wrote " << a.out << "\n";
  if (!a.blob.empty())
    std::cerr << "reduce: wrote " << a.blob << " (" << r.blob.size() << " bytes, format version " << int(kReducedModelVersion) << ")\n";
  if (a.json_out) {
    print_json(j);
    return;
  }
  for (const auto& s : r.speeds) {
    std::cout << fmt::format("{:.0f} rpm: HSV", s.speed_rpm);
    for (Eigen::Index i = 0; i < s.hsv.size(); ++i) std::cout << fmt::format(" {:.5g}", s.hsv[i]);
    std::cout << "; time constants of the network (min):";
    for (Eigen::Index i = s.poles.size() - 1; i >= 0; --i) std::cout << fmt::format(" {:.1f}", -1.0 / s.poles[i] / 60.0);
    std::cout << "\n";
  }
  for (const auto& l : map_lines) std::cout << l << "\n";
  for (int ch = 0; ch < 5; ++ch) {
    const auto& cr = r.channels[static_cast<std::size_t>(ch)];
    if (cr.node < 0) continue;
    std::cout << fmt::format("ch{} {}: time constant (min) running", ch + 1, net.nodes[static_cast<std::size_t>(cr.node)].name);
    for (std::size_t i = 1; i < cr.tau_s.size(); ++i) std::cout << fmt::format(" {:.0f}", cr.tau_s[i] / 60);
    std::cout << " at " << a.speeds << " rpm; stopped";
    for (int k = 0; k < kModelEarlyStopPhases; ++k)
      if (r.model.stop_end_s[k] != 0) std::cout << fmt::format(" {} (until {:.0f} min)", stop_time_constant_text(cr.stop_tau_s[static_cast<std::size_t>(k)]), r.model.stop_end_s[k] / 60.0);
    std::cout << fmt::format(" {:.0f} after; max error vs the full network {:.3f} K\n", cr.tau_s[0] / 60,
                             r.deviation.quantized_vs_full_K[static_cast<std::size_t>(ch)]);
    if (cr.carrier >= 0)
      std::cout << fmt::format("    rides on ch{} (coupling {:.3g} per step, share {:.2f}): duty-cycle error {:.2f} K -> {:.2f} K\n",
                               cr.carrier + 1, r.model.couple[ch], cr.coupling_share, cr.plain_duty_K, cr.carried_duty_K);
    const ChannelDetector& cd = r.model.detector[ch];
    std::cout << fmt::format("    detector: drift {:.2f} K, WARN {:.2f} K min, ALARM {:.2f} K min; colder: drift {:.2f} K, "
                             "WARN {:.2f} K min; limit {:.1f} degC, rise {:.2f} K/min\n",
                             cd.drift_K, cd.warn_evidence_K_min, cd.alarm_evidence_K_min, cd.low_drift_K,
                             cd.low_warn_evidence_K_min, cd.abs_limit_c, cd.max_rise_K_per_min);
  }
  std::cout << fmt::format("deviation over the {:.0f} h reduction profile: module model vs full network {:.4f} K (worst channel), "
                           "double reduction vs full {:.4f} K, fixed point vs double {:.6f} K\n",
                           r.deviation.profile_hours, r.deviation.quantized_vs_full_max_K, r.deviation.double_vs_full_max_K,
                           r.deviation.quantized_vs_double_max_K);
}

}  // namespace

void register_sysid_commands(CLI::App& app) {
  {
    auto a = std::make_shared<FitArgs>();
    auto* c = app.add_subcommand("fit", "Fit a thermal network model to recordings (cooling-first pipeline, no initial guess needed)");
    c->footer(
        "Fits every free parameter of the network to all recordings at once (output error, exact simulation).\n"
        "Pipeline: cooling phases first (integral equation-error start, then output error), the operating-only\n"
        "parameters on the warm-ups, then a joint fit. The per-recording initial states are estimated.\n"
        "The scale gauge (C, G, Q -> kC, kG, kQ) is fixed by --sum-c or the network's sum_capacitance_J_per_K, or by\n"
        "fixed parameters. Output: model JSON with values, units, 1 sigma, identifiability, fit metrics.\n"
        "Example: btsm fit warmup_*.csv --preset spindle4 --sum-c 20478.7 --out model.json\n"
        "A recording from `btsm record` carries the module's channel roles: nodes named like a role are measured by\n"
        "the channel with that role (or by none), as printed. With the default roles (ch5 spare) and the fifth probe\n"
        "on the shaft end, add --column shaft=T5 (the model JSON keeps the mapping for validate, reduce and heat).");
    c->add_option("recordings", a->recordings, "Recording CSV files (time_s,speed_rpm,ambient_c,T1..)")->required()->check(existing_input_file());
    c->add_option("--preset", a->preset, "Built-in network: spindle4 (Lo, Hu & Chang 2018)");
    c->add_option("--network", a->network, "Network description JSON (see README: Network JSON)")->check(existing_input_file());
    c->add_option("--sum-c", a->sum_c, "Known total heat capacity sum C_i in J/K (scale gauge)")->check(positive_number());
    c->add_option("--column", a->columns, "NODE=COLUMN: which recording column measures a node (repeatable; NODE= drops it)");
    c->add_option("--out", a->out, "Model JSON to write")->required();
    c->add_option("--initial", a->initial, "Initial state per recording: estimate (default) or first (first samples)")
        ->check(CLI::IsMember({"estimate", "first"}));
    c->add_flag("--joint-only", a->joint_only, "Skip the staged pipeline (needs initial values in the network JSON)");
    c->add_option("--iterations", a->iterations,
                  "Levenberg-Marquardt iterations of the final joint stage (default " + std::to_string(a->iterations) +
                      "; the start stages use 60)")
        ->check(CLI::Range(1, 1000000));
    c->add_flag("--json", a->json_out, "Print the model JSON (parameters, sigma, ...) to stdout");
    c->callback([a] { run_fit(*a); });
  }
  {
    auto a = std::make_shared<ValidateArgs>();
    auto* c = app.add_subcommand("validate", "Validate a fitted model against recordings (NMSE, RMSE, max error, steady-state MAPE)");
    c->footer(
        "Per recording and measured node: NMSE (paper A7: 1 - sum e^2 / sum (y - mean)^2, 1 = perfect), RMSE and max |error|, overall and per mode (operating /\n"
        "natural cooling); steady-state MAPE (paper A6, on rises above ambient) for every operating phase longer than\n"
        "5 slowest time constants that ends in a stop (probe values missing at the stop are extrapolated back).\n"
        "The initial state is estimated from the first --initial-rows rows only (honest external validation); a\n"
        "recording not longer than that is refused, one shorter than 4x that warned about.");
    c->add_option("model", a->model, "Model JSON from btsm fit")->required()->check(existing_input_file());
    c->add_option("recordings", a->recordings, "Recording CSV files")->required()->check(existing_input_file());
    c->add_option("--plots", a->plots, "Directory for measured-vs-predicted and residual plots (PNG + SVG)");
    c->add_option("--initial-rows", a->initial_rows, "Rows used to estimate the initial state (default 120)")
        ->check(CLI::Range(0.0, 1e9));  // -1 wrapped to 18446744073709551615 rows
    c->add_flag("--json", a->json_out, "Print metrics as JSON (nmse, rmse_K, max_abs_K per node; per recording details)");
    c->callback([a] { run_validate(*a); });
  }
  {
    auto a = std::make_shared<ReduceArgs>();
    auto* c = app.add_subcommand("reduce", "Reduce a fitted model to the module's model: one first-order model per channel (+ blob)");
    c->footer(
        "Per diagnosed channel, at each speed the DC-matched first-order step response closest (max norm) to the\n"
        "full network's node response, and while stopped poles scheduled on the time since the stop (--stop-phases);\n"
        "a channel rides on a slower channel's model (carrier: a bearing relaxes towards its housing or shaft after a\n"
        "stop and warms back after a start) where that cuts its duty-cycle error by >= 10 % (--no-carriers: none);\n"
        "the breakpoints (0 rpm + each speed) are quantized into the module's blob (format version 2). Printed: the\n"
        "network's HSV and time constants per speed, the channel map, each channel's time constants in minutes and\n"
        "its error against the full network over the reduction profile (stops and speed steps).\n"
        "Channel map: from the model JSON (the recordings' channel roles and columns, as fit saw them); --channels\n"
        "overrides it with five entries for ch1..ch5: a node name, 'ambient' or 'none'.\n"
        "Detector (per channel, two one-sided CUSUMs of measured - predicted): --calibrate-bands RECORDINGS sets drift and\n"
        "thresholds from the model's own residuals on recordings of normal running (rule printed); hand-set values\n"
        "are refused (exit 1) when the model's own error would reach them, unless --force: the defaults are a start\n"
        "for --force experiments, not bands for a module.\n"
        "Speed range: the module interpolates its breakpoints linearly in speed (0 rpm = the stop); reduce compares\n"
        "the module's steady rise with the network's every 25 rpm up to the top breakpoint (or the calibration\n"
        "recordings' top speed), prints the range where every channel is within half its drift, and refuses (exit 1)\n"
        "a model that is off by more at some speed, naming the channels and speeds (add breakpoints there, or --force\n"
        "when the spindle never runs there).\n"
        "Example: btsm reduce model.json --speeds 500,2000,4000,6000,8000 --calibrate-bands warmup_*.csv --out reduced.json --blob model.bin");
    c->add_option("model", a->model, "Model JSON from btsm fit")->required()->check(existing_input_file());
    c->add_option("--speeds", a->speeds, "Running breakpoints in rpm, ascending, at most 6, e.g. 500,2000,4000,6000,8000: cover every speed the spindle runs")->required();
    c->add_option("--out", a->out, "Reduced model JSON to write")->required();
    c->add_option("--blob", a->blob, "Also write the module's model blob (binary, 464 bytes)");
    c->add_option("--dt", a->dt, "Module sample period in s (default 5)")->check(CLI::Range(0.1, 60.0));
    c->add_option("--channels", a->channels, "Channel map override ch1..ch5: node names, 'ambient', 'none'");
    c->add_option("--stop-phases", a->stop_phases, "Ends of the early stop phases in s (default 600,2400; '0' = one stop pole)");
    c->add_flag("--no-carriers", a->no_carriers, "Every channel's model plain (no channel rides on a slower channel's model)");
    c->add_option("--cooling-ref", a->cooling_ref, "Speed whose stop state shapes the stop poles (default: the middle breakpoint)")
        ->check(non_negative_number());
    auto* calibrate = c->add_option("--calibrate-bands", a->calibrate, "Recordings of normal running: set the detector from the model's own residuals on them")
        ->check(existing_input_file());
    // The margin shapes only the calibration: without --calibrate-bands it did nothing, silently, and
    // one below 1 was refused only after the reduction's seconds of work (probe 4).
    c->add_option("--margin", a->rule.margin, "Calibration: WARN = margin x worst evidence + floor (default 1.5)")
                       ->check(CLI::Range(1.0, 100.0))
                       ->needs(calibrate);
    c->add_option("--design-heat", a->design_heat_w,
                  "Calibration: the extra heat (W) at a channel's node whose ALARM the drift makes soonest (default 10)");
    // The blob holds drift and rise in mK as 16 bits and the limit within the probes' IEC 60751
    // range: a value outside is a bad argument named here, not a blob refusal after the reduction.
    const auto blob_mK16 = CLI::Range(0.0, 65.535);
    const auto probe_range_c = CLI::Range(kModelMinAbsLimitMk / 1000.0, kModelMaxAbsLimitMk / 1000.0);
    c->add_option("--drift", a->detector.drift_K, "Detector drift in K: residual above the model forgiven per sample (default 0.5)")
        ->check(blob_mK16);
    c->add_option("--low-drift", a->detector.low_drift_K, "The same below the model, K (default 0.5)")->check(blob_mK16);
    c->add_option("--warn-evidence", a->detector.warn_evidence_K_min, "WARN threshold of the evidence in K min (default 2)");
    c->add_option("--alarm-evidence", a->detector.alarm_evidence_K_min, "ALARM threshold of the evidence in K min (default 4)");
    c->add_option("--low-warn-evidence", a->detector.low_warn_evidence_K_min,
                  "WARN threshold for a probe colder than its model, K min (default 4; 0 = off)");
    c->add_option("--abs-limit", a->detector.abs_limit_c, "Absolute temperature limit in degC (default 80)")->check(probe_range_c);
    c->add_option("--max-rise", a->detector.max_rise_K_per_min, "Maximum rate of rise in K/min (default 2; 0 = off)")
        ->check(blob_mK16);
    c->add_flag("--force", a->force,
                "Accept hand-set detector thresholds the model's own error would reach, and speeds where the model is off");
    c->add_flag("--json", a->json_out, "Print the reduced model JSON to stdout");
    c->callback([a, c] {
      std::vector<std::string> given;
      for (const char* opt : {"--drift", "--low-drift", "--warn-evidence", "--alarm-evidence", "--low-warn-evidence"})
        if (c->count(opt) > 0) given.push_back(opt);
      run_reduce(*a, given);
    });
  }
}

}  // namespace btsm::cli
