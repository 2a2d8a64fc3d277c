// Joint refit of one proposed effect (see candidate_fit.hpp).
#include "host/residual/candidate_fit.hpp"

#include "host/thermal/fit_starts.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

namespace btsm::residual {
namespace th = btsm::thermal;
namespace {

// A refit this many times worse than the base model's check error has diverged (record_fit).
constexpr double kDivergedFactor = 1000.0;


// A probe whose column carries at least this share of the base fit's residual sum of squares
// dominates it: one distorted reading is then the likeliest reason for the misfit, and a probe
// lag there is also started from the base fitted without that probe. A column of four to five
// carrying over half of the misfit is far from what an effect at a node spreads over its
// neighbours' probes.
constexpr double kProbeDominatesShare = 0.5;

int largest_capacitance_param(const th::Network& net, const Eigen::VectorXd& p) {
  int best = -1;
  for (const auto& nd : net.nodes)
    if (best < 0 || p(nd.capacitance_param) > p(best)) best = nd.capacitance_param;
  return best;
}

std::vector<Eigen::MatrixXd> impulses_for(const AugmentedModel& am, const std::vector<th::Recording>& recs) {
  std::vector<Eigen::MatrixXd> out;
  if (am.transient_node < 0) return out;
  for (const auto& r : recs) out.push_back(transient_impulses_w(am.net, am.params, r, am.transient_node, am.trigger));
  return out;
}

bool has_time_constant(EffectKind k) {
  return k == EffectKind::HeatSourceTransient || k == EffectKind::SensorLag || k == EffectKind::AmbientDynamics ||
         k == EffectKind::LatentMass;
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// The numerator and denominator of a ratio key "a/b" (AugmentedModel::key_params); nothing for a
// plain parameter's key.
std::optional<std::pair<std::string, std::string>> ratio_key_parts(const std::string& key) {
  const auto slash = key.find('/');
  if (slash == std::string::npos) return std::nullopt;
  return std::make_pair(key.substr(0, slash), key.substr(slash + 1));
}

// |value| / sigma of one key of an effect (AugmentedModel::key_params): a parameter, or the ratio
// "a/b" of two with its sigma from their covariance (first order). A key without sigma (held) counts
// as significant when it is nonzero.
double key_z_of(const th::Network& net, const th::FitResult& fr, const std::string& key) {
  const auto zs = [](double value, double sigma) { return sigma > 0 ? std::abs(value) / sigma : (value != 0 ? 1e9 : 0.0); };
  const auto parts = ratio_key_parts(key);
  if (!parts) {
    const auto& est = fr.estimates[static_cast<std::size_t>(net.param_index(key))];
    return zs(est.value, est.sigma);
  }
  const int a = net.param_index(parts->first), b = net.param_index(parts->second);
  const double va = fr.params[a], vb = fr.params[b];
  if (!(va != 0 && vb != 0)) return 0.0;
  const auto cov = [&](int i, int j) { return i < fr.covariance.rows() && j < fr.covariance.cols() ? fr.covariance(i, j) : 0.0; };
  const double rel2 = cov(a, a) / (va * va) + cov(b, b) / (vb * vb) - 2 * cov(a, b) / (va * vb);
  const double ratio = va / vb;
  return zs(ratio, std::abs(ratio) * std::sqrt(std::max(rel2, 0.0)));
}

// True when `name` is a key of the effect or the numerator of a ratio key (the parameter that
// carries it: a nuisance hold may fix the denominator, never that).
bool is_key(const AugmentedModel& am, const std::string& name) {
  for (const auto& k : am.key_params)
    if (k == name || k.rfind(name + "/", 0) == 0) return true;
  return false;
}

// A ratio key A/B whose denominator B is held because the data see only A/B (a pure ambient lag:
// C/g) keeps its ratio wherever B is held, but where B is held decides where A must sit: held where
// the refit drifted along the unseen direction (g 2.6e6 W/K), A ends at its bound (C 1e10 J/K for a
// 65 min lag) and the candidate would be rejected for a bound the data never asked for. A and B
// move by one factor until A is two decades inside its bounds, B within its own; the model's
// outputs do not see the move (B stays far above the machine's conductance when it was).
void slide_held_ratio_keys(const AugmentedModel& am, const std::vector<std::string>& held, Eigen::VectorXd& p) {
  for (const auto& key : am.key_params) {
    const auto ratio = ratio_key_parts(key);
    if (!ratio || std::find(held.begin(), held.end(), ratio->second) == held.end()) continue;
    const int a = am.net.param_index(ratio->first), b = am.net.param_index(ratio->second);
    if (a < 0 || b < 0 || a >= p.size() || b >= p.size()) continue;
    const th::Parameter& pa = am.net.params[static_cast<std::size_t>(a)];
    const th::Parameter& pb = am.net.params[static_cast<std::size_t>(b)];
    if (!(p[a] > 0 && p[b] > 0 && pa.min > 0 && pb.min > 0)) continue;
    const double lo = pa.min * 100, hi = pa.max / 100;
    if (!(lo < hi)) continue;
    double s = p[a] > hi ? hi / p[a] : p[a] < lo ? lo / p[a] : 1.0;
    s = std::clamp(s, pb.min / p[b], pb.max / p[b]);
    if (s == 1.0) continue;
    p[a] *= s;
    p[b] *= s;
  }
}

// The smallest |value| / sigma of the key parameters of one node of an effect (named "..._<node>").
double node_z(const AugmentedModel& am, const th::FitResult& fr, const std::string& node) {
  double z = std::numeric_limits<double>::infinity();
  for (const auto& name : am.key_params) {
    if (!ends_with(name, "_" + node)) continue;
    z = std::min(z, key_z_of(am.net, fr, name));
  }
  return z;
}

// The base capacitance held when an effect adds a free capacitance: the new capacitance is not
// part of the known total, so the largest base capacitance keeps its base-fit value instead (the
// same scale, fixed another way).
std::vector<std::string> held_for(const CandidateContext& ctx, const AugmentedModel& a) {
  std::vector<std::string> h;
  const th::Network& base = *ctx.base;
  if (a.adds_free_capacitance && std::isfinite(base.sum_capacitance_J_per_K)) {
    const int c = largest_capacitance_param(base, ctx.base_params);
    if (c >= 0 && !base.params[static_cast<std::size_t>(c)].fixed) h.push_back(base.params[static_cast<std::size_t>(c)].name);
  }
  return h;
}

// The evidence of a fitted candidate: errors on the full-rate fit and on the check recordings,
// BIC against the base, key |z|, identifiability, the effect in physical terms.
void fill_evidence(const CandidateContext& ctx, const AugmentedModel& am, const EffectSpec& spec, const th::FitResult& fr,
                   CandidateResult& cr) {
  const auto& fit = *ctx.fit;
  std::vector<Eigen::MatrixXd> rf, rc;
  const std::vector<Eigen::MatrixXd> imp_fit = impulses_for(am, fit);
  // (the refit's initial states: the decimated recordings start at the same row)
  for (std::size_t r = 0; r < fit.size(); ++r)
    rf.push_back(evaluate_model(cr.net, cr.values, fit[r], imp_fit.empty() ? nullptr : &imp_fit[r], &fr.initial_states[r]).residual_k);
  for (const auto& r : *ctx.check) rc.push_back(evaluate_candidate(cr, r).residual_k);
  cr.fit = error_metrics(rf, ctx.measured_fit);
  cr.check = error_metrics(rc, ctx.measured_check);
  std::size_t nn = 0;
  const double rss = sum_of_squares(rf, nn);
  // unknowns: the free parameters, every recording's initial state and a drifting probe's offset
  // in every recording (thermal/network.hpp)
  int drifting = 0;
  for (const auto& m : cr.net.measurements) drifting += m.drift_param >= 0 ? 1 : 0;
  const int k = fr.free_parameter_count + (cr.net.node_count() + drifting) * static_cast<int>(fit.size());
  cr.bic = bic(rss, nn, k);
  cr.delta_bic = ctx.base_bic - cr.bic;
  cr.check_factor = cr.check.rmse_k > 0 ? ctx.before_check.rmse_k / cr.check.rmse_k : 0;
  cr.key_z = std::numeric_limits<double>::infinity();
  for (const auto& name : am.key_params) cr.key_z = std::min(cr.key_z, key_z_of(am.net, fr, name));
  if (!std::isfinite(cr.key_z)) cr.key_z = 0;
  cr.identifiable = true;
  cr.params.clear();
  for (const auto& name : am.effect_params) {
    const auto& est = fr.estimates[static_cast<std::size_t>(am.net.param_index(name))];
    cr.params.push_back({est.name, est.unit, est.value, est.sigma, est.at_bound ? "at its bound" : th::identifiability_name(est.status),
                         base_confounding(am.net, ctx.base->param_count(), fr, name)});
    if (est.at_bound || est.status == th::Identifiability::NotIdentifiable) cr.identifiable = false;
  }
  cr.quantities = effect_quantities(am, spec, *ctx.base, fr.params, fr.covariance);
  if (!fr.stages.empty()) {
    cr.refit_iterations = fr.stages.back().iterations;
    cr.refit_continuations = fr.stages.back().continuations;
  }
  cr.refit_converged = fr.converged;
  if (spec.kind == EffectKind::HeatSourceTransient) {
    const auto tau = std::find_if(cr.quantities.begin(), cr.quantities.end(), [](const EffectQuantity& q) { return q.name == "tau_transient"; });
    if (tau != cr.quantities.end()) {
      cr.fit_triggers = trigger_coverage(am.net, fit, am.trigger, tau->value);
      cr.check_triggers = trigger_coverage(am.net, *ctx.check, am.trigger, tau->value);
    }
  }
}

}  // namespace

th::Recording decimated(const th::Recording& rec, double step_s) {
  std::vector<double> dts;
  for (std::size_t k = 1; k < rec.rows(); ++k) dts.push_back(rec.time_s[k] - rec.time_s[k - 1]);
  if (dts.empty()) return rec;
  std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2), dts.end());
  const auto k = static_cast<std::size_t>(std::max(1L, std::lround(step_s / dts[dts.size() / 2])));
  if (k <= 1) return rec;
  th::Recording out;
  out.source = rec.source;
  out.channels = rec.channels;
  out.meta = rec.meta;
  std::vector<Eigen::Index> rows;
  for (std::size_t r = 0; r < rec.rows(); r += k) rows.push_back(static_cast<Eigen::Index>(r));
  out.temp_c.resize(static_cast<Eigen::Index>(rows.size()), rec.temp_c.cols());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const auto r = static_cast<std::size_t>(rows[i]);
    out.time_s.push_back(rec.time_s[r]);
    out.speed_rpm.push_back(rec.speed_rpm[r]);
    out.ambient_c.push_back(rec.ambient_c[r]);
    out.temp_c.row(static_cast<Eigen::Index>(i)) = rec.temp_c.row(rows[i]);
  }
  return out;
}

