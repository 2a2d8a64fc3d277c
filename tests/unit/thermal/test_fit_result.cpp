// The final check of every fit (fit_result_problem): a result with a non-finite cost, values the
// network forbids or heat sources the fit drove all to (near) 0 W is no usable model -- what `btsm fit`
// printed as "converged" with rms inf before.
#include "host/thermal/fit.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace btsm::thermal {
namespace {

FitResult nominal_result(const Network& net) {
  FitResult r;
  r.params = default_parameters(net);
  r.rms_K = 0.01;
  return r;
}

TEST(FitResultProblem, UsableNonFiniteOutOfBoundsAndDegenerate) {
  const Network net = preset_network("spindle4");
  FitResult r = nominal_result(net);
  EXPECT_EQ(fit_result_problem(net, r), "");
  r.rms_K = std::numeric_limits<double>::infinity();
  EXPECT_NE(fit_result_problem(net, r).find("final cost is not finite"), std::string::npos);
  r.rms_K = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(fit_result_problem(net, r).find("final cost is not finite"), std::string::npos);
  r = nominal_result(net);
  r.params[net.param_index("R12")] = -0.5;
  EXPECT_NE(fit_result_problem(net, r).find("'R12' = -0.5"), std::string::npos) << fit_result_problem(net, r);
  r = nominal_result(net);
  r.params[net.param_index("C3")] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(fit_result_problem(net, r).find("'C3' is not finite"), std::string::npos);
  r = nominal_result(net);
  for (const char* q : {"qf1", "qf2", "qf3", "qf4"}) r.params[net.param_index(q)] = 0.0;
  EXPECT_NE(fit_result_problem(net, r).find("degenerate"), std::string::npos);
  // One source left heating is a model.
  r.params[net.param_index("qf2")] = 1.0;
  EXPECT_EQ(fit_result_problem(net, r), "");
  // Sources a hair above 0 W (where a fit stops at the lower bound) heat no more than the misfit:
  // still degenerate. Judged by the steady rise against the rms residual, not by the watts.
  for (const char* q : {"qf1", "qf2", "qf3", "qf4"}) r.params[net.param_index(q)] = 1e-6;
  EXPECT_NE(fit_result_problem(net, r).find("degenerate"), std::string::npos);
  r.rms_K = 0;  // a perfect fit: any heat at all is resolved
  EXPECT_EQ(fit_result_problem(net, r), "");
}

// A fit pinned at a log-scaled parameter's bound returns exp(log(bound)), an ulp beyond it: that
// is the bound (the demo fit's R23 = 10000 K/W was refused as "outside [0.0001, 10000]").
TEST(FitResultProblem, AValueAtItsBoundIsInsideIt) {
  const Network net = preset_network("spindle4");
  FitResult r = nominal_result(net);
  const int i = net.param_index("R23");
  const double max = net.params[static_cast<std::size_t>(i)].max;
  r.params[i] = std::nextafter(max, 2 * max);
  r.params[i] = std::nextafter(r.params[i], 2 * max);
  EXPECT_EQ(fit_result_problem(net, r), "");
  r.params[i] = max * (1 + 1e-6);
  EXPECT_NE(fit_result_problem(net, r).find("'R23'"), std::string::npos);
}

TEST(FitResultProblem, SourcesTheNetworkHoldsAtZeroAreAChoice) {
  Network net = preset_network("spindle4");
  FitResult r = nominal_result(net);
  for (const char* q : {"qf1", "qf2", "qf3", "qf4"}) {
    auto& p = net.params[static_cast<std::size_t>(net.param_index(q))];
    p.fixed = true;
    p.initial_auto = false;
    p.initial = 0.0;
    r.params[net.param_index(q)] = 0.0;
  }
  EXPECT_EQ(fit_result_problem(net, r), "");
}

}  // namespace
}  // namespace btsm::thermal
