// Detector calibration from recordings of normal running (rule in the header).
#include "detector_calibration.hpp"

#include "common/diagnosis.hpp"
#include "common/model_step.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace btsm::thermal {

std::string DetectorRule::describe() const {
  return fmt::format(
      "replay of the module's model over the recordings; per channel drift = max({:g} K, {:g} x worst residual above "
      "the model) and lower drift the same below, "
      "WARN = {:g} x worst upper evidence + {:g} K min, ALARM = {:g} x WARN, lower WARN = {:g} x worst lower evidence + {:g} K min",
      drift_floor_K, drift_fraction, margin, evidence_floor_K_min, alarm_factor, margin, evidence_floor_K_min);
}

std::array<std::vector<double>, kModelChannels> replay_residuals(const ReducedModel& q, const Recording& rec,
                                                                 const std::array<std::string, kModelChannels>& columns) {
  std::array<std::vector<double>, kModelChannels> out;
  int col[kModelChannels];
  for (int j = 0; j < kModelChannels; ++j) {
    col[j] = -1;
    const auto c = static_cast<std::size_t>(j);
    if (columns[c].empty() || !model_predicts(q.schedule.enabled_mask, q.schedule.ambient_channel, static_cast<uint8_t>(j)))
      continue;
    col[j] = rec.channel_index(columns[c]);
    if (col[j] < 0)
      throw std::invalid_argument(rec.source + ": no column '" + columns[c] + "' for channel " + std::to_string(j + 1));
  }
  if (rec.rows() == 0) return out;
  const double dt = q.schedule.dt_ms * 1e-3;
  ReducedModelState st{};
  bool started = false;
  double next_step = 0;
  for (std::size_t i = 0; i < rec.rows(); ++i) {
    const auto rpm = static_cast<uint16_t>(std::clamp(std::lround(rec.speed_rpm[i]), 0L, 65535L));
    const auto amb = static_cast<int32_t>(std::lround(rec.ambient_c[i] * 1000));
    int32_t meas[kModelChannels];
    for (int j = 0; j < kModelChannels; ++j) {
      const double v = col[j] >= 0 ? rec.temp_c(static_cast<Eigen::Index>(i), col[j]) : NAN;
      meas[j] = std::isfinite(v) ? static_cast<int32_t>(std::lround(v * 1000)) : kModelNoPrediction;
    }
    if (!started) {  // as after a boot: every channel from its first reading
      started = init_from_measurement(q.schedule.ambient_channel, q.schedule.enabled_mask, st, amb, meas);
      next_step = rec.time_s[i] + dt;
      continue;
    }
    // The module steps once per elapsed dt (its sweeps and model steps share the schedule).
    while (rec.time_s[i] + 1e-9 >= next_step) {
      int32_t pred[kModelChannels];
      step(q, st, rpm, amb, pred);
      for (int j = 0; j < kModelChannels; ++j)
        if (col[j] >= 0 && meas[j] != kModelNoPrediction && pred[j] != kModelNoPrediction)
          out[static_cast<std::size_t>(j)].push_back((meas[j] - pred[j]) / 1000.0);
      next_step += dt;
    }
  }
  return out;
}

std::pair<double, double> worst_evidence(const std::vector<std::vector<double>>& residuals, double drift_K,
                                         double low_drift_K, uint16_t dt_ms) {
  const double per_sample_to_K_min = dt_ms / 60000.0;
  double hi = 0, lo = 0;
  for (const auto& series : residuals) {
    double h = 0, l = 0;
    for (double r : series) {
      h = std::max(0.0, h + r - drift_K);
      l = std::max(0.0, l - r - low_drift_K);
      hi = std::max(hi, h);
      lo = std::max(lo, l);
    }
  }
  return {hi * per_sample_to_K_min, lo * per_sample_to_K_min};
}

DetectorCalibration calibrate_detector(const ReducedModel& q, const ReducedModelF64& model,
                                       const std::vector<const Recording*>& recordings,
                                       const std::array<std::string, kModelChannels>& columns, const DetectorRule& rule) {
  if (recordings.empty()) throw std::invalid_argument("detector calibration: no recordings");
  if (!(rule.margin >= 1.0) || !(rule.alarm_factor > 1.0) || !(rule.drift_fraction >= 0 && rule.drift_fraction <= 1) ||
      !(rule.drift_floor_K > 0) || !(rule.evidence_floor_K_min > 0))
    throw std::invalid_argument("detector calibration: need margin >= 1, alarm factor > 1, 0 <= drift fraction <= 1, floors > 0");
  DetectorCalibration out;
  out.recordings = recordings.size();
  out.rule = rule.describe();
  std::array<std::vector<std::vector<double>>, kModelChannels> res;
  for (const Recording* rec : recordings) {
    auto r = replay_residuals(q, *rec, columns);
    for (int j = 0; j < kModelChannels; ++j) res[static_cast<std::size_t>(j)].push_back(std::move(r[static_cast<std::size_t>(j)]));
  }
  for (int j = 0; j < kModelChannels; ++j) {
    const auto c = static_cast<std::size_t>(j);
    ChannelCalibration& cc = out.channels[c];
    cc.detector = model.detector[j];
    cc.column = columns[c];
    for (const auto& s : res[c]) {
      cc.samples += s.size();
      for (double v : s) {
        cc.worst_above_K = std::max(cc.worst_above_K, v);
        cc.worst_below_K = std::max(cc.worst_below_K, -v);
      }
    }
    if (cc.samples == 0) continue;
    cc.diagnosed = true;
    cc.worst_residual_K = std::max(cc.worst_above_K, cc.worst_below_K);
    const double drift = std::max(rule.drift_floor_K, rule.drift_fraction * cc.worst_above_K);
    const double low_drift = std::max(rule.drift_floor_K, rule.drift_fraction * cc.worst_below_K);
    const auto [hi, lo] = worst_evidence(res[c], drift, low_drift, q.schedule.dt_ms);
    cc.worst_high_K_min = hi;
    cc.worst_low_K_min = lo;
    cc.detector.drift_K = drift;
    cc.detector.low_drift_K = low_drift;
    cc.detector.warn_evidence_K_min = rule.margin * hi + rule.evidence_floor_K_min;
    cc.detector.alarm_evidence_K_min = rule.alarm_factor * cc.detector.warn_evidence_K_min;
    cc.detector.low_warn_evidence_K_min = rule.margin * lo + rule.evidence_floor_K_min;
  }
  return out;
}

void apply_calibration(const DetectorCalibration& c, ReducedModelF64& model) {
  for (int j = 0; j < kModelChannels; ++j)
    if (c.channels[static_cast<std::size_t>(j)].diagnosed) model.detector[j] = c.channels[static_cast<std::size_t>(j)].detector;
}

}  // namespace btsm::thermal