std::map<std::string, double> start_values(const th::Network& base, const Eigen::VectorXd& bp, const Proposal& p) {
  if (!p.effect_start.empty()) return p.effect_start;
  std::map<std::string, double> v;
  const auto& e = p.spec;
  const auto coef = [&](std::size_t i) { return i < p.coefficients.size() && std::isfinite(p.coefficients[i]) ? p.coefficients[i] : 0.0; };
  for (std::size_t i = 0; i < e.nodes.size(); ++i) {
    const std::string nn = base.nodes[static_cast<std::size_t>(e.nodes[i])].name;
    const double c = coef(i);
    switch (e.kind) {
      case EffectKind::HeatSourceTransient:
        if (e.multiplicative) {
          const double q0 = std::max(source_heat_at_w0(base, bp, e.nodes[i]), 1e-3);
          v["a_transient_" + nn] = std::max(c / q0, 1e-3);
        } else {
          v["a_transient_" + nn] = std::max(c, 0.05);
        }
        break;
      case EffectKind::TemperatureDependentHeat: v["k_heat_T_" + nn] = c; break;
      case EffectKind::CoupledHeat: v["k_couple_" + nn] = c; break;
      case EffectKind::ExtraHeatInput: v["q_extra_" + nn] = c; break;
      case EffectKind::SecondBoundary:
      case EffectKind::EventConductance: v["g_" + e.column + "_" + nn] = std::max(c, 1e-3); break;
      case EffectKind::LatentMass: {
        const double g = std::max(c, 1e-2);
        v["g_latent_" + nn] = g;
        v["C_latent_" + nn] = g * (e.tau_s > 0 ? e.tau_s : 1800.0);
        break;
      }
      default: break;
    }
  }
  if (e.kind == EffectKind::HeatSourceTransient) v["tau_transient"] = e.tau_s;
  if (e.kind == EffectKind::SensorLag) v["tau_probe_" + e.column] = e.tau_s * std::clamp(coef(0), 0.3, 3.0);
  if (e.kind == EffectKind::SensorDrift) v["d_" + e.column] = coef(0);
  return v;
}

