#include "speed_coverage.hpp"

#include "common/model_step.hpp"

#include <fmt/format.h>

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace btsm::thermal {

namespace {

// The module's steady rise (K) of channel j running at speed_rpm: the fixed point of
// T' = T_amb + a (T - T_amb) + c (T_h - T_amb) + b, i.e. (b + c R_h) / (1 - a) with R_h the
// carrier's own steady rise (a carrier is plain; c = 0 without one), with the coefficients the
// module interpolates.
double module_steady_rise_K(const ReducedModel& m, int j, double speed_rpm) {
  ModelBreakpoint p;
  coefficients_at(m, static_cast<uint16_t>(std::lround(speed_rpm)), 0, p);
  const auto plain = [&](int k) {
    const double a = static_cast<double>(p.ch[k].a_q30) / static_cast<double>(1L << 30);
    const double b_K = static_cast<double>(p.ch[k].b) / 1024.0 / 1000.0;
    return std::make_pair(a, b_K);
  };
  const auto [a, b_K] = plain(j);
  if (!(a < 1.0)) return 0.0;
  double carried = 0.0;
  const uint8_t h = m.schedule.coupling.carrier[j];
  if (h != kModelNoCarrier) {
    const auto [ah, bh] = plain(h - 1);
    const double c = static_cast<double>(m.schedule.coupling.c_q30[j]) / static_cast<double>(1L << 30);
    carried = ah < 1.0 ? c * bh / (1.0 - ah) : 0.0;
  }
  return (b_K + carried) / (1.0 - a);
}

}  // namespace

SpeedCoverage check_speed_coverage(const Network& net, const Eigen::VectorXd& params, const ScheduledReduction& r,
                                   const SpeedCoverageOptions& opts) {
  if (!(opts.step_rpm > 0) || !(opts.drift_fraction > 0) || !(opts.design_heat_w >= 0) || !(opts.design_alarm_within_min > 0))
    throw std::invalid_argument("speed coverage: step, drift fraction and ALARM time must be > 0, the design heat >= 0");
  const ReducedModel& q = r.quantized;
  const uint8_t n = q.schedule.n_breakpoints;
  if (n < 2) throw std::invalid_argument("speed coverage: the model has no running breakpoint");
  const double top_bp = q.schedule.speed_rpm[n - 1];
  const double top = std::min(65534.0, opts.top_rpm > 0 ? std::max(opts.top_rpm, top_bp) : top_bp);
  SpeedCoverage c;
  c.drift_fraction = opts.drift_fraction;
  c.design_heat_w = opts.design_heat_w;
  c.design_alarm_within_min = opts.design_alarm_within_min;
  for (double s = opts.step_rpm; s <= top + 1e-9; s += opts.step_rpm) c.speed_rpm.push_back(s);
  if (c.speed_rpm.empty() || c.speed_rpm.back() < top) c.speed_rpm.push_back(top);
  const std::size_t ns = c.speed_rpm.size();
  std::vector<bool> ok(ns, true);
  std::vector<int> worst_ch(ns, -1);
  std::vector<double> worst_excess(ns, 0.0), worst_err(ns, 0.0), worst_allowed(ns, 0.0), worst_fault_rise(ns, 0.0);
  std::vector<bool> worst_hides(ns, false);
  for (std::size_t i = 0; i < ns; ++i) {
    const NodeMatrices mm = assemble(net, params, c.speed_rpm[i]);
    Eigen::FullPivLU<Eigen::MatrixXd> lu(mm.G);
    if (!lu.isInvertible()) throw std::runtime_error("speed coverage: the network has no path to ambient");
    const Eigen::VectorXd rise = lu.solve(mm.heat_w);
    for (int j = 0; j < 5; ++j) {
      const int nd = r.channels[static_cast<std::size_t>(j)].node;
      if (nd < 0 || !model_predicts(q.schedule.enabled_mask, q.schedule.ambient_channel, static_cast<uint8_t>(j))) continue;
      const double e = rise[nd] - module_steady_rise_K(q, j, c.speed_rpm[i]);
      c.error_K[static_cast<std::size_t>(j)].push_back(e);
      c.worst_abs_K[static_cast<std::size_t>(j)] = std::max(c.worst_abs_K[static_cast<std::size_t>(j)], std::abs(e));
      const ChannelDetector& d = r.model.detector[j];
      // Below the model counts only where the lower evidence can WARN.
      const double allowed = opts.drift_fraction * (e >= 0 ? d.drift_K : d.low_drift_K);
      const bool side_on = e >= 0 || d.low_warn_evidence_K_min > 0;
      double excess = side_on ? std::abs(e) - allowed : 0.0;
      // The design fault: its lasting residual e + X beyond the drift must reach ALARM in time. The
      // shortfall in K (of the rate it needs) ranks it beside a plain excess.
      double fault_rise = 0.0, hidden = 0.0;
      if (opts.design_heat_w > 0) {
        fault_rise = opts.design_heat_w * lu.solve(Eigen::VectorXd::Unit(mm.G.rows(), nd))[nd];
        const double needed = d.drift_K + d.alarm_evidence_K_min / opts.design_alarm_within_min;
        if (fault_rise >= needed)
          hidden = needed - (e + fault_rise);  // the error at this speed hides what the bands would see
        else  // the bands themselves forgive this fault, whatever the model's error: said apart, not a gap
          c.bands_hide_fault_K[static_cast<std::size_t>(j)] = std::max(c.bands_hide_fault_K[static_cast<std::size_t>(j)], needed);
      }
      if (excess > 0 || hidden > 0) {
        ok[i] = false;
        const double worst = std::max(excess, hidden);
        if (worst > worst_excess[i]) {
          worst_excess[i] = worst;
          worst_ch[i] = j;
          worst_err[i] = e;
          worst_allowed[i] = allowed;
          worst_hides[i] = hidden > 0 && hidden >= excess;
          worst_fault_rise[i] = fault_rise;
        }
      }
    }
  }
  // Gaps: runs of uncovered speeds, each with its worst channel.
  for (std::size_t i = 0; i < ns;) {
    if (ok[i]) {
      ++i;
      continue;
    }
    SpeedGap g;
    g.from_rpm = c.speed_rpm[i];
    double worst = -1;
    for (; i < ns && !ok[i]; ++i) {
      g.to_rpm = c.speed_rpm[i];
      if (worst_excess[i] > worst) {
        worst = worst_excess[i];
        g.channel = worst_ch[i];
        g.worst_error_K = worst_err[i];
        g.allowed_K = worst_allowed[i];
        g.hides_fault = worst_hides[i];
        g.fault_rise_K = worst_fault_rise[i];
      }
    }
    c.gaps.push_back(g);
  }
  c.covers_all = c.gaps.empty();
  // The covered run around the top breakpoint (a model that is wrong there has none).
  std::size_t k = ns;
  for (std::size_t i = 0; i < ns; ++i)
    if (c.speed_rpm[i] >= top_bp - 1e-9) {
      k = i;
      break;
    }
  if (k < ns && ok[k]) {
    std::size_t lo = k, hi = k;
    while (lo > 0 && ok[lo - 1]) --lo;
    while (hi + 1 < ns && ok[hi + 1]) ++hi;
    c.valid_from_rpm = lo == 0 ? 0.0 : c.speed_rpm[lo];
    c.valid_to_rpm = c.speed_rpm[hi];
  }
  return c;
}

std::vector<std::string> describe_gaps(const SpeedCoverage& c) {
  std::vector<std::string> lines;
  for (const auto& g : c.gaps)
    if (g.hides_fault)
      lines.push_back(fmt::format("ch{}: {:.0f}-{:.0f} rpm: {:g} W more at the channel's node (+{:.2f} K) would not ALARM within "
                                  "{:g} min: a healthy spindle settles up to {:.2f} K {} the model there, and the drift "
                                  "forgives the rest",
                                  g.channel + 1, g.from_rpm, g.to_rpm, c.design_heat_w, g.fault_rise_K, c.design_alarm_within_min,
                                  std::abs(g.worst_error_K), g.worst_error_K >= 0 ? "above" : "below"));
    else
      lines.push_back(fmt::format("ch{}: {:.0f}-{:.0f} rpm: a healthy spindle settles up to {:.2f} K {} the model (allowed {:.2f} K, "
                                "{:g} x its drift)",
                                g.channel + 1, g.from_rpm, g.to_rpm, std::abs(g.worst_error_K),
                                g.worst_error_K >= 0 ? "above" : "below", g.allowed_K, c.drift_fraction));
  return lines;
}

nlohmann::json speed_coverage_to_json(const SpeedCoverage& c) {
  nlohmann::json j;
  j["rule"] = fmt::format("steady error (network - module, after a long run at the speed) within {:g} x the channel's drift, "
                          "checked every {:g} rpm",
                          c.drift_fraction, c.speed_rpm.size() > 1 ? c.speed_rpm[1] - c.speed_rpm[0] : 0.0);
  if (c.design_heat_w > 0)
    j["rule"] = j["rule"].get<std::string>() +
                fmt::format("; and {:g} W more at a channel's node ALARMs within {:g} min (steady residual beyond the drift)",
                            c.design_heat_w, c.design_alarm_within_min);
  j["valid_speed_range_rpm"] = {c.valid_from_rpm, c.valid_to_rpm};
  j["covers_all_checked_speeds"] = c.covers_all;
  j["checked_up_to_rpm"] = c.speed_rpm.empty() ? 0.0 : c.speed_rpm.back();
  j["gaps"] = nlohmann::json::array();
  for (const auto& g : c.gaps)
    j["gaps"].push_back({{"from_rpm", g.from_rpm}, {"to_rpm", g.to_rpm}, {"channel", g.channel + 1},
                         {"worst_steady_error_K", g.worst_error_K}, {"allowed_K", g.allowed_K},
                         {"hides_design_fault", g.hides_fault}, {"design_fault_rise_K", g.fault_rise_K}});
  j["bands_hide_design_fault"] = nlohmann::json::object();  // channel -> lasting K its bands need to ALARM in time
  for (int ch = 0; ch < 5; ++ch)
    if (c.bands_hide_fault_K[static_cast<std::size_t>(ch)] > 0)
      j["bands_hide_design_fault"]["ch" + std::to_string(ch + 1)] = c.bands_hide_fault_K[static_cast<std::size_t>(ch)];
  j["worst_steady_error_K"] = nlohmann::json::object();
  for (int ch = 0; ch < 5; ++ch)
    if (!c.error_K[static_cast<std::size_t>(ch)].empty()) j["worst_steady_error_K"]["ch" + std::to_string(ch + 1)] = c.worst_abs_K[static_cast<std::size_t>(ch)];
  return j;
}

}  // namespace btsm::thermal
