// btsm fit | validate | reduce
#include "cli_support.hpp"
#include "commands.hpp"

#include "host/thermal/fit.hpp"
#include "host/thermal/model_file.hpp"
#include "host/thermal/reduce.hpp"
#include "host/thermal/validate.hpp"
#include "host/report/thermal_figures.hpp"

#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>

namespace btsm::cli {
namespace {

using namespace btsm::thermal;
using nlohmann::json;

std::vector<Recording> read_all(const std::vector<std::string>& files) {
  std::vector<Recording> recs;
  for (const auto& f : files) {
    std::cerr << "reading " << f << "\n";
    try {
      recs.push_back(read_recording_csv(f));
    } catch (const std::exception& e) {
      throw CommandError(kExitUsage, e.what());
    }
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
    const std::string said = map_measurements(net, recs, a.columns);
    if (!said.empty()) std::cerr << "fit: from the recordings' channel roles:" << said << "\n";
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
    for (const auto& e : fit.estimates)
      std::cout << fmt::format("{:<8} {:>14.6g} {:>12.3g} {:>8.3g}  {:<10} {}{}\n", e.name, e.value, e.sigma,
                               e.value != 0 ? 100 * e.sigma / std::abs(e.value) : 0.0, e.unit, identifiability_name(e.status),
                               e.note.empty() ? "" : "  (" + e.note + ")");
    std::cout << "gauge: " << fit.gauge << "\n";
    for (const auto& w : fit.warnings) std::cout << "warning: " << w << "\n";
  }
  if (!fit.converged)
    throw CommandError(kExitFailure, fmt::format("the fit did not converge within {} iterations of its final stage (see "
                                                 "warnings; --iterations raises the limit)", a.iterations));
}

// ------------------------------------------------------------------------------------- validate
struct ValidateArgs {
  std::string model;
  std::vector<std::string> recordings;
  std::string plots;
  bool json_out = false;
  std::size_t initial_rows = 120;
};

void plot_validation(const Network& net, const Recording& rec, const RecordingValidation& v, const std::string& dir) {
  namespace rp = btsm::report;
  std::filesystem::create_directories(dir);
  const std::string stem = (std::filesystem::path(dir) / ("validate_" + std::filesystem::path(rec.source).stem().string())).string();
  rp::save_figure(rp::validation_figure(net, rec, v, std::filesystem::path(rec.source).filename().string()), stem,
                  rp::network_figure_options(net));
  std::cerr << "validate: wrote " << stem << ".png/.svg\n";
}

json metrics_json(const ErrorMetrics& m) {
  auto num = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  return {{"nmse", num(m.nmse)}, {"rmse_K", num(m.rmse_K)}, {"max_abs_K", num(m.max_abs_K)}, {"samples", m.count}};
}

void run_validate(const ValidateArgs& a) {
  FittedModel model;
  try {
    model = load_model(a.model);
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  const auto recs = read_all(a.recordings);
  const Network& net = model.network;
  ValidateOptions o;
  o.initial_rows = a.initial_rows;
  json out;
  out["model"] = a.model;
  out["recordings"] = json::array();
  json nmse, rmse, maxabs;
  double worst_mape = 0;
  for (const auto& rec : recs) {
    RecordingValidation v;
    try {
      v = validate_recording(net, model.params, rec, o);
    } catch (const std::invalid_argument& e) {
      throw CommandError(kExitUsage, e.what());
    }
    json rj;
    rj["file"] = rec.source;
    rj["initial_state_c"] = std::vector<double>(v.initial_state_c.data(), v.initial_state_c.data() + v.initial_state_c.size());
    std::cout << (a.json_out ? "" : fmt::format("{}\n  {:<6} {:>10} {:>10} {:>10} | {:>10} {:>10} | {:>10} {:>10}\n", rec.source, "node",
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
      if (!a.json_out)
        std::cout << fmt::format("  {:<6} {:>10.6f} {:>10.5f} {:>10.5f} | {:>10.6f} {:>10.5f} | {:>10.6f} {:>10.5f}\n", col, v.all[m].nmse,
                                 v.all[m].rmse_K, v.all[m].max_abs_K, v.operating[m].nmse, v.operating[m].max_abs_K,
                                 v.cooling[m].nmse, v.cooling[m].max_abs_K);
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
    out["recordings"].push_back(rj);
    if (!a.plots.empty()) plot_validation(net, rec, v, a.plots);
  }
  out["nmse"] = nmse;
  out["rmse_K"] = rmse;
  out["max_abs_K"] = maxabs;
  out["steady_mape_max_percent"] = worst_mape;
  out["summary_note"] = "nmse/rmse_K/max_abs_K: worst value per node over the recordings";
  if (a.json_out) print_json(out);
}

// ------------------------------------------------------------------------------------- reduce
struct ReduceArgs {
  std::string model, speeds, out, blob, channels = "1,2,3,ambient,none";
  double dt = 5.0, warn = 1.0, alarm = 2.0, abs_limit = 70.0, max_rise = 5.0, cooling_ref = 0.0;
  bool json_out = false;
};

void run_reduce(const ReduceArgs& a) {
  FittedModel model;
  try {
    model = load_model(a.model);
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  const Network& net = model.network;
  ReduceOptions o;
  {
    std::stringstream ss(a.speeds);
    std::string tok;
    while (std::getline(ss, tok, ',')) {
      try {
        std::size_t used = 0;
        o.speeds_rpm.push_back(std::stod(tok, &used));
        if (used != tok.size()) throw std::invalid_argument(tok);
      } catch (const std::exception&) {
        throw CommandError(kExitUsage, "--speeds: bad speed '" + tok + "'");
      }
    }
  }
  {
    // channel spec: five entries: measurement number (1-based, as in the network's measurements),
    // a node name, "ambient" or "none"
    std::stringstream ss(a.channels);
    std::string tok;
    int ch = 0;
    o.ambient_channel = -1;
    while (std::getline(ss, tok, ',')) {
      if (ch >= kModelChannels)
        throw CommandError(kExitUsage, "--channels: at most " + std::to_string(kModelChannels) + " entries");
      int node = -1;
      if (tok == "ambient") {
        if (o.ambient_channel >= 0) throw CommandError(kExitUsage, "--channels: only one ambient channel");
        o.ambient_channel = ch;
      } else if (tok != "none") {
        node = net.node_index(tok);
        if (node < 0) {
          try {
            const int m = std::stoi(tok);
            if (m < 1 || m > static_cast<int>(net.measurements.size())) throw std::out_of_range(tok);
            node = net.measurements[static_cast<std::size_t>(m - 1)].node;
          } catch (const std::exception&) {
            throw CommandError(kExitUsage, "--channels: '" + tok + "' is not a measurement number, node name, 'ambient' or 'none'");
          }
        }
      }
      o.channel_node[static_cast<std::size_t>(ch++)] = node;
    }
    for (; ch < kModelChannels; ++ch) o.channel_node[static_cast<std::size_t>(ch)] = -1;
  }
  o.dt_s = a.dt;
  o.warn_K = a.warn;
  o.alarm_K = a.alarm;
  o.abs_limit_c = a.abs_limit;
  o.max_rise_K_per_min = a.max_rise;
  o.cooling_reference_rpm = a.cooling_ref;
  if (!(o.alarm_K > o.warn_K) || !(o.warn_K > 0)) throw CommandError(kExitUsage, "bands: need 0 < --warn < --alarm");
  std::cerr << "reduce: " << o.speeds_rpm.size() << " speeds ...\n";
  ScheduledReduction r;
  try {
    r = build_scheduled_model(net, model.params, o);
  } catch (const std::invalid_argument& e) {
    throw CommandError(kExitUsage, e.what());
  }
  json j = reduction_to_json(net, r, o);
  j["model"] = a.model;
  save_json(a.out, j);
  std::cerr << "reduce: wrote " << a.out << "\n";
  if (!a.blob.empty()) {
    if (r.blob.empty())
      throw CommandError(kExitFailure, std::string("the scheduled model does not fit the firmware blob: ") + model_status_name(r.quantize_status.status));
    std::ofstream f(a.blob, std::ios::binary);
    f.write(reinterpret_cast<const char*>(r.blob.data()), static_cast<std::streamsize>(r.blob.size()));
    if (!f) throw CommandError(kExitFailure, a.blob + ": write failed");
    std::cerr << "reduce: wrote " << a.blob << " (" << r.blob.size() << " bytes)\n";
  }
  if (a.json_out) {
    print_json(j);
  } else {
    for (const auto& s : r.speeds) {
      std::cout << fmt::format("{:.0f} rpm: HSV", s.speed_rpm);
      for (Eigen::Index i = 0; i < s.hsv.size(); ++i) std::cout << fmt::format(" {:.5g}", s.hsv[i]);
      std::cout << fmt::format("; pole BT {:.4g} /s, DC-matched {:.4g} /s; slowest full pole {:.4g} /s\n", s.bt.pole, s.dc.pole,
                               s.poles.maxCoeff());
    }
    std::cout << fmt::format("cooling: DC-matched pole {:.4g} /s\n", r.cooling.dc.pole);
    std::cout << fmt::format("deviation over {:.0f} h test profile: quantized vs full {:.4f} K, double reduced vs full {:.4f} K, "
                             "quantized vs double {:.6f} K\n",
                             r.deviation.profile_hours, r.deviation.quantized_vs_full_max_K, r.deviation.double_vs_full_max_K,
                             r.deviation.quantized_vs_double_max_K);
    std::cout << "SCTC time constants are not model time constants; only the sum of their rates is exact\n";
  }
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
    c->add_option("recordings", a->recordings, "Recording CSV files (time_s,speed_rpm,ambient_c,T1..)")->required()->check(CLI::ExistingFile);
    c->add_option("--preset", a->preset, "Built-in network: spindle4 (Lo, Hu & Chang 2018)");
    c->add_option("--network", a->network, "Network description JSON (see README: Network JSON)")->check(CLI::ExistingFile);
    c->add_option("--sum-c", a->sum_c, "Known total heat capacity sum C_i in J/K (scale gauge)")->check(CLI::PositiveNumber);
    c->add_option("--column", a->columns, "NODE=COLUMN: which recording column measures a node (repeatable; NODE= drops it)");
    c->add_option("--out", a->out, "Model JSON to write")->required();
    c->add_option("--initial", a->initial, "Initial state per recording: estimate (default) or first (first samples)")
        ->check(CLI::IsMember({"estimate", "first"}));
    c->add_flag("--joint-only", a->joint_only, "Skip the staged pipeline (needs initial values in the network JSON)");
    c->add_option("--iterations", a->iterations,
                  "Levenberg-Marquardt iterations of the final joint stage (default " + std::to_string(a->iterations) +
                      "; the start stages use 60)")
        ->check(CLI::PositiveNumber);
    c->add_flag("--json", a->json_out, "Print the model JSON (parameters, sigma, ...) to stdout");
    c->callback([a] { run_fit(*a); });
  }
  {
    auto a = std::make_shared<ValidateArgs>();
    auto* c = app.add_subcommand("validate", "Validate a fitted model against recordings (NMSE, RMSE, max error, steady-state MAPE)");
    c->footer(
        "Per recording and measured node: NMSE (paper A7), RMSE and max |error|, overall and per mode (operating /\n"
        "natural cooling); steady-state MAPE (paper A6, on rises above ambient) for every operating phase longer than\n"
        "5 slowest time constants that ends in a stop (probe values missing at the stop are extrapolated back).\n"
        "The initial state is estimated from the first --initial-rows rows only (honest external validation).");
    c->add_option("model", a->model, "Model JSON from btsm fit")->required()->check(CLI::ExistingFile);
    c->add_option("recordings", a->recordings, "Recording CSV files")->required()->check(CLI::ExistingFile);
    c->add_option("--plots", a->plots, "Directory for measured-vs-predicted and residual plots (PNG + SVG)");
    c->add_option("--initial-rows", a->initial_rows, "Rows used to estimate the initial state (default 120)");
    c->add_flag("--json", a->json_out, "Print metrics as JSON (nmse, rmse_K, max_abs_K per node; per recording details)");
    c->callback([a] { run_validate(*a); });
  }
  {
    auto a = std::make_shared<ReduceArgs>();
    auto* c = app.add_subcommand("reduce", "Reduce a fitted model to the firmware's speed-scheduled 1st-order model (+ blob)");
    c->footer(
        "At each speed: Hankel singular values (inputs = heat sources in W, outputs = node rises), plain balanced\n"
        "truncation and DC-matched (singular perturbation) 1st-order poles, SCTC time constants. The DC-matched models\n"
        "become breakpoints (0 rpm = natural cooling + each speed) of the firmware model, quantized into the blob;\n"
        "the deviation of the quantized model from the full model is measured over a test profile.\n"
        "--channels: five entries for ch1..ch5: measurement number, node name, 'ambient' or 'none'.");
    c->add_option("model", a->model, "Model JSON from btsm fit")->required()->check(CLI::ExistingFile);
    c->add_option("--speeds", a->speeds, "Operating breakpoints in rpm, ascending, e.g. 4000,6000,8000")->required();
    c->add_option("--out", a->out, "Reduced model JSON to write")->required();
    c->add_option("--blob", a->blob, "Also write the firmware coefficient blob (binary)");
    c->add_option("--dt", a->dt, "Firmware sample period in s (default 5)")->check(CLI::Range(0.1, 60.0));
    c->add_option("--channels", a->channels, "Channel map ch1..ch5 (default 1,2,3,ambient,none)");
    c->add_option("--warn", a->warn, "WARN residual band in K (default 1.0)");
    c->add_option("--alarm", a->alarm, "ALARM residual band in K (default 2.0)");
    c->add_option("--abs-limit", a->abs_limit, "Absolute temperature limit in degC (default 70)");
    c->add_option("--max-rise", a->max_rise, "Maximum rate of rise in K/min (default 5; 0 = off)");
    c->add_option("--cooling-ref", a->cooling_ref, "Speed whose stop state shapes the cooling breakpoint (default: highest)");
    c->add_flag("--json", a->json_out, "Print the reduced model JSON (per speed hsv, pole_bt, pole_dc) to stdout");
    c->callback([a] { run_reduce(*a); });
  }
}

}  // namespace btsm::cli
