#include "host/residual/claim_lead.hpp"

#include <fmt/core.h>

namespace btsm::residual {

namespace {

// The other family's judged candidate with the lowest check error below the claim's, if any.
int rival_of(const std::vector<CandidateResult>& cands, int claim, double bic_margin, double check_improvement) {
  const CandidateResult& c = cands[static_cast<std::size_t>(claim)];
  int rival = -1;
  for (std::size_t i = 0; i < cands.size(); ++i) {
    const CandidateResult& r = cands[i];
    if (static_cast<int>(i) == claim || r.spec.kind == c.spec.kind) continue;
    if (r.status != "rejected" && r.status != "partial") continue;  // judged: not failed, refused or unfitted
    if (r.delta_bic < bic_margin || r.check_factor < check_improvement || !(r.check.rmse_k < c.check.rmse_k)) continue;
    if (rival < 0 || r.check.rmse_k < cands[static_cast<std::size_t>(rival)].check.rmse_k) rival = static_cast<int>(i);
  }
  return rival;
}

}  // namespace

std::vector<NotToldApart> keep_claims_with_a_lead(std::vector<CandidateResult>& candidates, int& best, double bic_margin,
                                                  double check_improvement) {
  std::vector<NotToldApart> dropped;
  while (best >= 0) {
    const int rival = rival_of(candidates, best, bic_margin, check_improvement);
    if (rival < 0) break;
    CandidateResult& c = candidates[static_cast<std::size_t>(best)];
    const CandidateResult& r = candidates[static_cast<std::size_t>(rival)];
    c.status = "rejected";
    c.reason += fmt::format("; but {} (another family the fit recordings support too, dBIC {:.1f}) explains the held-out part "
                            "better (check {:.4g} K against {:.4g} K) though it is not significant itself: the two are not told apart",
                            r.label, r.delta_bic, r.check.rmse_k, c.check.rmse_k);
    dropped.push_back({best, rival});
    best = -1;
    for (std::size_t i = 0; i < candidates.size(); ++i) {
      if (candidates[i].status != "effect") continue;
      if (best < 0 || candidates[i].check.rmse_k < candidates[static_cast<std::size_t>(best)].check.rmse_k) best = static_cast<int>(i);
    }
  }
  return dropped;
}

}  // namespace btsm::residual
