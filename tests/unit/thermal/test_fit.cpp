// The whole cooling-first fit on the noisy reference warm-ups (5 x 7201 rows, sigma 5 mK) against
// the known truth: parameters within 2 sigma, weak ones flagged, residual at the noise level.
#include "host/thermal/fit.hpp"
#include "host/thermal/reduce.hpp"
#include "host/thermal/simulator.hpp"
#include "host/thermal/validate.hpp"
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

// A fit that ends at its noise floor is left exactly as it was: its final stage is not solved again
// from other starts (fit.hpp: FitOptions::restart_above_noise_factor), which would only cost time.
TEST(ThermalFit, AFitAtItsNoiseFloorTriesNoOtherStart) {
  const auto& rf = reference_fit();
  EXPECT_EQ(rf.fit.final_starts_tried, 1);
  EXPECT_EQ(rf.fit.final_start, "staged");
  EXPECT_LT(rf.fit.rms_K, 2 * rf.fit.noise_floor_K) << "the floor the fit was compared with";
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

TEST(ThermalValidate, SelfAndExternalValidationMeetTheReferenceToolchain) {
  const auto& rf = reference_fit();
  std::vector<std::string> files = test::warmup_files();
  files.push_back(test::kStepwise);
  double worst_nmse = 1, worst_mape = 0;
  for (const auto& f : files) {
    const Recording rec = read_recording_csv(test::ref_dir() + "/" + f);
    const RecordingValidation v = validate_recording(rf.net, rf.fit.params, rec);
    for (std::size_t m = 0; m < v.all.size(); ++m) {
      EXPECT_GE(v.all[m].nmse, 0.99997) << f << " " << rf.net.measurements[m].column;
      worst_nmse = std::min(worst_nmse, v.all[m].nmse);
    }
    for (const auto& sp : v.steady) {
      EXPECT_LE(sp.mape_percent, 0.11) << f;
      worst_mape = std::max(worst_mape, sp.mape_percent);
    }
    if (f != test::kStepwise) {
      EXPECT_EQ(v.steady.size(), 1u) << f;
    }
    if (f == test::kStepwise) {
      // external run against the noise-free truth
      const Recording clean = read_recording_csv(test::ref_dir() + "/clean/" + f);
      const double err = (v.predicted_c - clean.temp_c).cwiseAbs().maxCoeff();
      std::cout << "external stepwise run: max |predicted - truth| = " << err << " K\n";
      for (int node = 0; node < 4; ++node) {
        Eigen::Index k = 0;
        const double e = (v.predicted_c.col(node) - clean.temp_c.col(node)).cwiseAbs().maxCoeff(&k);
        std::cout << "  node " << node << " max " << e << " at t = " << rec.time_s[static_cast<std::size_t>(k)] << " s; x0 err "
                  << v.initial_state_c[node] - clean.temp_c(0, node) << "\n";
      }
      EXPECT_LE(err, 0.005);
    }
  }
  std::cout << "worst NMSE " << worst_nmse << ", worst steady MAPE " << worst_mape << " %\n";
}

TEST(ThermalValidate, HankelSingularValuesOfTheFittedModel) {
  const auto& rf = reference_fit();
  const SpeedReduction r = reduce_at_speed(rf.net, rf.fit.params, 6000.0);
  const double hsv[4] = {0.18980, 0.059386, 0.010976, 0.0021142};
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(r.hsv[i] / hsv[i], 1.0, i < 3 ? 1e-3 : 5e-3) << i;
}

}  // namespace
}  // namespace btsm::thermal