// The options of a joint refit of base + effect (of the effect alone when the base is held): from
// `start`, with the effect's rest states, its impulses on `recs` and the capacitance held_for holds.
// `also_hold`: effect parameters held besides the scale (those the data cannot see); names the
// augmented network lacks are skipped.
th::FitOptions joint_options(const CandidateContext& ctx, const AugmentedModel& am, const Eigen::VectorXd& start,
                             const std::vector<th::Recording>& recs, const std::vector<std::string>& also_hold = {}) {
  th::FitOptions f;
  // The loop's thresholds (key |z|, identifiability) were measured with the per-run sigma (the
  // README's effect-suite table); it keeps that sigma until the suite is rerun with the summed one.
  f.sum_scores_over_runs = false;
  f.staged = false;
  f.start = start;
  f.relative_tolerance = 1e-9;
  f.max_iterations = ctx.joint_iterations;
  f.continuation = ctx.joint_continuation;
  f.extra_heat_w = impulses_for(am, recs);
  f.initial_state_at_ambient = am.rest_nodes;
  f.hold = held_for(ctx, am);
  for (const auto& h : also_hold)
    if (std::find(f.hold.begin(), f.hold.end(), h) == f.hold.end() &&
        std::find(am.effect_params.begin(), am.effect_params.end(), h) != am.effect_params.end())
      f.hold.push_back(h);
  if (!ctx.fit_base) f.free_only = am.effect_params;
  return f;
}

// A fitted augmented model into its candidate: the effect as fitted (its nodes, network, values,
// the states it adds) and the evidence for it.
void record_fit(const CandidateContext& ctx, const AugmentedModel& am, const EffectSpec& spec, const th::FitResult& fr,
                CandidateResult& cr, const std::vector<std::string>& also_hold = {}) {
  const th::Network& base = *ctx.base;
  cr.spec = spec;
  cr.label = effect_label(spec, base);
  cr.nodes = effect_nodes(spec, base);
  cr.net = am.net;
  cr.values = fr.params;
  cr.transient_node = am.transient_node;
  cr.trigger = am.trigger;
  cr.rest_nodes = am.rest_nodes;
  cr.key_params = am.key_params;
  cr.effect_params = am.effect_params;
  cr.held = joint_options(ctx, am, fr.params, {}, also_hold).hold;
  fill_evidence(ctx, am, spec, fr, cr);
  cr.status = "fitted";
  // A refit whose model errs a thousand times more than the base model did on the check part has
  // not fitted anything: its values make the network unstable (or the optimiser left the physical
  // range) and its error, BIC and |z| are numbers without meaning. It is a failed fit, reported as
  // diverged, not a rejected candidate with absurd evidence.
  const double worst = std::max(cr.fit.rmse_k, cr.check.rmse_k);
  const double limit = kDivergedFactor * std::max(ctx.before_check.rmse_k, 1e-3);
  if (!std::isfinite(worst) || worst > limit) {
    cr.status = "failed";
    cr.reason = fmt::format("the refit diverged: its model errs {:.3g} K on the fit recordings and {:.3g} K on the check "
                            "recordings, more than {:.0f}x the base model's check error ({:.3g} K)",
                            cr.fit.rmse_k, cr.check.rmse_k, kDivergedFactor, ctx.before_check.rmse_k);
  }
}

CandidateResult candidate_of(const Proposal& p, const th::Network& base) {
  CandidateResult c;
  c.spec = p.spec;
  c.label = effect_label(p.spec, base);
  c.effect = effect_name(p.spec.kind);
  c.nodes = effect_nodes(p.spec, base);
  c.variant = p.variant;
  c.explained_share = p.rss_fraction;
  c.screening_score = p.score;
  c.stability = p.stability;
  return c;
}

