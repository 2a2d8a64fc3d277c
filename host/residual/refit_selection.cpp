// Which proposals the residual loop refits (see refit_selection.hpp).
#include "host/residual/refit_selection.hpp"

#include <fmt/core.h>

#include <algorithm>

namespace btsm::residual {

bool same_explanation(const EffectSpec& a, const EffectSpec& b) {
  if (a.kind != b.kind || a.column != b.column) return false;
  std::vector<int> na = a.nodes, nb = b.nodes;
  std::sort(na.begin(), na.end());
  std::sort(nb.begin(), nb.end());
  return na == nb;
}

RefitSelection select_refits(const std::vector<Proposal>& proposals, int max_candidates) {
  RefitSelection s;
  s.reason.assign(proposals.size(), "");
  const std::size_t budget = static_cast<std::size_t>(std::max(max_candidates, 0));
  std::size_t distinct = 0;
  // the refitted proposal that already carries p's explanation, or -1
  const auto refitted_as = [&](const Proposal& p) -> int {
    for (std::size_t j : s.refit)
      if (same_explanation(proposals[j].spec, p.spec)) return static_cast<int>(j);
    return -1;
  };
  for (std::size_t i = 0; i < proposals.size(); ++i) {
    const Proposal& p = proposals[i];
    const int same = refitted_as(p);
    if (i < budget) {  // the best by score, second variants included
      if (same < 0) ++distinct;
      s.refit.push_back(i);
      continue;
    }
    const std::string below = fmt::format("screening score {:.0f} below the {} best proposals", p.score, budget);
    if (same >= 0) {
      s.reason[i] = fmt::format("{}; its family and nodes are refitted in the variant '{}' (score {:.0f})", below,
                                proposals[static_cast<std::size_t>(same)].variant, proposals[static_cast<std::size_t>(same)].score);
    } else if (distinct >= budget) {
      s.reason[i] = fmt::format("{} and below the {} best distinct explanations (family and nodes)", below, budget);
    } else if (!(p.score > 0)) {
      s.reason[i] = fmt::format("{}, and not selected by the screening's criterion (score <= 0)", below);
    } else {  // a new explanation while the best proposals repeated one
      ++distinct;
      s.refit.push_back(i);
    }
  }
  return s;
}

std::vector<Proposal> other_transient_variants(const std::vector<Proposal>& refitted, double speed_ref_rpm, bool with_starts_only) {
  std::vector<Proposal> out;
  const auto sorted_nodes = [](const EffectSpec& e) {
    std::vector<int> n = e.nodes;
    std::sort(n.begin(), n.end());
    return n;
  };
  // the variant already refitted (or added) at these nodes
  const auto present = [&](const std::vector<int>& nodes, TransientTrigger t, bool mult) {
    const std::vector<Proposal>* lists[] = {&refitted, &out};
    for (const std::vector<Proposal>* list : lists)
      for (const Proposal& q : *list)
        if (q.spec.kind == EffectKind::HeatSourceTransient && sorted_nodes(q.spec) == nodes && q.spec.trigger == t &&
            q.spec.multiplicative == mult)
          return true;
    return false;
  };
  const double units_per_start = std::max(speed_ref_rpm, 1.0) / 1000.0;
  for (const Proposal& p : refitted) {
    if (p.spec.kind != EffectKind::HeatSourceTransient) continue;
    const std::vector<int> nodes = sorted_nodes(p.spec);
    for (const TransientTrigger t : {TransientTrigger::SpeedIncrease, TransientTrigger::StartOrChange, TransientTrigger::Start})
      for (const bool mult : {false, true}) {
        if (present(nodes, t, mult) || (t == TransientTrigger::Start && !with_starts_only)) continue;
        Proposal q = p;
        q.spec.trigger = t;
        q.spec.multiplicative = mult;
        q.alternative = true;
        // W per unit of p's trigger -> W per unit of t's (x friction law: the same W at w0)
        double scale = 1.0;
        const bool from_units = p.spec.trigger == TransientTrigger::SpeedIncrease, to_units = t == TransientTrigger::SpeedIncrease;
        if (from_units && !to_units) scale = units_per_start;
        if (!from_units && to_units) scale = 1.0 / units_per_start;
        for (double& c : q.coefficients) c *= scale;
        q.variant = fmt::format("{}, {}, tau {:.0f} min (another variant of the screened transient)",
                                mult ? "x friction law" : "additive",
                                trigger_phrase(t), p.spec.tau_s / 60);
        out.push_back(std::move(q));
      }
  }
  return out;
}

}  // namespace btsm::residual
