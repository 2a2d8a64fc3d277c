// The whole cooling-first fit on the noisy reference warm-ups (5 x 7201 rows, sigma 5 mK) against
// the known truth: parameters within 2 sigma, weak ones flagged, residual at the noise level.
#include "host/thermal/fit.hpp"
#include "host/thermal/simulator.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

namespace btsm::thermal {
namespace {

struct ReferenceFit {
  Network net = preset_network("spindle4");
  std::vector<Recording> recs;
  FitResult fit;
  ReferenceFit() {
    for (const auto& f : test::warmup_files()) recs.push_back(read_recording_csv(test::ref_dir() + "/" + f));
    FitOptions o;
    o.sum_capacitance_J_per_K = 20478.7;
    fit = fit_network(net, recs, o);
  }
};

const ReferenceFit& reference_fit() {
  static const ReferenceFit f;
  return f;
}

TEST(ThermalFit, RecoversEveryParameterWithin2Sigma) {
  const auto& rf = reference_fit();
  const Eigen::VectorXd truth = test::true_parameters(rf.net);
  for (int i = 0; i < rf.net.param_count(); ++i) {
    const auto& e = rf.fit.estimates[static_cast<std::size_t>(i)];
    std::cout << e.name << " fit " << e.value << " truth " << truth[i] << " err% " << 100 * (e.value / truth[i] - 1)
              << " sigma " << e.sigma << " (" << identifiability_name(e.status) << ") " << e.note << "\n";
    EXPECT_LE(std::abs(e.value - truth[i]), 2 * e.sigma) << e.name;
  }
  for (const auto& s : rf.fit.stages) std::cout << s.name << " " << s.iterations << " it rms " << s.rms_K << " " << s.seconds << " s\n";
  for (const auto& w : rf.fit.warnings) std::cout << "warning: " << w << "\n";
  std::cout << "total " << rf.fit.seconds << " s, rms " << rf.fit.rms_K << " cond " << rf.fit.condition_number << "\n";
}

TEST(ThermalFit, WeakParametersAreReportedAsSuch) {
  const auto& rf = reference_fit();
  const Eigen::VectorXd truth = test::true_parameters(rf.net);
  const int i24 = rf.net.param_index("Rc_24");
  EXPECT_LE(std::abs(rf.fit.params[i24] / truth[i24] - 1), 0.15);
  for (const char* q : {"qf3", "qf4"}) {
    const auto& e = rf.fit.estimates[static_cast<std::size_t>(rf.net.param_index(q))];
    EXPECT_EQ(e.status, Identifiability::NotIdentifiable) << q;
  }
  EXPECT_NEAR(rf.fit.rms_K, 0.005, 0.0003);
  EXPECT_TRUE(rf.fit.converged);
}

}  // namespace
}  // namespace btsm::thermal
