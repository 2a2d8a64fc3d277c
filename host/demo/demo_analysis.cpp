#include "host/demo/demo_analysis.hpp"

#include "common/reduced_model.hpp"
#include "host/report/plot_style.hpp"
#include "host/report/thermal_figures.hpp"
#include "host/residual/residual_loop.hpp"
#include "host/residual/residual_report.hpp"
#include "host/thermal/fit.hpp"
#include "host/thermal/model_file.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"
#include "host/thermal/reduce.hpp"
#include "host/thermal/simulator.hpp"
#include "host/thermal/validate.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

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

// Residual bands from the firmware model's own error on the identification recordings. A
// first-order model cannot follow every fast transient of the spindle (the bearings cool quickly
// into the housing after a stop, for instance), so fixed bands would raise false alarms on normal
// running. The module's model (fixed point, exactly as it runs, started from the first measured row
// like after a boot) is replayed over every recording; per channel the ALARM band is the worst
// normal residual x `margin` (at least `floor_K`), WARN half of it. Returned per channel, K.
struct BandCalibration {
  double worst_K[kModelChannels] = {};
  double warn_K[kModelChannels] = {};
  double alarm_K[kModelChannels] = {};
};

BandCalibration calibrate_bands(ReducedModel& q, const std::vector<const thermal::Recording*>& recs,
                                const char* const columns[kModelChannels], double margin, double floor_K) {
  BandCalibration cal;
  for (const thermal::Recording* rec : recs) {
    int col[kModelChannels];
    for (int j = 0; j < kModelChannels; ++j) col[j] = columns[j] ? rec->channel_index(columns[j]) : -1;
    ReducedModelState st{};
    reset(st);
    for (size_t i = 0; i < rec->rows(); ++i) {
      const auto rpm = static_cast<uint16_t>(std::clamp(std::lround(rec->speed_rpm[i]), 0L, 65535L));
      const auto amb = static_cast<int32_t>(std::lround(rec->ambient_c[i] * 1000));
      int32_t meas[kModelChannels];
      for (int j = 0; j < kModelChannels; ++j) {
        const double v = col[j] >= 0 ? rec->temp_c(static_cast<Eigen::Index>(i), col[j]) : NAN;
        meas[j] = std::isfinite(v) ? static_cast<int32_t>(std::lround(v * 1000)) : kModelNoPrediction;
      }
      if (i == 0) init_from_measurement(q, st, rpm, amb, meas);
      int32_t pred[kModelChannels];
      step(q, st, rpm, amb, pred);
      for (int j = 0; j < kModelChannels; ++j)
        if (meas[j] != kModelNoPrediction && pred[j] != kModelNoPrediction && j != q.ambient_channel)
          cal.worst_K[j] = std::max(cal.worst_K[j], std::abs(meas[j] - pred[j]) / 1000.0);
    }
  }
  for (int j = 0; j < kModelChannels; ++j) {
    if (((q.enabled_mask >> j) & 1U) == 0 || j == q.ambient_channel) continue;
    cal.alarm_K[j] = std::min(60.0, std::max(floor_K, margin * cal.worst_K[j]));
    cal.warn_K[j] = 0.5 * cal.alarm_K[j];
    q.limits[j].alarm_band_mK = static_cast<uint16_t>(std::lround(cal.alarm_K[j] * 1000));
    q.limits[j].warn_band_mK = static_cast<uint16_t>(std::lround(cal.warn_K[j] * 1000));
  }
  return cal;
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
  residual::write_report(loop, check_recs, (dir / "residual").string());
  {
    std::ofstream j(dir / "residual" / "residual.json");
    j << residual::to_json(loop).dump(2) << "\n";
  }
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
  thermal::ReduceOptions ro;
  ro.speeds_rpm = in.reduce_speeds_rpm;
  ro.dt_s = in.sample_period_s;
  ro.channel_node = {{0, 1, 2, -1, 3}};  // ch5 = the probe on the shaft end
  progress("reducing to the speed-scheduled first-order model");
  const thermal::ScheduledReduction red = thermal::build_scheduled_model(final_net, final_params, ro);
  if (red.blob.empty()) {
    out.failures.push_back("the reduced model could not be quantized into the firmware blob");
    return out;
  }
  // Residual bands from the model's own error on everything recorded (fit and check runs).
  ReducedModel q = red.quantized;
  std::vector<const thermal::Recording*> all_recs;
  for (const auto& r : fit_recs) all_recs.push_back(&r);
  for (const auto& r : check_recs) all_recs.push_back(&r);
  const char* const channel_columns[kModelChannels] = {"T1", "T2", "T3", nullptr, "T5"};
  const BandCalibration bands = calibrate_bands(q, all_recs, channel_columns, in.band_margin, in.band_floor_K);
  out.blob.assign(kReducedModelBlobSize, 0);
  encode(q, out.blob.data());
  ReducedModel check{};
  if (!decode(out.blob.data(), out.blob.size(), check).ok()) {
    out.failures.push_back("the reduced model with calibrated bands does not pass its own validation");
    return out;
  }
  for (int j = 0; j < kModelChannels; ++j) out.alarm_band_K[j] = bands.alarm_K[j];
  out.quantized_vs_full_max_K = red.deviation.quantized_vs_full_max_K;
  out.reduced_json = (dir / "models" / "reduced_model.json").string();
  nlohmann::json rj = thermal::reduction_to_json(final_net, red, ro);
  {
    nlohmann::json cb = nlohmann::json::array();
    for (int j = 0; j < kModelChannels; ++j)
      cb.push_back({{"channel", j + 1}, {"worst_normal_residual_K", bands.worst_K[j]}, {"warn_band_K", bands.warn_K[j]},
                    {"alarm_band_K", bands.alarm_K[j]}});
    rj["diagnosis_calibrated"] = cb;
    std::string hex;
    for (uint8_t b : out.blob) hex += fmt::format("{:02x}", b);
    rj["blob_hex"] = hex;  // what `btsm flash-model` sends (bands above included)
  }
  thermal::save_json(out.reduced_json, rj);
  {
    std::ofstream b(dir / "models" / "reduced_model.bin", std::ios::binary);
    b.write(reinterpret_cast<const char*>(out.blob.data()), static_cast<std::streamsize>(out.blob.size()));
  }
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
    reset(st);
    const double dt = in.sample_period_s;
    const std::vector<std::pair<double, double>> prof = {{3 * 3600, 6000}, {2 * 3600, 3000}, {2 * 3600, 8000}, {3 * 3600, 0}};
    std::vector<double> t_h, f1, r1, f3, r3, rpm_trace;
    double t = 0;
    for (const auto& [dur, rpm] : prof)
      for (double s = 0; s < dur; s += dt, t += dt) {
        int32_t pred[kModelChannels];
        step(q, st, static_cast<uint16_t>(rpm), static_cast<int32_t>(std::lround(amb * 1000)), pred);
        t_h.push_back(t / 3600);
        f1.push_back(full.node_temp_c()[0]);
        f3.push_back(full.node_temp_c()[2]);
        r1.push_back(pred[0] / 1000.0);
        r3.push_back(pred[2] / 1000.0);
        rpm_trace.push_back(rpm);
        full.step(dt, rpm, amb);
      }
    report::Plot temps{"Firmware model (fixed point) vs the full model", report::kTimeAxis, report::kTemperatureAxis,
                       {report::model("rear_bearing", t_h, f1, "full model"),
                        report::alternative("rear_bearing", t_h, r1, "firmware model"),
                        report::model("front_bearing", t_h, f3, "full model"),
                        report::alternative("front_bearing", t_h, r3, "firmware model")}};
    report::save_figure({temps, report::speed_panel(t_h, rpm_trace)}, (dir / "reduced_vs_full").string(),
                        report::network_figure_options(final_net));
  }
  page.heading("4. Reduction to the module's speed-scheduled first-order model");
  page.paragraph(fmt::format("Model reduced: {}. DC-matched (singular perturbation) first-order models at each speed; the "
                             "quantized firmware model deviates from the full model by at most {:.3f} K and from its "
                             "double-precision reduction by {:.4f} K over {}.",
                             final_net.name, red.deviation.quantized_vs_full_max_K,
                             red.deviation.quantized_vs_double_max_K, red.deviation.profile));
  page.table({"speed (rpm)", "largest HSV (K/W)", "slowest full pole (1/s)", "BT pole (1/s)", "DC-matched pole (1/s)"}, rrow);
  {
    std::vector<std::vector<std::string>> brow;
    const char* names[kModelChannels] = {"T1 rear bearing", "T2 housing", "T3 front bearing", "T4 ambient", "T5 shaft end"};
    for (int j = 0; j < kModelChannels; ++j)
      if (bands.alarm_K[j] > 0)
        brow.push_back({names[j], fmt::format("{:.2f}", bands.worst_K[j]), fmt::format("{:.2f}", bands.warn_K[j]),
                        fmt::format("{:.2f}", bands.alarm_K[j])});
    page.paragraph(fmt::format("Residual bands: the firmware model replayed over every recording (started from the first "
                               "measured row, as after a boot); ALARM = {:.1f} x its worst normal residual (at least "
                               "{:.1f} K), WARN = half of that.", in.band_margin, in.band_floor_K));
    page.table({"channel", "worst normal residual (K)", "WARN band (K)", "ALARM band (K)"}, brow);
  }
  page.image("hankel_singular_values.png", "Hankel singular values: one dominant state at every speed");
  page.image("reduced_vs_full.png", "The module's fixed-point first-order model against the full network");
  return out;
}

}  // namespace btsm::demo
