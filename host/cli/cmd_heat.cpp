// `btsm heat MODEL.json REC.csv`: inverse estimation of time-varying heat sources (heat_inverse.hpp).
#include "commands.hpp"

#include "cli_support.hpp"
#include "host/io/output_file.hpp"
#include "host/io/utf8_text.hpp"
#include "host/thermal/column_map.hpp"
#include "host/thermal/heat_inverse.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"
#include "host/thermal/recording_metadata.hpp"
#include "host/report/thermal_figures.hpp"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

namespace btsm::cli {
namespace {

namespace th = btsm::thermal;

// The regularisation parameters --alpha and --alpha-range may take [K^2/W^2]: the default scan is
// 1e-10..1e3; on the demo recordings a fixed alpha below ~1e-20 or above ~1e12 left the smoother's
// covariance without a digit (exit 1 after the run, "effective parameters came out 7.7e+23"). The
// bounds keep five decades beyond the default scan on either side.
constexpr double kMinAlpha = 1e-15, kMaxAlpha = 1e9;
constexpr const char* kAlphaBounds = "1e-15..1e9";

std::string alpha_problem(const std::string& text) {
  double x = 0;
  if (!parse_decimal(text, x)) return "'" + io::printable(text) + "' is not a number";
  if (!(x >= kMinAlpha && x <= kMaxAlpha))
    return fmt::format("{} is outside {} K^2/W^2 (the default scan is 1e-10..1e3)", io::printable(text), kAlphaBounds);
  return "";
}

// One bound of --alpha-range, checked as it is parsed (it was blamed on the recording, after the run started).
double alpha_value(const std::string& option, const std::string& which, const std::string& text) {
  if (const std::string why = alpha_problem(text); !why.empty()) throw CLI::ValidationError(option, which + " " + why);
  return std::stod(text);
}

CLI::Validator alpha_bounds(const std::string& option) {
  return CLI::Validator([option](std::string& text) { return alpha_problem(text); }, "", option + " bounds");
}

struct HeatArgs {
  std::string model, recording, method = "tikhonov1", rule = "gcv", scheme = "cn", out_dir, nodes;
  double step_s = 60.0, alpha = 0.0, noise_k = 0.0, alpha_min = 1e-10, alpha_max = 1e3;
  int alpha_points = 40;
  bool keep_model_sources = false, json = false;
};

std::vector<int> parse_nodes(const th::Network& net, const std::string& list) {
  std::vector<int> out;
  std::stringstream ss(list);
  std::string name;
  while (std::getline(ss, name, ',')) {
    if (name.empty()) continue;
    const int i = net.node_index(name);
    if (i < 0) {
      std::string known;
      for (const auto& n : net.nodes) known += (known.empty() ? "" : ", ") + n.name;
      throw CommandError(kExitUsage, "--nodes: no node '" + name + "' in network " + net.name + " (nodes: " + known + ")");
    }
    // one node twice would be two unknowns for the same heat: a singular split between them
    if (std::find(out.begin(), out.end(), i) != out.end()) throw CommandError(kExitUsage, "--nodes: node '" + name + "' is listed twice");
    out.push_back(i);
  }
  // "--nodes ," names no node: the default (the network's source nodes) is asked for by leaving
  // --nodes out, not by a list that says nothing.
  if (out.empty() && !list.empty()) throw CommandError(kExitUsage, "--nodes '" + list + "': names no node");
  return out;
}

void write_outputs(const HeatArgs& a, const th::Network& net, const th::Recording& rec, const th::InverseProblem& p,
                   const th::HeatInverseResult& r, const std::vector<std::string>& cols) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(a.out_dir, ec);
  if (ec) throw CommandError(kExitFailure, "cannot create --out directory " + a.out_dir + ": " + ec.message());
  const int m = static_cast<int>(p.source_nodes.size());
  {
    const std::string path = a.out_dir + "/heat_sources.csv";
    std::ostringstream f;
    f << "# model: " << a.model << "\n# recording: " << a.recording << "\n# method: " << a.method
      << "\n# alpha_rule: " << r.rule << "\n# alpha_K2_per_W2: " << fmt::format("{:.6g}", r.alpha)
      << "\n# noise_sigma_K: " << fmt::format("{:.6g}", r.noise_sigma_k) << (r.noise_estimated ? " (estimated)" : "")
      << "\n# residual_rms_K: " << fmt::format("{:.6g}", r.residual_rms_k) << "\n";
    f << "step_start_s,step_end_s";
    for (int j = 0; j < m; ++j) f << "," << net.nodes[p.source_nodes[j]].name << "_W," << net.nodes[p.source_nodes[j]].name << "_sigma_W";
    f << "\n";
    for (int i = 0; i < r.heat_w.rows(); ++i) {
      const double end = i + 1 < r.heat_w.rows() ? r.piece_start_s[i + 1] : rec.time_s.back();
      f << fmt::format("{:.6g},{:.6g}", r.piece_start_s[i], end);
      for (int j = 0; j < m; ++j) f << fmt::format(",{:.5f},{:.5f}", r.heat_w(i, j), r.heat_sigma_w(i, j));
      f << "\n";
    }
    io::write_output_file(path, f.str(), "heat sources");
  }
  {
    const std::string path = a.out_dir + "/heat_alpha_scan.csv";
    std::ostringstream f;
    f << "alpha_K2_per_W2,rss_K2,seminorm_W2,dof,gcv\n";
    for (const auto& s : r.scan) f << fmt::format("{:.6g},{:.8g},{:.8g},{:.6g},{:.8g}\n", s.alpha, s.rss_k2, s.seminorm_w2, s.dof, s.gcv);
    io::write_output_file(path, f.str(), "alpha scan");
  }
  namespace rp = btsm::report;
  rp::save_figure(rp::heat_figure(net, rec, p, r, cols, a.method), a.out_dir + "/heat_sources",
                  rp::network_figure_options(net));
}

// What heat writes into --out.
const std::vector<io::OutputName> kHeatOutputs{{"heat_sources.csv", "heat sources"}, {"heat_alpha_scan.csv", "alpha scan"},
                                               {"heat_sources.png", "plot"}, {"heat_sources.svg", "plot"}};

void run_heat(const HeatArgs& a) {
  // Before the inverse: an --out that could not be made failed after it (exit 1), and a named pipe
  // in it under an output's name blocked for ever.
  io::refuse_output_dir_that_cannot_be_made(a.out_dir, "--out", kHeatOutputs);
  if (!a.out_dir.empty())
    for (const auto& f : kHeatOutputs) io::refuse_output_over_input(a.out_dir + "/" + f.name, "--out", {a.model, a.recording});
  th::HeatInverseOptions o;
  try {
    o.order = th::parse_tikhonov_order(a.method);
    o.rule = th::parse_alpha_rule(a.rule);
  } catch (const std::invalid_argument& e) {
    throw CommandError(kExitUsage, e.what());
  }
  if (a.scheme == "cn") o.scheme = th::Discretisation::CrankNicolson;
  else if (a.scheme == "exact") o.scheme = th::Discretisation::ExactZoh;
  else throw CommandError(kExitUsage, "--scheme must be cn or exact, not '" + a.scheme + "'");
  if (!(a.step_s > 0)) throw CommandError(kExitUsage, "--step must be > 0 s");
  if (o.rule == th::AlphaRule::Fixed && !(a.alpha > 0)) throw CommandError(kExitUsage, "--alpha-rule fixed needs --alpha > 0");
  if (o.rule != th::AlphaRule::Fixed && a.alpha != 0.0)
    throw CommandError(kExitUsage, "--alpha is used only with --alpha-rule fixed (the rule '" + a.rule +
                                       "' chooses alpha itself): add --alpha-rule fixed, or drop --alpha");
  o.step_s = a.step_s;
  o.break_at_speed_changes = true;  // friction heat jumps with the speed: no step straddles a change
  o.alpha_fixed = a.alpha;
  o.progress = [](const std::string& s) { std::cerr << "heat: " << s << "\n"; };
  o.noise_sigma_k = a.noise_k;
  o.alpha_min = a.alpha_min;
  o.alpha_max = a.alpha_max;
  o.alpha_points = a.alpha_points;

  th::ModelWithParameters model;
  th::Recording rec;
  try {
    model = th::load_model_with_parameters(a.model);
    rec = th::read_recording_csv(a.recording);
    for (const std::string& w : th::reading_warnings(rec)) std::cerr << "heat: WARNING: " << io::printable(w) << "\n";
    th::check_mapping_agrees_with_roles(model.network, model.channel_map, {rec}, {},
                                        "refit the model with this recording, or correct its channel_roles line");
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  for (const auto& w : th::unsampled_measurement_warnings(model.network, rec, "the heat is estimated without that probe"))
    std::cerr << "heat: WARNING: " << io::printable(w) << "\n";
  const std::vector<int> nodes = parse_nodes(model.network, a.nodes);
  th::InverseProblem p;
  try {
    p = th::make_inverse_problem(model.network, model.params, rec, nodes, a.keep_model_sources);
  } catch (const std::invalid_argument& e) {
    throw CommandError(kExitUsage, e.what());
  }
  const std::vector<std::string> cols = th::measured_columns(model.network, rec);
  int changes = 0;  // a step also begins at each speed change (o.break_at_speed_changes)
  for (std::size_t k = 1; k < rec.rows(); ++k) changes += rec.speed_rpm[k] != rec.speed_rpm[k - 1];
  std::cerr << fmt::format("heat: {} samples ({:.2f} h), {} measured columns, {} source nodes, {:g} s steps (a new one also at each "
                           "of the {} speed changes); alpha by {}\n",
                           rec.rows(), (rec.time_s.back() - rec.time_s.front()) / 3600.0, cols.size(), p.source_nodes.size(),
                           a.step_s, changes, a.rule);
  const auto t0 = std::chrono::steady_clock::now();
  th::HeatInverseResult r;
  try {
    r = th::solve_heat_inverse(p, o);
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    throw CommandError(kExitUsage, a.recording + ": " + what +
                                       (what.find("noise level") != std::string::npos ? " (or give it with --noise)" : ""));
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cerr << fmt::format("heat: done in {:.2f} s\n", secs);
  // Nothing is written from a result that is not a number: the model's terms overflowed at the
  // recording's speeds (a network unstable there), which no choice of alpha repairs.
  if (!r.heat_w.allFinite() || !std::isfinite(r.residual_rms_k))
    throw CommandError(kExitFailure, a.recording + ": the inverse with model " + a.model +
                                         " gives heat that is not a number (the model's terms overflow at this recording's "
                                         "speeds: is the model valid there? check it with btsm validate); nothing written");
  const double observations = static_cast<double>(p.measured.array().isFinite().count());
  if (!(r.dof >= 0 && r.dof <= observations))
    throw CommandError(kExitFailure, fmt::format("{}: the inverse's effective parameters came out {:.6g}, outside 0..{:.0f}: "
                                                 "its covariance lost precision (a model that does not fit this recording, "
                                                 "or sample steps far longer than the model's fast modes: check with btsm "
                                                 "validate); nothing written",
                                                 a.recording, r.dof, observations));
  // A fit that misses by far more than the recording's whole temperature span explains nothing:
  // its heat would be numbers, not an estimate (a model's probe drift of 1e10 K/h gave 6.7e9 K).
  double lo = INFINITY, hi = -INFINITY;
  for (Eigen::Index i = 0; i < rec.temp_c.size(); ++i)  // as read: p.measured has the model's probe drift taken off
    if (std::isfinite(rec.temp_c.data()[i])) lo = std::min(lo, rec.temp_c.data()[i]), hi = std::max(hi, rec.temp_c.data()[i]);
  const double span_k = hi >= lo ? hi - lo : 0.0;
  if (r.residual_rms_k > 10.0 * (span_k + 1.0))
    throw CommandError(kExitFailure, fmt::format("{}: model {} misses this recording by {:.4g} K rms, while its temperatures span "
                                                 "{:.4g} K: the model does not describe it (a probe drift, a source or a "
                                                 "conductance far off? check it with btsm validate); nothing written",
                                                 a.recording, a.model, r.residual_rms_k, span_k));
  if (!a.out_dir.empty()) write_outputs(a, model.network, rec, p, r, cols);

  const int m = static_cast<int>(p.source_nodes.size());
  if (a.json) {
    nlohmann::json j;
    j["model"] = a.model;
    j["recording"] = a.recording;
    j["method"] = a.method;
    j["alpha_rule"] = r.rule;
    j["alpha_K2_per_W2"] = r.alpha;
    j["step_s"] = a.step_s;
    j["scheme"] = a.scheme;
    j["noise_sigma_K"] = r.noise_sigma_k;
    j["noise_estimated"] = r.noise_estimated;
    j["residual_rms_K"] = r.residual_rms_k;
    j["dof"] = r.dof;
    j["seconds"] = secs;
    for (size_t c = 0; c < cols.size(); ++c) j["residual_rms_per_channel_K"][cols[c]] = r.residual_rms_per_channel_k(c);
    j["step_start_s"] = r.piece_start_s;
    j["sources"] = nlohmann::json::array();
    for (int s = 0; s < m; ++s) {
      nlohmann::json js;
      js["node"] = model.network.nodes[p.source_nodes[s]].name;
      std::vector<double> v(r.heat_w.rows()), sg(r.heat_w.rows());
      for (int i = 0; i < r.heat_w.rows(); ++i) { v[i] = r.heat_w(i, s); sg[i] = r.heat_sigma_w(i, s); }
      js["heat_W"] = v;
      js["sigma_W"] = sg;
      j["sources"].push_back(js);
    }
    j["scan"] = nlohmann::json::array();
    for (const auto& s : r.scan) j["scan"].push_back({{"alpha", s.alpha}, {"rss_K2", s.rss_k2}, {"seminorm_W2", s.seminorm_w2}, {"dof", s.dof}, {"gcv", s.gcv}});
    if (!a.out_dir.empty()) j["out_dir"] = a.out_dir;
    // same format as cli_support's print_json; printed here because this file is compiled into
    // btsm_thermal, which must not depend on the CLI executable's sources
    std::cout << j.dump(2) << "\n";
    return;
  }
  // A step holds at least one sample interval: with samples further apart than --step, the steps
  // are the sample intervals, and saying "steps of 60 s" of hourly samples would misstate them.
  const double mean_step_s = r.piece_start_s.size() > 1
                                 ? (r.piece_start_s.back() - r.piece_start_s.front()) / static_cast<double>(r.piece_start_s.size() - 1)
                                 : a.step_s;
  const std::string steps = mean_step_s > 1.5 * a.step_s
                                ? fmt::format("{} steps, one per sample interval (mean {:.4g} s): --step {:g} s is shorter than the samples' spacing",
                                              r.heat_w.rows(), mean_step_s, a.step_s)
                                : fmt::format("{} steps of up to {:g} s, a new one at each speed change", r.heat_w.rows(), a.step_s);
  // Steps differ in length (a speed change starts one): means are over time, not over steps.
  Eigen::VectorXd step_len(r.heat_w.rows());
  for (Eigen::Index i = 0; i < step_len.size(); ++i)
    step_len[i] = (i + 1 < step_len.size() ? r.piece_start_s[static_cast<std::size_t>(i + 1)] : rec.time_s.back()) -
                  r.piece_start_s[static_cast<std::size_t>(i)];
  const double total_s = step_len.sum();
  const auto time_mean = [&](const Eigen::VectorXd& v) { return total_s > 0 ? v.dot(step_len) / total_s : v.mean(); };
  std::cout << fmt::format("Inverse heat sources: {} on {} ({})\n", a.recording, model.network.name, steps);
  std::cout << fmt::format("  method {} ({}), alpha = {:.4g} K^2/W^2 chosen by {}{}\n", a.method,
                           a.scheme == "cn" ? "Crank-Nicolson" : "exact ZOH", r.alpha, r.rule,
                           r.monte_carlo_evaluations ? fmt::format(" ({} evaluations)", r.monte_carlo_evaluations) : "");
  std::cout << fmt::format("  noise sigma {:.4g} K{}, residual rms {:.4g} K, effective parameters {:.1f}\n", r.noise_sigma_k,
                           r.noise_estimated ? " (estimated from the data)" : "", r.residual_rms_k, r.dof);
  // A column with no value in any row has no residual (warned about above): "--", never "nan".
  for (size_t c = 0; c < cols.size(); ++c)
    std::cout << (std::isfinite(r.residual_rms_per_channel_k(c))
                      ? fmt::format("  residual rms {:>8}: {:.4g} K\n", cols[c], r.residual_rms_per_channel_k(c))
                      : fmt::format("  residual rms {:>8}: -- (no value in any row)\n", cols[c]));
  std::cout << fmt::format("  {:<16} {:>10} {:>10} {:>10} {:>12}\n", "node", "mean [W]", "min [W]", "max [W]", "mean 1σ [W]");
  for (int s = 0; s < m; ++s)
    std::cout << fmt::format("  {:<16} {:>10.3f} {:>10.3f} {:>10.3f} {:>12.3f}\n", model.network.nodes[p.source_nodes[s]].name,
                             time_mean(r.heat_w.col(s)), r.heat_w.col(s).minCoeff(), r.heat_w.col(s).maxCoeff(),
                             time_mean(r.heat_sigma_w.col(s)));
  if (!a.out_dir.empty()) std::cout << "  written: " << a.out_dir << "/heat_sources.csv, heat_alpha_scan.csv, heat_sources.png/.svg\n";
}

}  // namespace

void register_heat_commands(CLI::App& app) {
  auto args = std::make_shared<HeatArgs>();
  CLI::App* cmd = app.add_subcommand(
      "heat",
      "Estimate time-varying heat sources from measured temperatures (inverse heat transfer, after Li et al. 2022).\n"
      "The network's conductances and capacitances come from MODEL.json; the heat at the source nodes is\n"
      "unknown, piecewise constant over --step seconds, and found by Tikhonov regularisation. The solver is a\n"
      "Kalman/RTS smoother, so time and memory grow linearly with the recording length.");
  cmd->add_option("model", args->model,
                  "Model: fitted model JSON (network + parameter values), a network JSON whose parameters have values, "
                  "or a preset name (spindle4)")->required();
  cmd->add_option("recording", args->recording, "Recording CSV (time_s,speed_rpm,ambient_c,T...)")->required()->check(existing_input_file());
  cmd->add_option("--step", args->step_s, "Sources are constant over steps of this length [s] (default 60)");
  cmd->add_option("--method", args->method, "tikhonov0 (penalise |q|) or tikhonov1 (penalise changes of q; default)");
  cmd->add_option("--alpha-rule", args->rule,
                  "How alpha is chosen: gcv (default), lcurve, discrepancy (needs the noise level; estimated if not given), "
                  "montecarlo (the paper's ICO random search, threshold tied to the noise level), fixed (--alpha)");
  cmd->add_option("--alpha", args->alpha,
                  fmt::format("Regularisation parameter for --alpha-rule fixed [K^2/W^2], {}", kAlphaBounds))
      ->check(alpha_bounds("--alpha"));
  cmd->add_option("--alpha-range", [args](const std::vector<std::string>& v) {
        if (v.size() != 2) return false;
        args->alpha_min = alpha_value("--alpha-range", "MIN", v[0]);
        args->alpha_max = alpha_value("--alpha-range", "MAX", v[1]);
        if (!(args->alpha_min < args->alpha_max))
          throw CLI::ValidationError("--alpha-range", fmt::format("MIN {} is not below MAX {}: give MIN MAX, MIN < MAX, each in {} K^2/W^2",
                                                                  io::printable(v[0]), io::printable(v[1]), kAlphaBounds));
        return true;
      }, fmt::format("Search range MIN MAX of alpha [K^2/W^2], MIN < MAX, each in {} (default 1e-10 1e3)", kAlphaBounds))
      ->expected(2);
  // 1000 log-spaced points over 13 decades are 3 % apart, finer than any rule can tell; each
  // point is one smoother run (seconds on a large network), so 100,000 ran for days.
  cmd->add_option("--alpha-points", args->alpha_points, "Grid points of the alpha scan, 3..1000 (default 40)")
      ->check(CLI::Range(3, 1000));
  // Below 10 uK (the AD7794's noise is ~1 mK) the weights of the inverse reach 1e10/K and its
  // normal equations lose every digit: --noise 1e-7 gave 2.5e80 K residuals with exit 0.
  cmd->add_option("--noise", args->noise_k, "Measurement noise sigma [K], at least 1e-5 (default: estimated from the data)")
      ->check(CLI::Range(1e-5, 1e3));
  cmd->add_option("--scheme", args->scheme, "Time discretisation: cn (Crank-Nicolson, as in the paper; default) or exact (ZOH)");
  cmd->add_option("--nodes", args->nodes, "Comma-separated node names receiving unknown heat (default: the network's source nodes)");
  cmd->add_flag("--keep-model-sources", args->keep_model_sources,
                "Keep the model's own heat sources and estimate only the heat it does not explain");
  cmd->add_option("--out", args->out_dir, "Write heat_sources.csv, heat_alpha_scan.csv and heat_sources.png/.svg here")
      ->transform([](std::string dir) {  // "dir/" printed "dir//file"
        while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
        return dir;
      });
  cmd->add_flag("--json", args->json, "Print the result as JSON on stdout");
  cmd->callback([args] { run_heat(*args); });
}

}  // namespace btsm::cli