bool starts_only_restarts_alike(const th::Network& base, const std::vector<th::Recording>& recs) {
  for (const auto& r : recs)
    if (transient_triggers(base, r, TransientTrigger::StartOrChange) != transient_triggers(base, r, TransientTrigger::Start)) return false;
  return true;
}

CandidateResult starts_only_twin(const CandidateContext& ctx, const CandidateResult& c) {
  CandidateResult t = c;
  t.spec.trigger = t.trigger = TransientTrigger::Start;
  const auto swap_words = [](std::string& text) {
    for (const auto& [from, to] : {std::pair<std::string, std::string>{trigger_name(TransientTrigger::StartOrChange),
                                                                        trigger_name(TransientTrigger::Start)},
                                   {trigger_phrase(TransientTrigger::StartOrChange), trigger_phrase(TransientTrigger::Start)},
                                   {"each start or speed change", "each start from standstill"},
                                   {"W per start/change", "W per start"}})
      for (std::size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size())) text.replace(at, from.size(), to);
  };
  swap_words(t.variant);
  t.variant += " (the same fit as the start-or-change variant: no fit recording changes speed while turning)";
  for (EffectQuantity& q : t.quantities) {
    swap_words(q.meaning);
    swap_words(q.unit);
  }
  std::vector<Eigen::MatrixXd> rc;
  for (const auto& r : *ctx.check) rc.push_back(evaluate_candidate(t, r).residual_k);
  t.check = error_metrics(rc, ctx.measured_check);
  t.check_factor = t.check.rmse_k > 0 ? ctx.before_check.rmse_k / t.check.rmse_k : 0;
  const auto tau = std::find_if(t.quantities.begin(), t.quantities.end(), [](const EffectQuantity& q) { return q.name == "tau_transient"; });
  if (tau != t.quantities.end()) {
    t.fit_triggers = trigger_coverage(t.net, *ctx.fit, t.trigger, tau->value);
    t.check_triggers = trigger_coverage(t.net, *ctx.check, t.trigger, tau->value);
  }
  return t;
}

// The share of the base fit's residual sum of squares (on the fit recordings) that one measured
// column carries.
double residual_share_of_column(const CandidateContext& ctx, const std::string& column) {
  const th::Network& base = *ctx.base;
  int mi = -1;
  for (std::size_t m = 0; m < base.measurements.size(); ++m)
    if (base.measurements[m].column == column) mi = static_cast<int>(m);
  if (mi < 0) return 0.0;
  double own = 0, all = 0;
  for (const auto& rec : *ctx.fit) {
    const Evaluation ev = evaluate_model(base, ctx.base_params, rec);
    for (Eigen::Index c = 0; c < ev.residual_k.cols(); ++c)
      for (Eigen::Index k = 0; k < ev.residual_k.rows(); ++k) {
        const double e = ev.residual_k(k, c);
        if (!std::isfinite(e)) continue;
        all += e * e;
        if (c == mi) own += e * e;
      }
  }
  return all > 0 ? own / all : 0.0;
}

// The base parameters fitted (staged, from the data) without one probe's distortion: a probe whose
// own reading is distorted (a drift, a lag) drags the base fit into a basin that also bends the
// other columns, and no start near that basin leads to the joint optimum.
// - A lag (`drifted` null): the probe is left out; its node is simply unprobed.
// - A drift: the probe stays in, its readings with the drift of `drifted` (an augmented model
//   fitted so far: its ramp and its least-squares offset in every recording) taken off. The
//   staged fit's equation-error stages use the readings themselves, and a probe offset by up to
//   a kelvin or more bends every parameter they start.
th::FitResult base_fit_without_probe(const CandidateContext& ctx, const std::string& column, const std::vector<th::Recording>& recs,
                                     const AugmentedModel* drifted, const Eigen::VectorXd& drifted_params) {
  th::Network net = *ctx.base;
  std::vector<th::Recording> corrected;
  if (drifted) {
    int mi = -1;
    for (std::size_t m = 0; m < drifted->net.measurements.size(); ++m)
      if (drifted->net.measurements[m].column == column) mi = static_cast<int>(m);
    if (mi < 0) throw std::invalid_argument("no measurement of " + column);
    const int node = drifted->net.measurements[static_cast<std::size_t>(mi)].node;
    corrected = recs;
    for (auto& rec : corrected) {
      // model at the column = node + drift ramp + offset: what the probe adds is the difference
      const Evaluation ev = evaluate_model(drifted->net, drifted_params, rec, nullptr, nullptr, drifted->rest_nodes);
      const int c = rec.channel_index(column);
      for (Eigen::Index k = 0; k < ev.model_c.rows(); ++k) rec.temp_c(k, c) -= ev.model_c(k, mi) - ev.nodes_c(k, node);
    }
  } else {
    net.measurements.erase(std::remove_if(net.measurements.begin(), net.measurements.end(),
                                          [&](const th::Measurement& m) { return m.column == column; }),
                           net.measurements.end());
  }
  th::FitOptions f;
  f.sum_scores_over_runs = false;  // as in joint_options
  f.staged = true;
  f.max_iterations = ctx.joint_iterations;
  return th::fit_network(net, corrected.empty() ? recs : corrected, f);
}

