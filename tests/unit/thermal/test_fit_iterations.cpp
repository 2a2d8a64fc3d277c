// The fit's iteration budget: the default converges on the demo's recordings (a model that lacks
// the plant's effect, where the final stage needs about 100 iterations and 60 used to stop it),
// and a budget too small is reported as not converged, at exactly that many iterations.
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

FitResult fit_demo(int max_iterations) {
  const DemoRecordings d;
  FitOptions o;
  o.sum_capacitance_J_per_K = 20478.7;
  if (max_iterations > 0) o.max_iterations = max_iterations;
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

}  // namespace
}  // namespace btsm::thermal
