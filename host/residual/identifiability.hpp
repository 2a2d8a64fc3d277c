#pragma once
// Why the fit recordings cannot decide an effect: evidence measured on a candidate's joint refit,
// turned into a reason a thermal engineer can act on. Used by the decision (residual_loop.cpp) to
// say WHY a candidate is rejected, partial or not told apart; it never turns a miss into a claim.
//
// Two kinds of evidence:
// - confounding with the base model: an effect parameter whose joint-refit covariance ties it to
//   the base parameters (multiple correlation R close to 1: the base can take over what the effect
//   does on these recordings). Its sigma with the base refitted is `inflation` times the sigma it
//   would have were the base known; the reason names the base parameter it is most correlated with.
// - coverage: the fit recordings lack a situation the check recordings contain that the effect
//   behaves differently in. For a run-in transient: a new trigger (a speed change) while the
//   previous transient has not decayed yet. Warm-ups from standstill after long pauses only ever
//   start the transient from zero, so how it re-arms or adds up on a speed change while warm is
//   not seen, and the check run (a stepwise speed profile) depends on exactly that.
#include "host/residual/effects.hpp"
#include "host/thermal/fit.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"

#include <string>
#include <vector>

namespace btsm::residual {

struct BaseConfounding {
  double multiple_correlation = 0;  // R of the parameter with all free base parameters (0..1)
  double inflation = 1;             // sigma / sigma with the base parameters known = 1 / sqrt(1 - R^2)
  double pair_correlation = 0;      // the largest |correlation| with one base parameter (signed)
  std::string partner;              // that base parameter's name ("" when no base parameter is free)
};

// From a joint refit's covariance (network order, zero rows for held parameters): the confounding
// of `param` with the first `base_count` parameters (the base network's).
BaseConfounding base_confounding(const thermal::Network& net, int base_count, const thermal::FitResult& fr, const std::string& param);

struct TriggerCoverage {
  int triggers = 0;       // triggers of the transient (starts, speed changes as the trigger counts them)
  int while_running = 0;  // of them: speed changes while the spindle runs (the others: starts from standstill)
  int while_active = 0;   // of them: with the previous transient still above `active_share` of its start
  double max_state = 0;   // the largest share of a previous transient left at a trigger (0..1)
};

// The triggers of a transient with decay time `tau_s` in `recs`, and how many arrive while the
// previous one is still above `active_share` of its initial value (exp(-dt/tau) > active_share).
TriggerCoverage trigger_coverage(const thermal::Network& net, const std::vector<thermal::Recording>& recs, TransientTrigger trigger,
                                 double tau_s, double active_share = 0.2);

}  // namespace btsm::residual