CandidateResult refit_candidate(const CandidateContext& ctx, const Proposal& p) {
  const auto t0 = std::chrono::steady_clock::now();
  const th::Network& base = *ctx.base;
  const auto& fit = *ctx.fit;
  const auto& refit = ctx.fit_refit ? *ctx.fit_refit : fit;
  CandidateResult cr = candidate_of(p, base);
  auto say = [&](const std::string& s) {
    if (ctx.progress) ctx.progress(s);
  };
  try {
    // Starts. (1) the base fit with the screening's effect; (2) the screening's effect pinned and
    // the base refitted around it: a base that absorbed part of the effect gives it back (the
    // joint refit from (1) crawls through that valley); (3) for a family with a time constant,
    // a second one on the better base. Each start ends with an effect-only fit; the joint refit
    // runs from the best.
    // (4) The cooling-first staged pipeline on the augmented network, from the data: where the
    // base fit absorbed much of the effect into wrong base values, neither (1) nor (2) is near
    // the joint optimum, and the staged pipeline needs no start (every family but a
    // sensor lag: its probe state is not measured, which the equation-error starts need).
    // (5) For a probe's drift, after (1)-(4): the base staged-fitted on the probe's readings with
    // the drift of the best start so far taken off (base_fit_without_probe), then the effect alone
    // on it; the staged pipeline of (4) takes the drifted readings at face value in its
    // equation-error stages. For a probe's lag whose column carries most of the base residual: the
    // base fitted without that probe, then the effect alone on it.
    // (6) Given the base values of a candidate fitted before (ctx.other_base_params), the staged
    // pipeline of (4) once more from them: the base fit absorbed the effect into its own values, a
    // candidate that explains most of the residual elsewhere has given much of that back, and
    // the staged stages hold part of their start (an unprobed node's heat: the base fit's basin and
    // the data-driven one both leave it in the neighbours' sources).
    // (7) For a proposal flagged start_from_data, the staged pipeline of (4) with no base value
    // given: every base parameter, and every effect parameter that enters linearly, started by its
    // equation-error stages. (4) hands the staged pipeline the base fit's values, and a parameter
    // with a start skips those stages: it is the joint fit from the base fit's basin once more.
    // Where the base fit is bent by what it lacks (a strong declared coolant: 0.557 K, 101x its
    // noise floor, with the plant's own base values at 0.028 K), no start near it reaches the
    // joint optimum, and the staged fit from the data alone does (0.0023 K).
    struct Start {
      Proposal p;
      bool pinned = false, on_best_base = false;
      std::string what;
      bool staged = false, without_probe = false, other_base = false, from_data = false;
    };
    std::vector<Start> starts{{.p = p, .what = "base fit"}};
    const bool leave_basin = ctx.fit_base && ctx.basin_starts;  // (2), (4), (6), (7)
    if (leave_basin) starts.push_back({.p = p, .pinned = true, .what = "base refitted around the screening's effect"});
    if (leave_basin && p.spec.kind != EffectKind::SensorLag)
      starts.push_back({.p = p, .what = "staged fit of base + effect from the data", .staged = true});
    if (leave_basin && p.start_from_data && p.spec.kind != EffectKind::SensorLag)
      starts.push_back({.p = p, .what = "staged fit of base + effect from the data alone, no base value given", .staged = true, .from_data = true});
    if (leave_basin && p.spec.kind != EffectKind::SensorLag && ctx.other_base_params.size() == base.param_count())
      starts.push_back({.p = p, .what = "staged fit from the base of " + ctx.other_base_from, .staged = true, .other_base = true});
    if (ctx.fit_base && p.spec.kind == EffectKind::SensorDrift)
      starts.push_back({.p = p, .what = "base fitted on the probe with the drift so far taken off", .without_probe = true});
    if (ctx.fit_base && p.spec.kind == EffectKind::SensorLag) {
      const double share = residual_share_of_column(ctx, p.spec.column);
      if (share >= kProbeDominatesShare || ctx.lag_from_base_without_probe) {
        say(share >= kProbeDominatesShare
                ? fmt::format("residual:     {}: column {} carries {:.0f} % of the base residual: the base is also fitted without it", cr.label,
                              p.spec.column, 100 * share)
                : fmt::format("residual:     {}: no claim so far: the base is also fitted without column {} ({:.0f} % of the base residual)",
                              cr.label, p.spec.column, 100 * share));
        starts.push_back({.p = p, .what = "base fitted without the probe", .without_probe = true});
      }
    }
    th::FitOptions fo;
    fo.sum_scores_over_runs = false;  // as in joint_options
    fo.staged = false;
    fo.relative_tolerance = 1e-8;
    th::FitResult best;
    AugmentedModel best_am;
    EffectSpec best_spec = p.spec;
    double best_rms = std::numeric_limits<double>::infinity();
    Eigen::VectorXd best_base = ctx.base_params;
    bool second_tau_added = false;
    std::optional<std::pair<AugmentedModel, Eigen::VectorXd>> without_probe;  // a lag's start without its probe (ctx.lag_from_base_without_probe)
    for (std::size_t s = 0; s < starts.size() + (second_tau_added ? 0 : 1); ++s) {
      if (s == starts.size()) {
        second_tau_added = true;
        // the second time constant, on the base of the best start so far
        if (!(has_time_constant(p.spec.kind) && p.spec.tau_s > 0)) break;
        Proposal q = p;
        q.spec.tau_s = p.spec.tau_s * 2.5;
        starts.push_back({.p = q, .on_best_base = true, .what = "second time constant"});
      }
      Eigen::VectorXd base_values = starts[s].on_best_base ? best_base : starts[s].other_base ? ctx.other_base_params : ctx.base_params;
      if (starts[s].without_probe) {
        try {
          const bool drift = p.spec.kind == EffectKind::SensorDrift && std::isfinite(best_rms);
          const th::FitResult fw = base_fit_without_probe(ctx, p.spec.column, refit, drift ? &best_am : nullptr, best.params);
          say(fmt::format("residual:     {} start {}: the base fitted {} {}: rms {:.4g} K", cr.label, s + 1,
                          drift ? "with the drift so far taken off" : "without", p.spec.column, fw.rms_K));
          base_values = fw.params;
        } catch (const std::exception& e) {
          say(fmt::format("residual:     {} start {} ({}) failed: {}", cr.label, s + 1, starts[s].what, e.what()));
          continue;
        }
      }
      AugmentedModel am = augment(base, base_values, starts[s].p.spec, start_values(base, base_values, starts[s].p));
      if (starts[s].staged) {
        th::FitOptions fs;
        fs.sum_scores_over_runs = false;  // as in joint_options
        fs.staged = true;
        fs.start = am.params;
        fs.max_iterations = ctx.joint_iterations;
        fs.extra_heat_w = impulses_for(am, refit);
        fs.initial_state_at_ambient = am.rest_nodes;
        if (am.adds_free_capacitance && std::isfinite(base.sum_capacitance_J_per_K)) {
          const int c = largest_capacitance_param(base, ctx.base_params);
          if (c >= 0 && !base.params[static_cast<std::size_t>(c)].fixed) fs.hold.push_back(base.params[static_cast<std::size_t>(c)].name);
        }
        // (7): no start value (neither FitOptions::start nor the parameter's own `initial`, which
        // augment() sets to the effect's start) for what the equation-error stages can start
        th::Network staged_net = am.net;
        if (starts[s].from_data) {
          const auto forms = th::fitting::linear_forms(staged_net);
          for (int i = 0; i < staged_net.param_count(); ++i) {
            th::Parameter& par = staged_net.params[static_cast<std::size_t>(i)];
            if (par.fixed || std::find(fs.hold.begin(), fs.hold.end(), par.name) != fs.hold.end()) continue;  // held: keeps its value
            const bool effect = std::find(am.effect_params.begin(), am.effect_params.end(), par.name) != am.effect_params.end();
            if (effect && forms[static_cast<std::size_t>(i)] == th::fitting::LinearForm::None) continue;  // needs its start
            fs.start[i] = std::numeric_limits<double>::quiet_NaN();
            par.initial_auto = true;
          }
        }
        th::FitResult f;
        try {
          f = th::fit_network(staged_net, refit, fs);
        } catch (const std::exception& e) {
          say(fmt::format("residual:     {} start {} ({}) failed: {}", cr.label, s + 1, starts[s].what, e.what()));
          continue;
        }
        say(fmt::format("residual:     {} start {} ({}): rms {:.4g} K", cr.label, s + 1, starts[s].what, f.rms_K));
        if (f.rms_K < best_rms) {
          best_rms = f.rms_K;
          best_base = f.params.head(base.param_count());
          best = std::move(f);
          best_am = std::move(am);
          best_spec = starts[s].p.spec;
        }
        continue;
      }
      if (starts[s].pinned) {
        th::FitOptions f0 = fo;
        f0.start = am.params;
        f0.hold = am.effect_params;
        f0.max_iterations = ctx.joint_iterations;
        f0.extra_heat_w = impulses_for(am, refit);
        f0.initial_state_at_ambient = am.rest_nodes;
        if (am.adds_free_capacitance && std::isfinite(base.sum_capacitance_J_per_K)) {
          const int c = largest_capacitance_param(base, ctx.base_params);
          if (c >= 0 && !base.params[static_cast<std::size_t>(c)].fixed) f0.hold.push_back(base.params[static_cast<std::size_t>(c)].name);
        }
        const th::FitResult f = th::fit_network(am.net, refit, f0);
        say(fmt::format("residual:     {} start {}: the base refitted around the screening's effect: rms {:.4g} K", cr.label, s + 1, f.rms_K));
        am.params = f.params;
      }
      th::FitOptions f1 = fo;
      f1.start = am.params;
      f1.free_only = am.effect_params;
      f1.max_iterations = ctx.effect_iterations;
      f1.extra_heat_w = impulses_for(am, refit);
      f1.initial_state_at_ambient = am.rest_nodes;
      th::FitResult f = th::fit_network(am.net, refit, f1);
      say(fmt::format("residual:     {} start {} ({}{}): rms {:.4g} K with the effect alone", cr.label, s + 1, starts[s].what,
                      starts[s].p.spec.tau_s > 0 ? fmt::format(", tau {:.0f} s", starts[s].p.spec.tau_s) : std::string(), f.rms_K));
      if (starts[s].without_probe && p.spec.kind == EffectKind::SensorLag && ctx.lag_from_base_without_probe)
        without_probe.emplace(am, f.params);
      if (f.rms_K < best_rms) {
        best_rms = f.rms_K;
        best_base = f.params.head(base.param_count());
        best = std::move(f);
        best_am = std::move(am);
        best_spec = starts[s].p.spec;
      }
    }
    AugmentedModel am = std::move(best_am);
    EffectSpec spec = best_spec;
    // The joint refit of every parameter (or, with a fixed base, of the effect alone) from `start`.
    std::vector<std::string> nuisance;  // effect parameters held because the data cannot see them
    const auto joint = [&](const AugmentedModel& a, const Eigen::VectorXd& start) {
      const th::FitOptions f2 = joint_options(ctx, a, start, refit, nuisance);
      return th::fit_network(a.net, refit, f2);
    };
    th::FitResult fr = best;
    if (ctx.fit_base) {
      fr = joint(am, best.params);
      say(fmt::format("residual:     {} joint refit: rms {:.4g} K, {} ({} iterations, {} chunk(s) past the budget)", cr.label, fr.rms_K,
                      fr.converged ? "converged" : "NOT converged", fr.stages.empty() ? 0 : fr.stages.back().iterations,
                      fr.stages.empty() ? 0 : fr.stages.back().continuations));
      if (without_probe) {
        th::FitResult fw = joint(without_probe->first, without_probe->second);
        say(fmt::format("residual:     {} joint refit from the base fitted without {}: rms {:.4g} K, {} ({} iterations, {} chunk(s) past "
                        "the budget)",
                        cr.label, p.spec.column, fw.rms_K, fw.converged ? "converged" : "NOT converged",
                        fw.stages.empty() ? 0 : fw.stages.back().iterations, fw.stages.empty() ? 0 : fw.stages.back().continuations));
        if (fw.rms_K < fr.rms_K) {
          fr = std::move(fw);
          am = std::move(without_probe->first);
        }
      }
    }
    // Backward elimination of nodes: the screening proposes up to max_nodes nodes from a linear
    // view; a node whose share of the effect the joint refit cannot tell from zero is dropped and
    // the rest refitted, so an effect is named at the nodes the data support, not at every node
    // that helped the linear screening a little.
    while (spec.nodes.size() > 1) {
      std::size_t weakest = 0;
      double weakest_z = std::numeric_limits<double>::infinity();
      for (std::size_t i = 0; i < spec.nodes.size(); ++i) {
        const double z = node_z(am, fr, base.nodes[static_cast<std::size_t>(spec.nodes[i])].name);
        if (z < weakest_z) {
          weakest_z = z;
          weakest = i;
        }
      }
      if (!(weakest_z < ctx.param_z)) break;
      EffectSpec fewer = spec;
      fewer.nodes.erase(fewer.nodes.begin() + static_cast<std::ptrdiff_t>(weakest));
      std::map<std::string, double> values;
      for (const auto& name : am.effect_params) values[name] = fr.params[am.net.param_index(name)];
      if (spec.kind == EffectKind::HeatSourceTransient) {
        // keep the decay time: the dropped coupling's share moves to the decay path
        const double g = values["g_transient_" + base.nodes[static_cast<std::size_t>(spec.nodes[weakest])].name];
        values["g_transient_decay"] += g;
      }
      AugmentedModel a2 = augment(base, fr.params.head(base.param_count()), fewer, values);
      th::FitResult f2 = joint(a2, a2.params);
      say(fmt::format("residual:     {}: {} dropped (|z| {:.1f} < {:.0f}), refit rms {:.4g} K", cr.label,
                      base.nodes[static_cast<std::size_t>(spec.nodes[weakest])].name, weakest_z, ctx.param_z, f2.rms_K));
      spec = fewer;
      am = std::move(a2);
      fr = std::move(f2);
    }
    // A non-key effect parameter the refit cannot identify (e.g. the conductance of a lagged
    // ambient to the measured one when the lag is a pure delay: only C/g is seen) is held at its
    // value and the rest refitted, so the key parameter's sigma is not that unseen direction's.
    if (ctx.fit_base) {
      for (const auto& name : am.effect_params) {
        if (is_key(am, name)) continue;
        const auto& est = fr.estimates[static_cast<std::size_t>(am.net.param_index(name))];
        if (est.status == th::Identifiability::NotIdentifiable || est.at_bound) nuisance.push_back(name);
      }
      if (!nuisance.empty()) {
        Eigen::VectorXd start = fr.params;
        slide_held_ratio_keys(am, nuisance, start);
        th::FitResult f3 = joint(am, start);
        say(fmt::format("residual:     {}: {} not identifiable, held at {:.4g}; refit rms {:.4g} K", cr.label, nuisance.front(),
                        start[am.net.param_index(nuisance.front())], f3.rms_K));
        fr = std::move(f3);
      }
    }
    record_fit(ctx, am, spec, fr, cr, nuisance);
  } catch (const std::exception& e) {
    cr.status = "failed";
    cr.reason = std::string("fit failed: ") + e.what();
  }
  cr.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return cr;
}

