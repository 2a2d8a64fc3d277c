// Residual loop report (see residual_report.hpp).
#include "host/residual/residual_report.hpp"

#include "host/io/output_file.hpp"
#include "host/report/plot_style.hpp"
#include "host/report/thermal_figures.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace btsm::residual {
namespace {

nlohmann::json num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json metrics_json(const ErrorMetrics& m) {
  return {{"rmse_K", num(m.rmse_k)}, {"nmse_min", num(m.nmse_min)}, {"max_abs_K", num(m.max_abs_k)}, {"cells", m.cells}};
}

nlohmann::json params_json(const std::vector<ParamReport>& ps) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& p : ps) {
    nlohmann::json pj = {{"name", p.name}, {"unit", p.unit}, {"value", num(p.value)}, {"sigma", num(p.sigma)}, {"status", p.status}};
    if (!p.base.partner.empty())  // an effect parameter refitted jointly with free base parameters
      pj["base_confounding"] = {{"multiple_correlation", num(p.base.multiple_correlation)},
                                {"sigma_inflation", num(p.base.inflation)},
                                {"most_correlated_with", p.base.partner},
                                {"correlation", num(p.base.pair_correlation)}};
    a.push_back(pj);
  }
  return a;
}

nlohmann::json quantities_json(const std::vector<EffectQuantity>& qs) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& q : qs)
    a.push_back({{"name", q.name}, {"unit", q.unit}, {"value", num(q.value)}, {"sigma", num(q.sigma)}, {"meaning", q.meaning}});
  return a;
}

std::string join(const std::vector<std::string>& v, const char* sep = ", ") {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : sep) + x;
  return s;
}

}  // namespace

nlohmann::json to_json(const LoopResult& r) {
  nlohmann::json j;
  j["verdict"] = r.verdict;
  j["effect"] = r.effect;
  j["label"] = r.label;
  j["nodes"] = r.nodes;
  j["quantities"] = quantities_json(r.quantities);
  j["parameters"] = params_json(r.params);
  j["explanation"] = r.explanation;
  j["undecided"] = r.undecided;
  j["noise_sigma_K"] = num(r.noise_sigma_k);
  j["check_floor_K"] = num(r.check_floor_k);
  j["rmse_before_K"] = num(r.before_check.rmse_k);
  j["rmse_after_K"] = num(r.after_check.rmse_k);
  j["nmse_before"] = num(r.before_check.nmse_min);
  j["nmse_after"] = num(r.after_check.nmse_min);
  j["max_error_before_K"] = num(r.before_check.max_abs_k);
  j["max_error_after_K"] = num(r.after_check.max_abs_k);
  j["fit"] = {{"before", metrics_json(r.before_fit)}, {"after", metrics_json(r.after_fit)}};
  j["check"] = {{"before", metrics_json(r.before_check)}, {"after", metrics_json(r.after_check)}};
  j["correlated_signals"] = r.correlated_signals;
  j["screening"] = {{"regressors", r.screening.regressors},
                    {"cells", r.screening.cells},
                    {"effective_samples", num(r.screening.effective_samples)},
                    {"rss_base_K2", num(r.screening.rss_base_k2)}};
  j["candidates"] = nlohmann::json::array();
  for (const auto& c : r.candidates) {
    const bool fitted = c.status == "effect" || c.status == "partial" || c.status == "rejected";
    nlohmann::json cj = {{"label", c.label},
                         {"effect", c.effect},
                         {"nodes", c.nodes},
                         {"variant", c.variant},
                         {"status", c.status},
                         {"accepted", c.status == "effect"},
                         {"reason", c.reason},
                         {"undecided", c.undecided},
                         {"explained_share", num(c.explained_share)},
                         {"screening_score", num(c.screening_score)},
                         {"stability", num(c.stability)}};
    if (fitted) {
      cj["fit_rmse_K"] = num(c.fit.rmse_k);
      cj["check_rmse_K"] = num(c.check.rmse_k);
      cj["bic"] = num(c.bic);
      cj["delta_bic"] = num(c.delta_bic);
      cj["check_factor"] = num(c.check_factor);
      cj["key_z"] = num(c.key_z);
      cj["identifiable"] = c.identifiable;
      cj["parameters"] = params_json(c.params);
      cj["quantities"] = quantities_json(c.quantities);
      if (c.fit_triggers.triggers > 0 || c.check_triggers.triggers > 0) {
        const auto cov = [](const TriggerCoverage& t) {
          return nlohmann::json{{"triggers", t.triggers}, {"while_running", t.while_running}, {"while_active", t.while_active},
                                {"max_left", num(t.max_state)}};
        };
        cj["trigger_coverage"] = {{"fit", cov(c.fit_triggers)}, {"check", cov(c.check_triggers)}};
      }
      cj["refit_iterations"] = c.refit_iterations;
      cj["refit_continuations"] = c.refit_continuations;
      cj["refit_converged"] = c.refit_converged;
      cj["seconds"] = num(c.seconds);
    }
    j["candidates"].push_back(cj);
  }
  j["diagnostics"] = nlohmann::json::array();
  for (const auto& d : r.diagnostics) {
    nlohmann::json cj = {{"column", d.column}, {"node", d.node}, {"rms_K", num(d.all.rms)}, {"lag1", num(d.all.lag1)},
                         {"ljung_box_p", num(d.all.p_value)}, {"operating_p", num(d.operating.p_value)},
                         {"cooling_p", num(d.cooling.p_value)}, {"white", d.white}};
    cj["correlations"] = nlohmann::json::array();
    for (const auto& t : d.correlations) cj["correlations"].push_back({{"signal", t.signal}, {"r", num(t.r)}, {"p", num(t.p_value)}});
    j["diagnostics"].push_back(cj);
  }
  j["trace"] = nlohmann::json::array();
  for (const auto& t : r.trace) j["trace"].push_back({{"node", t.node}, {"rms_W", num(t.rms_w)}});
  nlohmann::json bf;
  bf["rms_K"] = num(r.base_fit.rms_K);
  bf["converged"] = r.base_fit.converged;
  bf["gauge"] = r.base_fit.gauge;
  bf["parameters"] = nlohmann::json::array();
  for (const auto& e : r.base_fit.estimates)
    bf["parameters"].push_back({{"name", e.name}, {"unit", e.unit}, {"value", num(e.value)}, {"sigma", num(e.sigma)},
                                {"status", thermal::identifiability_name(e.status)}});
  j["base_fit"] = bf;
  j["base_fit_warnings"] = r.base_fit.warnings;  // as `btsm fit` prints them; [] with --use-values
  j["seconds"] = r.seconds;
  return j;
}

