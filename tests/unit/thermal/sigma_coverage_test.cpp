// Sigma calibrated over experiments: eight simulated module experiments with known truth (the
// demo's protocol -- 4 h warm-up, 3 h cooling, three times -- at three speeds drawn per seed, no
// hidden effect, AD7794 noise seed = the seed), recorded by `btsm record` from `btsm sim-module`
// (tests/data/module-warmups/make_module_warmups.sh), each fitted like the demo's warm-ups.
// Over all identifiable parameters x experiments the truth must lie within 1 sigma near 68 % and
// within 2 sigma near 95 % of the time: bounds both ways, so a sigma that claims too much (the
// per-run Bartlett sum: 61 % / 89 % on these eight) fails, and so does one merely inflated (twice
// the sigma puts ~95 % within 1 sigma). Each experiment's staged fit must also end no higher than
// a joint fit started at the truth: a start set or stage order that leaves the truth's basin fails.
#include "host/thermal/fit.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

namespace btsm::thermal {
namespace {

namespace fs = std::filesystem;

struct Experiment {
  unsigned seed;
  const char* rpms;  // three warm-up speeds, drawn once (3000..9000 rpm, 250 rpm steps, >= 750 apart)
};
constexpr Experiment kExperiments[] = {{2, "7000,7750,6250"}, {3, "6750,5750,4750"}, {4, "6250,3750,8750"},
                                       {5, "6750,6000,7500"}, {6, "5750,3250,4750"}, {7, "3250,7750,4250"},
                                       {8, "7000,5500,3500"}, {9, "4250,3000,6750"}};

TEST(SigmaCoverage, TruthWithinOneAndTwoSigmaNearNominalOverExperiments) {
  const fs::path dir = fs::temp_directory_path() / ("btsm-sigma-coverage-" + std::to_string(::getpid()));
  int within1 = 0, within2 = 0, count = 0;
  double worst = 0, truth_basin_ratio_max = 0;
  std::string worst_name;
  for (const auto& ex : kExperiments) {
    const fs::path out = dir / ("s" + std::to_string(ex.seed));
    const std::string cmd = "bash '" + std::string(BTSM_TEST_DATA_DIR) + "/module-warmups/make_module_warmups.sh' '" +
                            std::string(BTSM_BIN_DIR) + "/btsm' '" + out.string() + "' " + std::to_string(ex.seed) + " " +
                            ex.rpms + " > /dev/null 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    Network net = preset_network("spindle4");
    std::vector<Recording> recs;
    for (const auto& e : fs::directory_iterator(out)) recs.push_back(read_recording_csv(e.path().string()));
    ASSERT_EQ(recs.size(), 3u);
    map_measurements(net, recs, {"shaft=T5"});
    FitOptions o;
    o.sum_capacitance_J_per_K = 20478.7;
    const FitResult fit = fit_network(net, recs, o);
    ASSERT_TRUE(fit.converged) << "seed " << ex.seed;
    const Eigen::VectorXd truth = test::true_parameters(net);
    // The staged pipeline's starts must reach the minimum of the truth's own basin (or a lower
    // one): a joint fit started at the truth may end no lower than the staged fit.
    FitOptions from_truth = o;
    from_truth.staged = false;
    from_truth.start = truth;
    const FitResult truth_fit = fit_network(net, recs, from_truth);
    EXPECT_LE(fit.rms_K, truth_fit.rms_K * (1 + 1e-3))
        << "seed " << ex.seed << ": the staged fit ended in a worse minimum than the one a fit started at the truth reaches";
    truth_basin_ratio_max = std::max(truth_basin_ratio_max, fit.rms_K / truth_fit.rms_K);
    std::cout << "seed " << ex.seed << " (" << ex.rpms << " rpm):";
    for (int i = 0; i < net.param_count(); ++i) {
      const auto& e = fit.estimates[static_cast<std::size_t>(i)];
      if (e.status != Identifiability::Good && e.status != Identifiability::Weak) continue;
      const double z = std::abs(e.value - truth[i]) / e.sigma;
      within1 += z <= 1 ? 1 : 0;
      within2 += z <= 2 ? 1 : 0;
      ++count;
      if (z > worst) worst = z, worst_name = e.name + " (seed " + std::to_string(ex.seed) + ")";
      std::cout << " " << e.name << " " << z;
    }
    std::cout << "\n";
  }
  fs::remove_all(dir);
  ASSERT_GE(count, 8 * 18);
  const double c1 = static_cast<double>(within1) / count, c2 = static_cast<double>(within2) / count;
  std::cout << count << " parameter-experiments: within 1 sigma " << c1 << ", within 2 sigma " << c2 << ", worst " << worst
            << " sigma, " << worst_name << "; staged / truth-started fit rms at most " << truth_basin_ratio_max << "\n";
  // Measured 0.677 / 0.944. No bound on the worst |z|: seed 8 (7000, 5500, 3500 rpm) ends 8-12
  // sigma from the truth (qf3 0.50 W takes over part of qf1; Ra1, rav1 follow), but that point is
  // the data's own minimum, not a start's: the fit started at the truth ends there too (checked
  // above for every experiment), and holding qf3 at its true value costs 15.5 % more squared
  // residual (rms 1.109 against 1.031 mK). The recordings' systematic difference from the network
  // (fit rms 1.0 mK against 0.34 mK white noise) carries the bias; no start can mend it, and a
  // sigma computed from the residuals does not see it.
  EXPECT_GE(c1, 0.62);
  EXPECT_LE(c1, 0.85);
  EXPECT_GE(c2, 0.91);
  EXPECT_LE(c2, 0.995);
}

}  // namespace
}  // namespace btsm::thermal