std::map<std::string, double> fitted_effect_values(const CandidateResult& c) {
  std::map<std::string, double> values;
  for (const auto& name : c.effect_params) {
    const int i = c.net.param_index(name);
    if (i >= 0 && i < c.values.size()) values[name] = c.values[i];
  }
  return values;
}

CandidateResult refit_fewer_nodes(const CandidateContext& ctx, const CandidateResult& c, std::size_t drop) {
  const th::Network& base = *ctx.base;
  CandidateResult r = c;
  EffectSpec spec = c.spec;
  const std::string dropped = base.nodes[static_cast<std::size_t>(spec.nodes.at(drop))].name;
  spec.nodes.erase(spec.nodes.begin() + static_cast<std::ptrdiff_t>(drop));
  std::map<std::string, double> values = fitted_effect_values(c);
  if (spec.kind == EffectKind::HeatSourceTransient) values["g_transient_decay"] += values["g_transient_" + dropped];
  AugmentedModel am = augment(base, c.values.head(base.param_count()), spec, values);
  // (nuisance parameters the candidate's refit held stay held)
  const th::FitResult fr = th::fit_network(am.net, *ctx.fit_refit, joint_options(ctx, am, am.params, *ctx.fit_refit, c.held));
  record_fit(ctx, am, spec, fr, r, c.held);
  return r;
}