std::string format_table(const LoopResult& r) {
  std::ostringstream o;
  o << fmt::format("Residual loop on network '{}' ({} measured columns), noise sigma {:.3g} K, check measurement floor {:.3g} K\n",
                   r.base_net.name, r.columns.size(), r.noise_sigma_k, r.check_floor_k);
  o << "\nResidual tests of the base model (fit + check recordings; LB = Ljung-Box p-value):\n";
  o << fmt::format("  {:<10} {:<16} {:>9} {:>6} {:>9} {:>9} {:>9} {:>6}  {}\n", "column", "node", "rms [K]", "lag1", "LB all",
                   "LB oper.", "LB cool", "white", "strongest correlations (r)");
  for (const auto& d : r.diagnostics) {
    std::string cs;
    for (std::size_t i = 0; i < d.correlations.size() && i < 3; ++i)
      cs += (i ? ", " : "") + fmt::format("{} {:+.2f}", d.correlations[i].signal, d.correlations[i].r);
    o << fmt::format("  {:<10} {:<16} {:>9.4f} {:>6.2f} {:>9.2g} {:>9.2g} {:>9.2g} {:>6}  {}\n", d.column, d.node, d.all.rms, d.all.lag1,
                     d.all.p_value, d.operating.p_value, d.cooling.p_value, d.white ? "yes" : "no", cs);
  }
  if (!r.trace.empty()) {
    o << "\nUnexplained heat flow (inverse method on the residual, first fit recording), rms per node:\n";
    for (const auto& t : r.trace) o << fmt::format("  {:<16} {:>9.3f} W\n", t.node, t.rms_w);
  }
  o << fmt::format("\nProposals (linear screening of {} regressors, base refit projected out, effective samples {:.0f}) and "
                   "their joint refits (fit on --fit, scored on --check):\n",
                   r.screening.regressors, r.screening.effective_samples);
  o << fmt::format("  {:<46} {:>8} {:>7} {:>9} {:>10} {:>7} {:>9} {:>6}  {}\n", "candidate", "explains", "stable", "fit [K]",
                   "check [K]", "factor", "dBIC", "|z|", "status");
  for (const auto& c : r.candidates) {
    const bool fitted = c.status == "effect" || c.status == "partial" || c.status == "rejected";
    if (c.status == "refused") {
      o << fmt::format("  {:<46} {:>8} {:>7} {:>9} {:>10} {:>7} {:>9} {:>6}  refused: {}\n", c.label, "", "", "", "", "", "", "", c.reason);
      continue;
    }
    o << fmt::format("  {:<46} {:>7.1f}% {:>6.0f}% ", c.label, 100 * c.explained_share, 100 * c.stability);
    if (fitted)
      o << fmt::format("{:>9.4f} {:>10.4f} {:>7.2f} {:>9.1f} {:>6.1f}  {}\n", c.fit.rmse_k, c.check.rmse_k, c.check_factor, c.delta_bic,
                       c.key_z, c.status);
    else if (c.status == "failed")  // a fit that threw or diverged: no evidence, the reason instead
      o << fmt::format("{:>9} {:>10} {:>7} {:>9} {:>6}  failed: {}\n", "", "", "", "", "", c.reason);
    else
      o << fmt::format("{:>9} {:>10} {:>7} {:>9} {:>6}  {}\n", "", "", "", "", "", c.status);
    if (!c.variant.empty()) o << fmt::format("  {:<46} {}\n", "", c.variant);
    if (!c.undecided.empty()) o << fmt::format("  {:<46} the fit recordings cannot decide it: {}\n", "", c.undecided);
  }
  o << "\nVerdict: " << r.verdict;
  if (r.verdict == "effect" || r.verdict == "partial") o << " " << r.label;
  if (!r.nodes.empty()) o << "  (nodes: " << join(r.nodes) << ")";
  o << "\n  " << r.explanation << "\n";
  for (const auto& q : r.quantities)
    o << fmt::format("  {:<32} = {:+.5g} ± {:.2g} {}  ({})\n", q.name, q.value, q.sigma, q.unit, q.meaning);
  if (!r.correlated_signals.empty()) o << "  correlated signals: " << join(r.correlated_signals) << "\n";
  o << fmt::format("\n  {:<22} {:>10} {:>10} {:>10}\n", "errors", "RMSE [K]", "NMSE min", "max [K]");
  auto row = [&](const char* name, const ErrorMetrics& m) {
    o << fmt::format("  {:<22} {:>10.4f} {:>10.6f} {:>10.4f}\n", name, m.rmse_k, m.nmse_min, m.max_abs_k);
  };
  row("fit, before", r.before_fit);
  row("fit, after", r.after_fit);
  row("check, before", r.before_check);
  row("check, after", r.after_check);
  return o.str();
}

