// Why the fit recordings cannot decide a candidate (see undecided_reason.hpp).
#include "host/residual/undecided_reason.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

namespace btsm::residual {
namespace th = btsm::thermal;
namespace {

bool fitted(const CandidateResult& c) {
  return c.status == "fitted" || c.status == "effect" || c.status == "partial" || c.status == "rejected";
}

std::vector<std::string> unprobed_nodes_of(const CandidateResult& c, const th::Network& base) {
  std::vector<std::string> out;
  for (const auto& n : c.nodes) {
    const int i = base.node_index(n);
    if (i >= 0 && !base.has_probe(i)) out.push_back(n);
  }
  return out;
}

std::string join(const std::vector<std::string>& v, const char* sep = ", ") {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : sep) + x;
  return s;
}

bool is_key(const CandidateResult& c, const std::string& name) {
  for (const auto& k : c.key_params)
    if (k == name || k.rfind(name + "/", 0) == 0) return true;
  return false;
}

// The effect parameter the base parameters tie most (largest sigma inflation), or null.
const ParamReport* most_tied(const CandidateResult& c) {
  const ParamReport* best = nullptr;
  for (const auto& p : c.params)
    if (!p.base.partner.empty() && (best == nullptr || p.base.inflation > best->base.inflation)) best = &p;
  return best;
}

std::string tie_text(const ParamReport& p) {
  return fmt::format("multiple correlation {:.4f} with the base parameters, most with {} (r {:+.2f})", p.base.multiple_correlation,
                     p.base.partner, p.base.pair_correlation);
}

// A key parameter too uncertain to claim because the base parameters take it over: it would be
// significant were the base known.
std::string tied_finding(const CandidateResult& c, const th::Network& base, const UndecidedOptions& o) {
  const ParamReport* p = nullptr;  // of the keys below param_z, the one the base ties most
  double z = 0;
  for (const auto& q : c.params) {
    if (!is_key(c, q.name) || !(q.sigma > 0) || q.base.partner.empty()) continue;
    const double zq = std::abs(q.value) / q.sigma;
    if (!(zq < o.param_z && q.base.inflation >= o.tied_inflation && zq * q.base.inflation >= o.param_z)) continue;
    if (p == nullptr || q.base.inflation > p->base.inflation) {
      p = &q;
      z = zq;
    }
  }
  if (p == nullptr) return "";
  std::string s = fmt::format("{} cannot be told from the base model on the fit recordings: |z| {:.1f}, {:.0f} were the base known "
                              "({}); they fix only the combination",
                              p->name, z, z * p->base.inflation, tie_text(*p));
  const auto unprobed = unprobed_nodes_of(c, base);
  if (!unprobed.empty()) s += fmt::format("; {} has no probe: a probe there would measure it directly", join(unprobed));
  return s;
}

// A key parameter below param_z sigma that the base parameters do not explain: were the base known
// it would still be below param_z sigma, so the fit recordings themselves hardly excite it.
std::string unexcited_finding(const CandidateResult& c, const UndecidedOptions& o) {
  const ParamReport* p = nullptr;  // of the weak keys, the weakest one
  double z = 0;
  for (const auto& q : c.params) {
    if (!is_key(c, q.name) || !(q.sigma > 0)) continue;
    const double zq = std::abs(q.value) / q.sigma;
    const double known = zq * (q.base.partner.empty() ? 1.0 : q.base.inflation);
    if (!(zq < o.param_z && known < o.param_z)) continue;
    if (p == nullptr || zq < z) {
      p = &q;
      z = zq;
    }
  }
  if (p == nullptr) return "";
  return fmt::format("{}{} is not determined by the fit recordings even with the base known (|z| {:.1f}, {:.1f} were the base known): "
                     "they hardly excite it",
                     p->name, p->status == "at its bound" ? " (at its bound)" : "", z, z * (p->base.partner.empty() ? 1.0 : p->base.inflation));
}

// Fitted to the fit recordings' noise, yet the check is left unexplained: what the check needs is
// not in the fit part. The parameter the base ties most names the direction the fit part leaves open.
std::string exhausted_finding(const CandidateResult& c, const UndecidedOptions& o) {
  if (!(o.noise_k > 0) || !(c.fit.rmse_k <= 2 * o.noise_k) || c.check_factor >= o.explained_factor || !(c.check.rmse_k > 2 * o.noise_k))
    return "";
  std::string s = fmt::format("it fits the fit recordings to {:.2f}x their noise floor ({:.3g} K) but leaves {:.3g} K on the check: "
                              "the fit part does not hold what the check needs",
                              c.fit.rmse_k / o.noise_k, c.fit.rmse_k, c.check.rmse_k);
  const ParamReport* p = most_tied(c);
  if (p != nullptr && p->base.inflation >= o.tied_inflation)
    s += fmt::format(" ({} is tied to the base: {}; its sigma {:.0f}x what it would be were the base known)", p->name, tie_text(*p),
                     p->base.inflation);
  return s;
}

std::string coverage_finding(const CandidateResult& c, const UndecidedOptions& o) {
  if (c.spec.kind != EffectKind::HeatSourceTransient || c.check_factor >= o.explained_factor) return "";
  const TriggerCoverage &f = c.fit_triggers, &k = c.check_triggers;
  if (!(f.triggers > 0 && f.while_running == 0 && k.while_running > 0)) return "";
  return fmt::format("the fit recordings start every transient from standstill ({} start(s), no speed change while running), where "
                     "it overlaps the network's own warm-up; the check holds {} speed change(s) while running, where it sits on a "
                     "warm state: a speed change while warm (or a start from a warm spindle) in the fit recordings would decide it",
                     f.triggers, k.while_running);
}

std::string alike_finding(const std::vector<CandidateResult>& all, std::size_t i, const UndecidedOptions& o) {
  const CandidateResult& c = all[i];
  if (!(c.fit.rmse_k > 0)) return "";
  std::vector<std::string> labels;
  double lo = c.fit.rmse_k, hi = c.fit.rmse_k, clo = c.check.rmse_k, chi = c.check.rmse_k;
  for (std::size_t j = 0; j < all.size(); ++j) {
    const CandidateResult& r = all[j];
    if (j == i || !fitted(r) || r.label == c.label || r.delta_bic < o.bic_margin || !(r.check_factor >= o.check_improvement)) continue;
    if (!(std::abs(r.fit.rmse_k - c.fit.rmse_k) <= o.alike_fit * c.fit.rmse_k)) continue;
    if (std::find(labels.begin(), labels.end(), r.label) != labels.end()) continue;
    labels.push_back(r.label);
    lo = std::min(lo, r.fit.rmse_k);
    hi = std::max(hi, r.fit.rmse_k);
    clo = std::min(clo, r.check.rmse_k);
    chi = std::max(chi, r.check.rmse_k);
  }
  if (labels.empty()) return "";
  return fmt::format("{} other candidate(s) fit the fit recordings alike ({}; fit rms {:.3g}-{:.3g} K, within {:.0f} % of each other) "
                     "and cut the check too (check {:.3g}-{:.3g} K): the fit part does not tell these drivers apart",
                     labels.size(), join(labels), lo, hi, 100 * o.alike_fit, clo, chi);
}

// The findings on all[i]: its own (tied, fitted out, not covered) and the rivals that fit alike.
struct Findings {
  std::vector<std::string> own;
  std::string alike;
};

Findings findings_of(const std::vector<CandidateResult>& all, std::size_t i, const th::Network& base, const UndecidedOptions& o) {
  Findings f;
  const CandidateResult& c = all.at(i);
  // Only a candidate the fit recordings support (dBIC) that cuts the check (>= check_improvement)
  // and is not claimed: the question is why the fit part cannot settle it, not whether there is
  // anything at all (a candidate the check refutes is decided, by the check).
  if (!fitted(c) || c.status == "effect" || c.delta_bic < o.bic_margin || !(c.check_factor >= o.check_improvement)) return f;
  for (const std::string& s : {tied_finding(c, base, o), unexcited_finding(c, o), exhausted_finding(c, o), coverage_finding(c, o)})
    if (!s.empty()) f.own.push_back(s);
  f.alike = alike_finding(all, i, o);
  return f;
}

}  // namespace