int weakest_node(const CandidateContext& ctx, const CandidateResult& c) {
  if (c.status == "failed" || c.spec.nodes.size() < 2) return -1;
  int weakest = -1;
  double weakest_z = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < c.spec.nodes.size(); ++i) {
    const std::string node = ctx.base->nodes[static_cast<std::size_t>(c.spec.nodes[i])].name;
    // rank: a parameter at its bound first (its sigma, 0 there, says nothing), then |value| / sigma;
    // weak: below param_z, at its bound or not identifiable (what the decision rejects for)
    double z = std::numeric_limits<double>::infinity();
    bool weak = false;
    for (const auto& name : c.key_params) {
      if (!ends_with(name, "_" + node)) continue;
      const auto p = std::find_if(c.params.begin(), c.params.end(), [&](const ParamReport& r) { return r.name == name; });
      if (p == c.params.end()) continue;
      const double zp = p->status == "at its bound" ? -1.0 : p->sigma > 0 ? std::abs(p->value) / p->sigma : (p->value != 0 ? 1e9 : 0.0);
      weak = weak || zp < ctx.param_z || p->status == th::identifiability_name(th::Identifiability::NotIdentifiable);
      z = std::min(z, zp);
    }
    if (weak && z < weakest_z) {
      weakest_z = z;
      weakest = static_cast<int>(i);
    }
  }
  return weakest;
}