std::vector<io::OutputName> report_files() {
  std::vector<io::OutputName> files{{"residual_result.json", "residual result"}, {"residual_table.txt", "residual table"}};
  for (const char* stem : {"residual_model", "residual_residuals", "residual_heat_trace"})
    for (const char* ext : {".png", ".svg"}) files.push_back({std::string(stem) + ext, "plot"});
  return files;
}

void write_report(const LoopResult& r, const std::vector<thermal::Recording>& check, const std::string& dir,
                  const thermal::Recording* trace_recording) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create report directory " + dir + ": " + ec.message());
  io::write_output_file(dir + "/residual_result.json", to_json(r).dump(2) + "\n", "residual result");
  io::write_output_file(dir + "/residual_table.txt", format_table(r), "residual table");
  namespace rp = btsm::report;
  if (check.empty() || r.check_resid_before.empty()) return;
  const thermal::Recording& rec = check[0];
  const std::string rec_name = std::filesystem::path(rec.source).filename().string();
  const int nc = static_cast<int>(r.columns.size());
  const std::vector<double> t_h = rp::hours(rec.time_s);
  rp::FigureOptions style;
  for (const auto& n : r.base_net.nodes) style.key_order.push_back(n.name);  // colours as in every figure of this network
  auto node_of = [&](int c) { return c < static_cast<int>(r.diagnostics.size()) ? r.diagnostics[c].node : r.columns[c]; };
  auto column = [&](const Eigen::MatrixXd& m, int c) {
    std::vector<double> v(rec.rows());
    for (std::size_t k = 0; k < rec.rows(); ++k) v[k] = m(static_cast<Eigen::Index>(k), c);
    return v;
  };
  // the (up to) four columns with the largest residual before
  std::vector<std::pair<double, int>> order;
  for (int c = 0; c < nc; ++c) {
    double ss = 0;
    int n = 0;
    for (Eigen::Index k = 0; k < r.check_resid_before[0].rows(); ++k)
      if (std::isfinite(r.check_resid_before[0](k, c))) { ss += std::pow(r.check_resid_before[0](k, c), 2); ++n; }
    order.emplace_back(-(n ? ss / n : 0), c);
  }
  std::sort(order.begin(), order.end());
  std::vector<rp::Plot> model_panels;
  for (std::size_t i = 0; i < order.size() && i < 4; ++i) {
    const int c = order[i].second;
    const std::string node = node_of(c);
    rp::Plot p{fmt::format("{} ({}) — check recording {}", rp::display_name(node), r.columns[c], rec_name),
               rp::kTimeAxis, rp::kTemperatureAxis, {}};
    std::vector<double> meas = column(r.check_model_before[0], c);
    for (std::size_t k = 0; k < rec.rows(); ++k) meas[k] += r.check_resid_before[0](static_cast<Eigen::Index>(k), c);
    p.series.push_back(rp::measured(node, t_h, meas));
    p.series.push_back(rp::model(node, t_h, column(r.check_model_before[0], c), "base model"));
    if (r.chosen >= 0)
      p.series.push_back(rp::alternative(node, t_h, column(r.check_model_after[0], c), (r.verdict == "partial" ? "partly, with " : "with ") + r.label));
    model_panels.push_back(p);
  }
  model_panels.push_back(rp::recording_speed_panel(rec));
  rp::add_event_spans(model_panels, rec);
  rp::save_figure(model_panels, dir + "/residual_model", style);
  std::vector<rp::Plot> res_panels;
  auto residual_plot = [&](const std::vector<Eigen::MatrixXd>& res, const std::string& title) {
    rp::Plot p{title, rp::kTimeAxis, rp::kResidualAxis, {}};
    for (int c = 0; c < nc; ++c) p.series.push_back(rp::trace(node_of(c), t_h, column(res[0], c)));
    return p;
  };
  res_panels.push_back(residual_plot(r.check_resid_before, "Residuals of the base model (check recording " + rec_name + ")"));
  if (r.chosen >= 0)
    res_panels.push_back(residual_plot(r.check_resid_after, (r.verdict == "partial" ? "Residuals with the partial explanation " : "Residuals with ") + r.label));
  if (!r.check_distortion.empty()) {
    rp::Plot p{"Estimated measurement distortion (reading − node temperature)", rp::kTimeAxis, "distortion (K)", {}};
    for (int c = 0; c < nc; ++c) {
      if (r.check_distortion[0].col(c).cwiseAbs().maxCoeff() == 0) continue;
      p.series.push_back(rp::trace(node_of(c), t_h, column(r.check_distortion[0], c)));
    }
    res_panels.push_back(p);
  }
  res_panels.push_back(rp::recording_speed_panel(rec));
  rp::add_event_spans(res_panels, rec);
  rp::save_figure(res_panels, dir + "/residual_residuals", style);
  if (!r.trace.empty()) {
    const std::string trace_name =
        trace_recording ? std::filesystem::path(trace_recording->source).filename().string() : std::string("first fit recording");
    rp::Plot p{"Unexplained heat flow per node (inverse method on the base-model residual, " + trace_name + ")",
               rp::kTimeAxis, rp::kHeatAxis, {}};
    for (const auto& t : r.trace) p.series.push_back(rp::trace(t.node, rp::hours(t.time_s), t.heat_w, rp::Series::Style::Step));
    std::vector<rp::Plot> trace_panels{p};
    // Heat that follows the speed is read against it, as in every other time plot.
    if (trace_recording) {
      trace_panels.push_back(rp::recording_speed_panel(*trace_recording));
      rp::add_event_spans(trace_panels, *trace_recording);
    } else {
      style.panel_height = 420;
    }
    rp::save_figure(trace_panels, dir + "/residual_heat_trace", style);
  }
}

}  // namespace btsm::residual