std::string undecided_reason(const std::vector<CandidateResult>& all, std::size_t i, const th::Network& base, const UndecidedOptions& o) {
  Findings f = findings_of(all, i, base, o);
  if (!f.alike.empty()) f.own.push_back(f.alike);
  return join(f.own, "; ");
}

std::string undecided_summary(const std::vector<CandidateResult>& all, int chosen, const th::Network& base, const UndecidedOptions& o) {
  if (chosen >= 0) {
    const CandidateResult& c = all.at(static_cast<std::size_t>(chosen));
    return c.undecided.empty() ? "" : c.label + ": " + c.undecided;
  }
  std::vector<std::size_t> idx;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (!all[i].undecided.empty() && all[i].check_factor >= o.check_improvement) idx.push_back(i);
  std::stable_sort(idx.begin(), idx.end(), [&](std::size_t a, std::size_t b) { return all[a].check.rmse_k < all[b].check.rmse_k; });
  // The best one with all its findings; the others with their own findings only (the rivals that
  // fit alike name each other: once is enough), up to three candidates in all.
  std::string out;
  int named = 0;
  for (std::size_t k = 0; k < idx.size() && named < 3; ++k) {
    Findings f = findings_of(all, idx[k], base, o);
    if (k == 0 && !f.alike.empty()) f.own.push_back(f.alike);
    if (f.own.empty()) continue;
    out += (out.empty() ? "" : "; and ") + all[idx[k]].label + ": " + join(f.own, "; ");
    ++named;
  }
  return out;
}

}  // namespace btsm::residual
