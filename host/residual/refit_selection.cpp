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

}  // namespace btsm::residual
