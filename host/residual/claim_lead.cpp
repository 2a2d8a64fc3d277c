#include "host/residual/claim_lead.hpp"

#include <fmt/core.h>

namespace btsm::residual {

namespace {

// Why a rival of another family takes the claim's lead away.
enum class Lead { Kept, CheckBetter, FitBetterCheckAlike };

struct Rival {
  int index = -1;
  Lead why = Lead::Kept;
};

// The other family's judged candidate with the lowest check error below the claim's, if any; else
// another family's candidate that passed every test as the claim did (`effect` or `partial`),
// that the fit recordings support MORE (a larger BIC gain) and whose check error is within
// `check_improvement` of the claim's. The held-out part then prefers the claim by less than the cut
// it asks of any effect, the fit recordings prefer the rival: the data do not single either out
// (effect-suite seed 2026, extra_heat_input_unprobed_shaft_01: coupled_heat@rear_bearing claimed at
// check 8.74 mK, dBIC 99 622, against extra_heat_input@rear_bearing+front_bearing at 9.13 mK,
// dBIC 257 810; the truth was heat at the unprobed shaft).
Rival rival_of(const std::vector<CandidateResult>& cands, int claim, double bic_margin, double check_improvement) {
  const CandidateResult& c = cands[static_cast<std::size_t>(claim)];
  Rival rival;
  for (std::size_t i = 0; i < cands.size(); ++i) {
    const CandidateResult& r = cands[i];
    if (static_cast<int>(i) == claim || r.spec.kind == c.spec.kind) continue;
    if (r.status != "rejected" && r.status != "partial") continue;  // judged: not failed, refused or unfitted
    if (r.delta_bic < bic_margin || r.check_factor < check_improvement || !(r.check.rmse_k < c.check.rmse_k)) continue;
    if (rival.index < 0 || r.check.rmse_k < cands[static_cast<std::size_t>(rival.index)].check.rmse_k) rival = {static_cast<int>(i), Lead::CheckBetter};
  }
  if (rival.index >= 0) return rival;
  for (std::size_t i = 0; i < cands.size(); ++i) {
    const CandidateResult& r = cands[i];
    if (static_cast<int>(i) == claim || r.spec.kind == c.spec.kind) continue;
    if (r.status != "effect" && r.status != "partial") continue;  // passed BIC, significance, identifiability, the check
    if (!(r.delta_bic > c.delta_bic) || !(r.check.rmse_k <= check_improvement * c.check.rmse_k)) continue;
    if (rival.index < 0 || r.delta_bic > cands[static_cast<std::size_t>(rival.index)].delta_bic)
      rival = {static_cast<int>(i), Lead::FitBetterCheckAlike};
  }
  return rival;
}

}  // namespace

std::vector<NotToldApart> keep_claims_with_a_lead(std::vector<CandidateResult>& candidates, int& best, double bic_margin,
                                                  double check_improvement) {
  std::vector<NotToldApart> dropped;
  while (best >= 0) {
    const Rival rival = rival_of(candidates, best, bic_margin, check_improvement);
    if (rival.index < 0) break;
    CandidateResult& c = candidates[static_cast<std::size_t>(best)];
    const CandidateResult& r = candidates[static_cast<std::size_t>(rival.index)];
    c.status = "rejected";
    if (rival.why == Lead::CheckBetter)
      c.reason += fmt::format("; but {} (another family the fit recordings support too, dBIC {:.1f}) explains the held-out part "
                              "better (check {:.4g} K against {:.4g} K) though it is not significant itself: the two are not told apart",
                              r.label, r.delta_bic, r.check.rmse_k, c.check.rmse_k);
    else
      c.reason += fmt::format("; but {} (another family, passing every test too) fits the fit recordings better (dBIC {:.1f} against "
                              "{:.1f}) and the check alike (check {:.4g} K against {:.4g} K, within x{:.2f}): the two are not told apart",
                              r.label, r.delta_bic, c.delta_bic, r.check.rmse_k, c.check.rmse_k, check_improvement);
    dropped.push_back({best, rival.index});
    best = -1;
    for (std::size_t i = 0; i < candidates.size(); ++i) {
      if (candidates[i].status != "effect") continue;
      if (best < 0 || candidates[i].check.rmse_k < candidates[static_cast<std::size_t>(best)].check.rmse_k) best = static_cast<int>(i);
    }
  }
  return dropped;
}

}  // namespace btsm::residual
