#pragma once
// Why the fit recordings cannot decide a candidate the loop does not claim, from measured evidence
// (identifiability.hpp), in words a thermal engineer can act on. Five findings, each only when
// measured on the candidate's own refit:
// - tied to the base: a key parameter below param_z sigma that would be significant were the base
//   known (its sigma inflated >= `tied_inflation` times by the base parameters, multiple
//   correlation R >= 0.995 at 10x): the fit recordings fix only the combination; the base
//   parameter it is most correlated with is named (and a node without a probe);
// - not excited: a key parameter below param_z sigma that would stay below it were the base known:
//   the fit recordings themselves hardly excite it;
// - fitted out: the fit recordings fitted to within 2x their noise floor while the check is left
//   unexplained (cut < explained_factor): what the check needs is not in the fit part; with the
//   effect parameter the base ties most;
// - not covered: a run-in transient whose fit recordings start it from standstill only while the
//   check recordings change the speed while running (the transient then sits on a warm state);
// - explained alike: other candidates (another family or other nodes) that fit the fit recordings
//   within `alike_fit` of this one's rms and improve the check too: the fit part does not tell them
//   apart.
// Only for a candidate the fit recordings support (dBIC) that cuts the check (>= check_improvement)
// but is not claimed. It says why; it never changes a status (a miss stays a miss).
#include "host/residual/residual_loop.hpp"

#include <string>
#include <vector>

namespace btsm::residual {

struct UndecidedOptions {
  double tied_inflation = 10.0;    // x, sigma inflation by the base parameters that counts as "tied" (R >= 0.995)
  double alike_fit = 0.10;         // fraction, relative fit-rms difference within which two candidates fit alike
  double check_improvement = 1.25; // x, a candidate or rival must improve the check at least this much (LoopOptions)
  double explained_factor = 2.0;   // x, a check cut below this leaves the check unexplained (LoopOptions)
  double bic_margin = 10.0;        // 1, a candidate the fit part does not support (dBIC below) is not "undecided" (LoopOptions)
  double param_z = 3.0;            // sigma, |key| / sigma a claim needs (LoopOptions)
  double noise_k = 0;              // K, the fit recordings' noise floor (the base fit's; 0: unknown)
};

// The reason for `all[i]` ("" when none of the findings holds). `base` names the nodes.
std::string undecided_reason(const std::vector<CandidateResult>& all, std::size_t i, const thermal::Network& base,
                             const UndecidedOptions& o = {});

// For a verdict without a claim (`partial`, `unexplained`): `partial`, the chosen candidate's reason;
// `unexplained`, the reason of the unclaimed candidate that cuts the check most, then the own
// findings (tied, not excited, fitted out, not covered) of the next ones in check order, up to three
// candidates (the rivals that fit alike name each other once). "" when none has a reason.
std::string undecided_summary(const std::vector<CandidateResult>& all, int chosen, const thermal::Network& base,
                              const UndecidedOptions& o = {});

}  // namespace btsm::residual
