// The fit's iteration budget: the default converges on the demo's recordings (a model that lacks
// the plant's effect, where the final stage needs about 100 iterations and 60 used to stop it),
// and a budget too small is reported as not converged, at exactly that many iterations -- unless
// FitOptions::continuation lets a stage still descending at its budget go on (to its cap).
#include "host/thermal/fit.hpp"

#include <gtest/gtest.h>

#include <string>

namespace btsm::thermal {
namespace {

struct DemoRecordings {
  Network net = preset_network("spindle4");
  std::vector<Recording> recs;
  DemoRecordings() {
    remap_measurements(net, {"shaft=T5"});
    for (const char* f : {"warmup_4000rpm.csv", "warmup_6000rpm.csv", "warmup_8000rpm.csv"})
      recs.push_back(read_recording_csv(std::string(BTSM_TEST_DATA_DIR) + "/demo-warmups/" + f));
  }
};

FitResult fit_demo(int max_iterations, const BudgetContinuation& continuation = {}) {
  const DemoRecordings d;
  FitOptions o;
  o.sum_capacitance_J_per_K = 20478.7;
  if (max_iterations > 0) o.max_iterations = max_iterations;
  o.continuation = continuation;
  return fit_network(d.net, d.recs, o);
}

TEST(ThermalFitIterations, DefaultBudgetConvergesOnTheDemoRecordings) {
  const FitResult r = fit_demo(0);
  ASSERT_FALSE(r.stages.empty());
  EXPECT_TRUE(r.converged) << "final stage stopped after " << r.stages.back().iterations << " iterations";
  EXPECT_GT(r.stages.back().iterations, 60) << "the old budget would have done; the data set no longer tests the default";
  for (const auto& w : r.warnings) EXPECT_EQ(w.find("iteration limit"), std::string::npos) << w;
}

TEST(ThermalFitIterations, ASmallBudgetIsReportedAsNotConverged) {
  const FitResult r = fit_demo(20);
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(r.stages.back().iterations, 20);
  bool said = false;
  for (const auto& w : r.warnings) said = said || w.find("iteration limit") != std::string::npos;
  EXPECT_TRUE(said);
  // the start stages keep their own budget
  for (std::size_t s = 0; s + 1 < r.stages.size(); ++s) EXPECT_LE(r.stages[s].iterations, FitOptions{}.start_iterations);
}

// The demo's final stage needs about 100 iterations: a budget of 20 stops it on a slope, and the
// continuation (chunks of 20 while a chunk gains > 0.01 %, up to 10x the budget) takes it to the
// minimum the default budget reaches.
TEST(ThermalFitIterations, ABudgetTooSmallIsContinuedWhileTheCostStillFalls) {
  const FitResult full = fit_demo(0);
  const FitResult r = fit_demo(20, BudgetContinuation{10.0, 20, 1e-4});
  ASSERT_TRUE(full.converged);
  EXPECT_TRUE(r.converged) << "stopped after " << r.stages.back().iterations << " iterations";
  EXPECT_GT(r.stages.back().continuations, 0);
  EXPECT_GT(r.stages.back().iterations, 20);
  EXPECT_LE(r.stages.back().iterations, 200);
  EXPECT_LT(r.rms_K, full.rms_K * 1.001) << "continued to " << r.rms_K << " K, the default budget reaches " << full.rms_K << " K";
  for (const auto& w : r.warnings) EXPECT_EQ(w.find("iteration limit"), std::string::npos) << w;
  // the start stages are never continued
  for (std::size_t s = 0; s + 1 < r.stages.size(); ++s) EXPECT_EQ(r.stages[s].continuations, 0) << r.stages[s].name;
}

TEST(ThermalFitIterations, TheContinuationStopsAtItsCapAndOnAFlatChunk) {
  // the cap: 2x a budget of 20 = one chunk of 20, still not at the minimum
  const FitResult capped = fit_demo(20, BudgetContinuation{2.0, 20, 1e-4});
  EXPECT_FALSE(capped.converged);
  EXPECT_EQ(capped.stages.back().iterations, 40);
  EXPECT_EQ(capped.stages.back().continuations, 1);
  // a gain threshold no chunk reaches (a chunk never lowers the cost by 100 %): stops at the budget
  const FitResult flat = fit_demo(20, BudgetContinuation{10.0, 20, 1.0});
  EXPECT_FALSE(flat.converged);
  EXPECT_EQ(flat.stages.back().iterations, 20);
  EXPECT_EQ(flat.stages.back().continuations, 0);
}

}  // namespace
}  // namespace btsm::thermal
