#pragma once
// A claim needs a lead over the other explanations, not only over the base model.
//
// When a candidate of ANOTHER family, which the fit recordings support too (its BIC gain clears the
// margin), explains the held-out part better than the claimed effect and falls short only of
// significance or identifiability, the data do not tell the two apart: heat at a node no probe
// measures, a coupling between two nodes and a temperature-dependent source can all bend the same
// probed columns. Claiming the first would name an effect the data do not single out, so it is not
// claimed; the next effect in line is judged the same way.
#include "host/residual/residual_loop.hpp"

#include <vector>

namespace btsm::residual {

struct NotToldApart {
  int claim = -1;  // the candidate that was not claimed (now "rejected", the reason says why)
  int rival = -1;  // the other family's candidate that explains the held-out part better
};

// `best` is the index of the "effect" candidate with the lowest check error (-1: none). Every claim
// without a lead is set to "rejected" with the rival in its reason, and `best` moves to the next
// "effect" candidate (lowest check error) that keeps its lead, or to -1. Returns the claims dropped.
std::vector<NotToldApart> keep_claims_with_a_lead(std::vector<CandidateResult>& candidates, int& best, double bic_margin,
                                                  double check_improvement);

}  // namespace btsm::residual
