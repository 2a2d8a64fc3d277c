#include "host/demo/demo_analysis.hpp"

#include "common/model_blob.hpp"
#include "common/model_step.hpp"
#include "host/io/output_file.hpp"
#include "host/report/plot_style.hpp"
#include "host/report/thermal_figures.hpp"
#include "host/residual/residual_loop.hpp"
#include "host/residual/residual_report.hpp"
#include "host/thermal/detector_calibration.hpp"
#include "host/thermal/fit.hpp"
#include "host/thermal/model_file.hpp"
#include "host/thermal/time_constant_text.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"
#include "host/thermal/reduce.hpp"
#include "host/thermal/simulator.hpp"
#include "host/thermal/validate.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

namespace fs = std::filesystem;

namespace btsm::demo {
namespace {

// The module measures the rear bearing, housing and front bearing on ch1..ch3 (recorded as T1..T3),
// ambient on ch4 (ambient_c) and the shaft through the probe on the stationary shaft end on ch5
// (recorded as T5). Without that fifth probe the shaft node is not observable enough to identify
// the paper's network (the fit then leaves it to the output error alone and crawls).
thermal::Network demo_network() {
  thermal::Network net = thermal::preset_network("spindle4");
  thermal::remap_measurements(net, {"shaft=T5"});  // as `btsm fit --column shaft=T5`
  return net;
}

std::string fmt_g(double v, int digits = 4) { return fmt::format("{:.{}g}", v, digits); }

void plot_validation(const thermal::Network& net, const thermal::Recording& rec, const thermal::RecordingValidation& v,
                     const std::string& stem, const std::string& title) {
  report::save_figure(report::validation_figure(net, rec, v, title), stem, report::network_figure_options(net));
}

}  // namespace

AnalysisOutputs analyse(const AnalysisInputs& in, report::HtmlReport& page) {
  AnalysisOutputs out;
  auto progress = [&](const std::string& s) { if (in.progress) in.progress(s); };
  const fs::path dir(in.out_dir);
  std::vector<thermal::Recording> fit_recs, check_recs;
  for (const auto& p : in.fit_csv) fit_recs.push_back(thermal::read_recording_csv(p));
  for (const auto& p : in.check_csv) check_recs.push_back(thermal::read_recording_csv(p));

  // --- Fit the paper's network -----------------------------------------------------------------
  const thermal::Network net = demo_network();
  thermal::FitOptions fo;
  fo.sum_capacitance_J_per_K = 20478.7;  // the spindle's mass x c_p: the scale gauge
  fo.max_iterations = 400;
  fo.start_iterations = 400;
  fo.progress = [&](const std::string& s) { progress("fit: " + s); };
  progress(fmt::format("fitting spindle4 (T1..T3 and the shaft on T5 measured) to {} recordings", fit_recs.size()));
  const thermal::FitResult fit = thermal::fit_network(net, fit_recs, fo);
  out.model_json = (dir / "models" / "full_model.json").string();
  thermal::save_json(out.model_json, thermal::model_to_json(net, fit, fit_recs));
  std::vector<std::vector<std::string>> prow;
  int weak = 0;
  for (const auto& e : fit.estimates) {
    prow.push_back({e.name, e.unit, fmt_g(e.value), fmt_g(e.sigma, 2), thermal::identifiability_name(e.status)});
    if (e.status == thermal::Identifiability::Weak || e.status == thermal::Identifiability::NotIdentifiable) ++weak;
  }
  page.heading("2. Full thermal network fitted (Lo, Hu & Chang 2018, heat balances A2)");
  page.paragraph(fmt::format("Gauge: {}. Residual rms {:.4f} K over {} values in {:.2f} s; {} of {} parameters are weakly "
                             "or not identifiable from these recordings and are reported so.",
                             fit.gauge, fit.rms_K, fit.residual_count, fit.seconds, weak, fit.estimates.size()));
  page.table({"parameter", "unit", "value", "1σ", "identifiability"}, prow);

  // --- Validation, self and external --------------------------------------------------------------
  std::vector<std::vector<std::string>> vrow;
  auto validate_set = [&](const std::vector<thermal::Recording>& recs, const char* kind) {
    for (const auto& rec : recs) {
      const auto v = thermal::validate_recording(net, fit.params, rec);
      for (size_t m = 0; m < net.measurements.size(); ++m)
        vrow.push_back({fs::path(rec.source).stem().string(), kind, net.measurements[m].column,
                        fmt::format("{:.6f}", v.all[m].nmse), fmt::format("{:.4f}", v.all[m].rmse_K),
                        fmt::format("{:.4f}", v.all[m].max_abs_K)});
      if (std::string(kind) == "external")
        plot_validation(net, rec, v, (dir / "validation_external").string(), fs::path(rec.source).stem().string());
    }
  };
  validate_set(fit_recs, "self");
  validate_set(check_recs, "external");
  page.heading("3. Validation of the base model");
  page.table({"recording", "validation", "node", "NMSE", "RMSE (K)", "max |e| (K)"}, vrow);
  page.image("validation_external.png", "External validation run: measured vs the fitted base model, and residuals");

  // --- The residual loop ---------------------------------------------------------------------------
  progress("residual loop: testing residuals, tracing unexplained heat, trying the effect library");
  residual::LoopOptions lo;
  lo.fit_base = true;  // candidates refit the base jointly (it has absorbed part of the effect); it starts from the fit above
  lo.progress = [&](const std::string& s) { progress(s); };  // the loop prefixes "residual:" itself
  const residual::LoopResult loop = residual::run_residual_loop(net, fit.params, fit_recs, check_recs, lo);
  fs::create_directories(dir / "residual");
  residual::write_report(loop, check_recs, (dir / "residual").string(), fit_recs.empty() ? nullptr : &fit_recs.front());
  io::write_output_file((dir / "residual" / "residual.json").string(), residual::to_json(loop).dump(2) + "\n", "residual result");
  out.effect = loop.label.empty() ? loop.effect : loop.label;
  out.effect_nodes = loop.nodes;
  out.check_rmse_before_K = loop.before_check.rmse_k;
  out.check_rmse_after_K = loop.after_check.rmse_k;
  progress(fmt::format("residual loop: effect {} — check RMSE {:.4f} K -> {:.4f} K", out.effect,
                       out.check_rmse_before_K, out.check_rmse_after_K));
  page.heading("3b. Residual loop: what the paper's model lacks");
  page.paragraph(loop.explanation);
  page.preformatted(residual::format_table(loop));
  page.image("residual/residual_model.png", "Check recordings: measured vs the base model and the model with the effect");
  page.image("residual/residual_residuals.png", "Residuals before and after adding the effect");
  page.image("residual/residual_heat_trace.png", "Unexplained heat flow per node, estimated inversely from the base model's residual");

  // --- Reduce the (augmented) model to the firmware's first-order model ----------------------------
  thermal::Network final_net = net;
  Eigen::VectorXd final_params = fit.params;
  if (loop.verdict == "effect" && loop.candidates[loop.chosen].transient_node < 0) {
    final_net = loop.candidates[loop.chosen].net;
    final_params = loop.candidates[loop.chosen].values;
  }
  {
    // The model that is reduced (the base fit with the effect found, if one was), as a model JSON
    // `btsm reduce` reads.
    nlohmann::json fj;
    fj["format"] = thermal::kFittedModelFormat;
    fj["network"] = thermal::network_to_json(final_net);
    for (int i = 0; i < final_net.param_count(); ++i) fj["parameters"][final_net.params[static_cast<std::size_t>(i)].name] = final_params[i];
    fj["channel_map"] = thermal::channel_map_json(final_net, fit_recs);
    thermal::save_json((dir / "models" / "final_model.json").string(), fj);
  }
  thermal::ReduceOptions ro;
  ro.speeds_rpm = in.reduce_speeds_rpm;
  ro.dt_s = in.sample_period_s;
  ro.channel_node = {{0, 1, 2, -1, 3}};  // ch5 = the probe on the shaft end
  for (const auto* set : {&fit_recs, &check_recs})  // the duty cycle runs up to the recorded top speed
    for (const auto& r : *set)
      for (double v : r.speed_rpm) ro.duty_max_rpm = std::max(ro.duty_max_rpm, v);
  progress("reducing to one first-order model per channel");
  thermal::ScheduledReduction red = thermal::build_scheduled_model(final_net, final_params, ro);
  if (red.blob.empty()) {
    out.failures.push_back("the reduced model could not be quantized into the firmware blob");
    return out;
  }
  // The detector from the model's own residuals on everything recorded (fit and check runs).
  std::vector<const thermal::Recording*> all_recs;
  for (const auto& r : fit_recs) all_recs.push_back(&r);
  for (const auto& r : check_recs) all_recs.push_back(&r);
  const std::array<std::string, kModelChannels> channel_columns = {"T1", "T2", "T3", "", "T5"};
  const thermal::DetectorCalibration cal =
      thermal::calibrate_detector(red, all_recs, channel_columns, in.detector_rule);
  thermal::apply_calibration(cal, red.model);
  thermal::requantize(red);
  if (red.blob.empty()) {
    out.failures.push_back(std::string("the calibrated detector does not fit the blob: ") +
                           model_status_name(red.quantize_status.status));
    return out;
  }
  out.blob = red.blob;
  ReducedModel check{};
  if (!decode(out.blob.data(), out.blob.size(), check).ok()) {
    out.failures.push_back("the reduced model with the calibrated detector does not pass its own validation");
    return out;
  }
  for (int j = 0; j < kModelChannels; ++j) {
    const auto c = static_cast<std::size_t>(j);
    out.deviation_vs_full_K[j] = red.deviation.quantized_vs_full_K[c];
    if (!cal.channels[c].diagnosed) continue;
    out.worst_residual_K[j] = cal.channels[c].worst_residual_K;
    out.drift_K[j] = cal.channels[c].detector.drift_K;
    out.alarm_evidence_K_min[j] = cal.channels[c].detector.alarm_evidence_K_min;
  }
  out.quantized_vs_full_max_K = red.deviation.quantized_vs_full_max_K;
  out.reduced_json = (dir / "models" / "reduced_model.json").string();
  nlohmann::json rj = thermal::reduction_to_json(final_net, red, ro);
  {
    nlohmann::json cb = nlohmann::json::array();
    for (int j = 0; j < kModelChannels; ++j) {
      const auto& cc = cal.channels[static_cast<std::size_t>(j)];
      if (!cc.diagnosed) continue;
      cb.push_back({{"channel", j + 1}, {"column", cc.column}, {"worst_normal_residual_K", cc.worst_residual_K},
                    {"worst_upper_evidence_K_min", cc.worst_high_K_min}, {"worst_lower_evidence_K_min", cc.worst_low_K_min},
                    {"design_fault_alarm_min", cc.design_alarm_min},
                    {"worst_above_K", cc.worst_above_K}, {"worst_below_K", cc.worst_below_K},
                    {"drift_K", cc.detector.drift_K}, {"low_drift_K", cc.detector.low_drift_K},
                    {"warn_evidence_K_min", cc.detector.warn_evidence_K_min},
                    {"alarm_evidence_K_min", cc.detector.alarm_evidence_K_min},
                    {"low_warn_evidence_K_min", cc.detector.low_warn_evidence_K_min}});
    }
    rj["detector_calibration"] = {{"rule", cal.rule}, {"recordings", cal.recordings}, {"channels", cb}};
  }
  thermal::save_json(out.reduced_json, rj);
  io::write_output_file((dir / "models" / "reduced_model.bin").string(),
                        std::string_view(reinterpret_cast<const char*>(out.blob.data()), out.blob.size()), "model blob");
  std::vector<std::vector<std::string>> rrow;
  report::Plot hsv{"Hankel singular values per speed", "state index", "Hankel singular value (K/W)", {}, true};
  for (const auto& s : red.speeds) {
    std::vector<double> idx, v;
    for (int i = 0; i < s.hsv.size(); ++i) idx.push_back(i + 1), v.push_back(s.hsv[i]);
    hsv.series.push_back({fmt::format("{:.0f} rpm", s.speed_rpm), idx, v});
    rrow.push_back({fmt::format("{:.0f}", s.speed_rpm), fmt_g(s.hsv[0]), fmt_g(s.poles[s.poles.size() - 1]),
                    fmt_g(s.bt.pole), fmt_g(s.dc.pole)});
  }
  report::save_plot(hsv, (dir / "hankel_singular_values").string());

  // Reduced (fixed point, as the module runs it) vs the full model over a speed profile.
  {
    thermal::Simulator full(final_net, final_params);
    const double amb = 20.0;
    full.reset(Eigen::VectorXd::Constant(final_net.node_count(), amb));
    ReducedModel q{};
    decode(out.blob.data(), out.blob.size(), q);
    ReducedModelState st{};
    init_at_ambient(st, static_cast<int32_t>(std::lround(amb * 1000)));
    const double dt = in.sample_period_s;
    const std::vector<std::pair<double, double>> prof = {{3 * 3600, 6000}, {2 * 3600, 3000}, {0.5 * 3600, 0},
                                                         {2 * 3600, 8000}, {3 * 3600, 0}};
    const int channels[4] = {0, 1, 2, 4};
    const int nodes[4] = {0, 1, 2, 3};  // rear bearing, housing, front bearing, shaft (its probe on ch5)
    std::vector<double> t_h, f[4], r[4], rpm_trace;
    double t = 0;
    for (const auto& [dur, rpm] : prof)
      for (double s = 0; s < dur; s += dt, t += dt) {
        int32_t pred[kModelChannels];
        step(q, st, static_cast<uint16_t>(rpm), static_cast<int32_t>(std::lround(amb * 1000)), pred);
        t_h.push_back(t / 3600);
        for (int k = 0; k < 4; ++k) {
          f[k].push_back(full.node_temp_c()[nodes[k]]);
          r[k].push_back(pred[channels[k]] / 1000.0);
        }
        rpm_trace.push_back(rpm);
        full.step(dt, rpm, amb);
      }
    report::Plot temps{"Module model (fixed point, one per channel) vs the full network", report::kTimeAxis,
                       report::kTemperatureAxis, {}};
    for (int k = 0; k < 4; ++k) {
      const std::string node = final_net.nodes[static_cast<std::size_t>(nodes[k])].name;
      temps.series.push_back(report::model(node, t_h, f[k], "full network"));
      temps.series.push_back(report::alternative(node, t_h, r[k], "module model"));
    }
    report::save_figure({temps, report::speed_panel(t_h, rpm_trace)}, (dir / "reduced_vs_full").string(),
                        report::network_figure_options(final_net));
  }
  page.heading("4. Reduction to the module's model: one first-order model per channel");
  page.paragraph(fmt::format("Model reduced: {}. Each diagnosed channel has its own speed-scheduled first-order model "
                             "(DC-matched; own poles while stopped, scheduled on the time since the stop). The quantized "
                             "module model deviates from the full network by at most {:.3f} K (per channel: T1 {:.2f}, T2 "
                             "{:.2f}, T3 {:.2f}, T5 {:.2f} K) and from its double-precision reduction by {:.4f} K over {}.",
                             final_net.name, red.deviation.quantized_vs_full_max_K, red.deviation.quantized_vs_full_K[0],
                             red.deviation.quantized_vs_full_K[1], red.deviation.quantized_vs_full_K[2],
                             red.deviation.quantized_vs_full_K[4], red.deviation.quantized_vs_double_max_K,
                             red.deviation.profile));
  page.table({"speed (rpm)", "largest HSV (K/W)", "slowest full pole (1/s)", "BT pole (1/s)", "DC-matched pole (1/s)"}, rrow);
  {
    std::vector<std::vector<std::string>> trow;
    const char* names[kModelChannels] = {"T1 rear bearing", "T2 housing", "T3 front bearing", "T4 ambient", "T5 shaft end"};
    for (int j = 0; j < kModelChannels; ++j) {
      const auto& cr = red.channels[static_cast<std::size_t>(j)];
      if (cr.node < 0) continue;
      std::string taus;
      for (std::size_t i = 1; i < cr.tau_s.size(); ++i) taus += fmt::format("{}{:.0f}", i > 1 ? " / " : "", cr.tau_s[i] / 60);
      trow.push_back({names[j], taus, fmt::format("{} / {} / {:.0f}", thermal::stop_time_constant_text(cr.stop_tau_s[0]), thermal::stop_time_constant_text(cr.stop_tau_s[1]), cr.tau_s[0] / 60)});
    }
    page.table({"channel", "time constant running (min, per speed)", "time constants stopped (min, per phase)"}, trow);
    std::vector<std::vector<std::string>> brow;
    for (int j = 0; j < kModelChannels; ++j) {
      const auto& cc = cal.channels[static_cast<std::size_t>(j)];
      if (!cc.diagnosed) continue;
      brow.push_back({names[j], fmt::format("{:.2f} / {:.2f}", cc.worst_above_K, cc.worst_below_K),
                      fmt::format("{:.2f} / {:.2f}", cc.detector.drift_K, cc.detector.low_drift_K),
                      fmt::format("{:.2f}", cc.worst_high_K_min), fmt::format("{:.2f}", cc.detector.warn_evidence_K_min),
                      fmt::format("{:.2f}", cc.detector.alarm_evidence_K_min),
                      fmt::format("{:.2f}", cc.detector.low_warn_evidence_K_min)});
    }
    page.paragraph("Detector: " + cal.rule + ".");
    page.table({"channel", "worst normal residual above / below (K)", "drift above / below (K)", "worst upper evidence (K min)", "WARN (K min)",
                "ALARM (K min)", "lower WARN (K min)"},
               brow);
  }
  page.image("hankel_singular_values.png", "Hankel singular values: one dominant state at every speed");
  page.image("reduced_vs_full.png", "The module's fixed-point first-order model against the full network");
  return out;
}

}  // namespace btsm::demo