CandidateResult refit_more_nodes(const CandidateContext& ctx, const CandidateResult& c, int node) {
  const th::Network& base = *ctx.base;
  if (c.spec.nodes.empty()) throw std::invalid_argument("refit_more_nodes: the candidate acts on no node");
  CandidateResult r = c;
  EffectSpec spec = c.spec;
  spec.nodes.push_back(node);
  std::sort(spec.nodes.begin(), spec.nodes.end());
  std::map<std::string, double> values = fitted_effect_values(c);
  const std::string first = "_" + base.nodes[static_cast<std::size_t>(c.spec.nodes.front())].name;
  const std::string added = "_" + base.nodes[static_cast<std::size_t>(node)].name;
  for (const auto& name : c.effect_params)
    if (name.size() > first.size() && name.compare(name.size() - first.size(), first.size(), first) == 0)
      values[name.substr(0, name.size() - first.size()) + added] = values[name];
  AugmentedModel am = augment(base, c.values.head(base.param_count()), spec, values);
  const th::FitResult fr = th::fit_network(am.net, *ctx.fit_refit, joint_options(ctx, am, am.params, *ctx.fit_refit, c.held));
  record_fit(ctx, am, spec, fr, r, c.held);
  return r;
}

bool prune_weak_nodes(const CandidateContext& ctx, CandidateResult& c) {
  bool pruned = false;
  for (int w = weakest_node(ctx, c); w >= 0; w = weakest_node(ctx, c)) {
    const std::string node = ctx.base->nodes[static_cast<std::size_t>(c.spec.nodes[static_cast<std::size_t>(w)])].name;
    CandidateResult r = refit_fewer_nodes(ctx, c, static_cast<std::size_t>(w));
    if (ctx.progress)
      ctx.progress(fmt::format("residual: {}: {} is not supported by the data (|z| < {:.0f} or at its bound); without it: fit rms {:.4g} K, "
                               "check {:.4g} K, key |z| {:.1f}",
                               c.label, node, ctx.param_z, r.fit.rmse_k, r.check.rmse_k, r.key_z));
    r.seconds = c.seconds;
    c = std::move(r);
    pruned = true;
  }
  return pruned;
}

bool polish_candidate(const CandidateContext& ctx, CandidateResult& c) {
  if (!ctx.fit_base || c.status == "failed" || c.status == "refused" || c.status == "not fitted") return false;
  if (ctx.fit_refit == nullptr || ctx.fit_refit == ctx.fit) return false;
  bool decimated_any = false;
  for (std::size_t r = 0; r < ctx.fit->size(); ++r) decimated_any = decimated_any || (*ctx.fit_refit)[r].rows() != (*ctx.fit)[r].rows();
  if (!decimated_any) return false;
  AugmentedModel am;
  am.net = c.net;
  am.params = c.values;
  am.key_params = c.key_params;
  am.effect_params = c.effect_params;
  am.transient_node = c.transient_node;
  am.rest_nodes = c.rest_nodes;
  am.trigger = c.trigger;
  th::FitOptions f = joint_options(ctx, am, c.values, *ctx.fit);
  f.hold = c.held;  // the rebuilt model does not know which capacitance the refit held
  th::FitResult fr = th::fit_network(am.net, *ctx.fit, f);
  if (!(fr.rms_K < c.fit.rmse_k)) return false;
  // The refit's rule on the full-rate data too: a non-key effect parameter they cannot see (a pure
  // ambient lag's conductance: only C/g shows) is held at its value and the rest refitted, so the
  // candidate is not rejected for that unseen direction.
  std::vector<std::string> unseen;
  for (const auto& name : am.effect_params) {
    if (is_key(am, name) || std::find(f.hold.begin(), f.hold.end(), name) != f.hold.end()) continue;
    const auto& est = fr.estimates[static_cast<std::size_t>(am.net.param_index(name))];
    if (est.status == th::Identifiability::NotIdentifiable || est.at_bound) unseen.push_back(name);
  }
  if (!unseen.empty()) {
    f.hold.insert(f.hold.end(), unseen.begin(), unseen.end());
    f.start = fr.params;
    slide_held_ratio_keys(am, f.hold, f.start);
    fr = th::fit_network(am.net, *ctx.fit, f);
    c.held = f.hold;
    if (ctx.progress)
      ctx.progress(fmt::format("residual:     {}: {} not identifiable on the full-rate recordings, held at {:.4g}; refit rms {:.4g} K", c.label,
                               unseen.front(), fr.params[am.net.param_index(unseen.front())], fr.rms_K));
  }
  c.values = fr.params;
  fill_evidence(ctx, am, c.spec, fr, c);
  return true;
}

}  // namespace btsm::residual
