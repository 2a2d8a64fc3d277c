// Detector calibration from recordings of normal running (rule in the header).
#include "detector_calibration.hpp"

#include "common/diagnosis.hpp"
#include "common/model_step.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace btsm::thermal {

std::string DetectorRule::describe(const FaultSignature& design) const {
  return fmt::format(
      "the module's model replayed over the recordings{}; per channel and side, for each drift d in steps of {:g} K: "
      "WARN = {:g} x worst evidence + {:g} K min, ALARM = {:g} x WARN; the drift whose ALARM (lower: WARN) {:g} W more "
      "at the channel's node at {:.0f} rpm reaches soonest, the lower drift not below the upper one",
      include_duty_cycle ? " and against the fitted network over the duty cycle" : "", drift_floor_K, margin,
      evidence_floor_K_min, alarm_factor, design.heat_w, design.speed_rpm);
}

double minutes_to_evidence(const std::vector<double>& rise, double drift_K, double threshold_K_min, uint16_t dt_ms) {
  const double per_step = dt_ms / 60000.0;
  double ev = 0;
  for (std::size_t k = 0; k < rise.size(); ++k) {
    ev = std::max(0.0, ev + (rise[k] - drift_K) * per_step);
    if (ev > threshold_K_min) return (k + 1) * per_step;
  }
  return -1;
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
    if (col[j] < 0) {
      if (const std::string why = reserved_column_problem(columns[c]); !why.empty())
        throw std::invalid_argument(rec.source + ": column '" + columns[c] + "' for channel " + std::to_string(j + 1) + " " + why);
      throw std::invalid_argument(rec.source + ": no column '" + columns[c] + "' for channel " + std::to_string(j + 1));
    }
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
    // The module steps once per elapsed dt (its sweeps and model steps share the schedule). A gap
    // of months between two rows is not a recording of the module running: refused, not replayed.
    constexpr double kMaxStepsPerGap = 1.0e6;
    if ((rec.time_s[i] - next_step) / dt > kMaxStepsPerGap)
      throw std::invalid_argument(fmt::format("{}: a gap of {:.6g} s before t = {:.6g} s (data row {}): the module's model would be "
                                              "replayed for more than {:.0f} steps of {:g} s across it; split the recording there",
                                              rec.source, rec.time_s[i] - rec.time_s[i - 1], rec.time_s[i], i + 1,
                                              kMaxStepsPerGap, dt));
    // Across a gap (lost samples: more than one step before this row) the module ran on readings
    // the recording does not hold: the steps in between hold the row before's speed and ambient
    // (zero-order hold) and give no residual; only the step at this row is compared with it. Each
    // of them compared with the reading after the gap made a 10-minute gap pile up 21 K min of
    // evidence and widened the bands 20-fold.
    const auto prev_rpm = static_cast<uint16_t>(std::clamp(std::lround(rec.speed_rpm[i - 1]), 0L, 65535L));
    const auto prev_amb = static_cast<int32_t>(std::lround(rec.ambient_c[i - 1] * 1000));
    while (rec.time_s[i] + 1e-9 >= next_step) {
      const bool at_row = rec.time_s[i] + 1e-9 < next_step + dt;  // the last step up to this row
      int32_t pred[kModelChannels];
      step(q, st, at_row ? rpm : prev_rpm, at_row ? amb : prev_amb, pred);
      if (at_row)
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

namespace {
// The candidate drift (multiples of `step` up to one beyond `worst`) whose threshold the design
// rise reaches soonest; threshold(d) from the worst evidence of `res` on that side. `upper`
// selects the side. Ties go to the larger drift (more forgiving of what was not recorded).
struct SideChoice {
  double drift = 0, worst_K_min = 0, minutes = -1;
};
SideChoice choose_drift(const std::vector<std::vector<double>>& res, const std::vector<double>& design_rise, double worst,
                        bool upper, const DetectorRule& rule, uint16_t dt_ms) {
  SideChoice best;
  best.drift = rule.drift_floor_K;
  const int n = std::max(1, static_cast<int>(std::ceil(worst / rule.drift_floor_K)) + 1);
  for (int i = 1; i <= n; ++i) {
    const double d = rule.drift_floor_K * i;
    const auto [hi, lo] = worst_evidence(res, upper ? d : 1e9, upper ? 1e9 : d, dt_ms);
    const double worst_ev = upper ? hi : lo;
    const double warn = rule.margin * worst_ev + rule.evidence_floor_K_min;
    const double threshold = upper ? rule.alarm_factor * warn : warn;
    const double t = minutes_to_evidence(design_rise, d, threshold, dt_ms);
    const bool better = t >= 0 && (best.minutes < 0 || t <= best.minutes);
    if (better || (best.minutes < 0 && i == 1)) {
      best.drift = d;
      best.worst_K_min = worst_ev;
      best.minutes = t;
    }
  }
  return best;
}
}  // namespace

DetectorCalibration calibrate_detector(const ScheduledReduction& red, const std::vector<const Recording*>& recordings,
                                       const std::array<std::string, kModelChannels>& columns, const DetectorRule& rule) {
  if (recordings.empty()) throw std::invalid_argument("detector calibration: no recordings");
  if (!(rule.margin >= 1.0) || !(rule.alarm_factor > 1.0) || !(rule.drift_floor_K > 0) || !(rule.evidence_floor_K_min > 0))
    throw std::invalid_argument("detector calibration: need margin >= 1, alarm factor > 1, drift step > 0, evidence floor > 0");
  if (!red.quantize_status.ok()) throw std::invalid_argument("detector calibration: the reduction did not quantize");
  {
    // The bands are the worst the model misses a healthy spindle by; learnt from a few samples they
    // are the noise of a moment, and the module false-alarms at its first warm-up.
    double running_s = 0;
    for (const Recording* rec : recordings)
      for (std::size_t k = 0; k + 1 < rec->rows(); ++k)
        if (rec->speed_rpm[k] > 0) running_s += rec->time_s[k + 1] - rec->time_s[k];
    if (running_s < kMinCalibrationRunningS)
      throw std::invalid_argument(fmt::format(
          "detector calibration: the recordings hold {:.3g} min of running (speed > 0), less than the {:.0f} min the bands are "
          "learnt from; calibrate on recordings of normal running, e.g. the warm-ups the model was fitted on",
          running_s / 60.0, kMinCalibrationRunningS / 60.0));
  }
  const ReducedModel& q = red.quantized;
  const uint16_t dt_ms = q.schedule.dt_ms;
  DetectorCalibration out;
  out.recordings = recordings.size();
  out.rule = rule.describe(red.design_fault);
  std::array<std::vector<std::vector<double>>, kModelChannels> res;
  for (const Recording* rec : recordings) {
    auto r = replay_residuals(q, *rec, columns);
    for (int j = 0; j < kModelChannels; ++j) res[static_cast<std::size_t>(j)].push_back(std::move(r[static_cast<std::size_t>(j)]));
  }
  for (int j = 0; j < kModelChannels; ++j) {
    const auto c = static_cast<std::size_t>(j);
    ChannelCalibration& cc = out.channels[c];
    cc.detector = red.model.detector[j];
    cc.column = columns[c];
    std::size_t recorded = 0;
    for (const auto& s : res[c]) recorded += s.size();
    if (recorded == 0) continue;
    cc.diagnosed = true;
    if (rule.include_duty_cycle && !red.duty.residual_K[c].empty()) res[c].push_back(red.duty.residual_K[c]);
    for (const auto& s : res[c]) {
      cc.samples += s.size();
      for (double v : s) {
        cc.worst_above_K = std::max(cc.worst_above_K, v);
        cc.worst_below_K = std::max(cc.worst_below_K, -v);
      }
    }
    cc.worst_residual_K = std::max(cc.worst_above_K, cc.worst_below_K);
    const std::vector<double>& rise = red.design_fault.rise_K[c];
    const SideChoice up = choose_drift(res[c], rise, cc.worst_above_K, true, rule, dt_ms);
    SideChoice down = choose_drift(res[c], rise, cc.worst_below_K, false, rule, dt_ms);
    if (down.drift < up.drift) {
      // The lower side is never tighter than the upper one: a probe colder than its model has no
      // detection-time target, and the fitted network's own error where the recordings did not go
      // (a restart beyond their top speed) shows on both sides.
      down.drift = up.drift;
      down.worst_K_min = worst_evidence(res[c], 1e9, up.drift, dt_ms).second;
      down.minutes = minutes_to_evidence(rise, up.drift, rule.margin * down.worst_K_min + rule.evidence_floor_K_min, dt_ms);
    }
    cc.worst_high_K_min = up.worst_K_min;
    cc.worst_low_K_min = down.worst_K_min;
    cc.design_alarm_min = up.minutes;
    cc.design_low_warn_min = down.minutes;
    cc.detector.drift_K = up.drift;
    cc.detector.low_drift_K = down.drift;
    cc.detector.warn_evidence_K_min = rule.margin * up.worst_K_min + rule.evidence_floor_K_min;
    cc.detector.alarm_evidence_K_min = rule.alarm_factor * cc.detector.warn_evidence_K_min;
    cc.detector.low_warn_evidence_K_min = rule.margin * down.worst_K_min + rule.evidence_floor_K_min;
  }
  return out;
}

void apply_calibration(const DetectorCalibration& c, ReducedModelF64& model) {
  for (int j = 0; j < kModelChannels; ++j)
    if (c.channels[static_cast<std::size_t>(j)].diagnosed) model.detector[j] = c.channels[static_cast<std::size_t>(j)].detector;
}

}  // namespace btsm::thermal
