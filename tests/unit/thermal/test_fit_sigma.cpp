// Honest sigma: on recordings of the simulated module (tests/data/module-warmups: btsm record at
// 5 s, no hidden effect, so the plant's truth is the spindle4 preset) the fit's residuals are
// strongly autocorrelated and repeat from run to run. The covariance for correlated residuals
// must put the truth within 2 sigma of every identifiable parameter, where the white-noise
// covariance misses it by tens of sigma; and its building blocks must do what they say on series
// with known answers. Calibration over many experiments: sigma_coverage_test.cpp.
#include "host/thermal/fit.hpp"
#include "host/thermal/fit_uncertainty.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>

namespace btsm::thermal {
namespace {

struct ModuleFit {
  Network net = preset_network("spindle4");
  std::vector<Recording> recs;
  FitResult fit;
  explicit ModuleFit(bool correlated) {
    for (const char* f : {"warmup_4000rpm.csv", "warmup_6000rpm.csv", "warmup_8000rpm.csv"})
      recs.push_back(read_recording_csv(std::string(BTSM_TEST_DATA_DIR) + "/module-warmups/" + f));
    map_measurements(net, recs, {"shaft=T5"});
    FitOptions o;
    o.sum_capacitance_J_per_K = 20478.7;
    o.correlated_residuals = correlated;
    fit = fit_network(net, recs, o);
  }
  // |estimate - truth| / sigma of every parameter the fit calls identifiable (or weakly so).
  std::vector<std::pair<std::string, double>> identifiable_z() const {
    const Eigen::VectorXd truth = test::true_parameters(net);
    std::vector<std::pair<std::string, double>> z;
    for (int i = 0; i < net.param_count(); ++i) {
      const auto& e = fit.estimates[static_cast<std::size_t>(i)];
      if (e.status != Identifiability::Good && e.status != Identifiability::Weak) continue;
      z.emplace_back(e.name, std::abs(e.value - truth[i]) / e.sigma);
    }
    return z;
  }
};

const ModuleFit& correlated_fit() {
  static const ModuleFit f(true);
  return f;
}

TEST(ThermalFitSigma, TruthLiesWithinTwoSigmaForEveryIdentifiableParameter) {
  // The demo's warm-ups: every parameter the fit calls identifiable (or weakly so) has the truth
  // within 2 sigma. The per-run Bartlett sum this replaced put C1 at 2.41 and Rc_a1 at 2.15 sigma.
  const auto& mf = correlated_fit();
  ASSERT_TRUE(mf.fit.converged);
  const auto z = mf.identifiable_z();
  ASSERT_GE(z.size(), 18u) << "the data set no longer identifies the network";
  for (const auto& [name, zi] : z) {
    std::cout << name << " |estimate - truth| = " << zi << " sigma\n";
    EXPECT_LE(zi, 2.0) << name;
  }
  std::cout << "bandwidths (rows):";
  for (int b : mf.fit.correlation_rows) std::cout << " " << b;
  std::cout << "\n";
  for (int b : mf.fit.correlation_rows) EXPECT_GT(b, 50) << "module residuals are correlated over minutes";
  // What the data cannot resolve is labelled so, not given a tiny sigma: the linear friction terms
  // (truth 0.0043 and 0.0073 W beside 37 and 28 W of the 5/3-power terms).
  for (const auto& e : mf.fit.estimates)
    if (e.name == "qf3" || e.name == "qf4") {
      EXPECT_EQ(e.status, Identifiability::NotIdentifiable) << e.name;
    }
  EXPECT_NE(mf.fit.sigma_method.find("Driscoll-Kraay"), std::string::npos);
}

TEST(ThermalFitSigma, WhiteNoiseSigmaMissesTheTruthOnTheSameData) {
  const ModuleFit white(false);
  const auto z = white.identifiable_z();
  int outside2 = 0;
  double worst = 0;
  for (const auto& [name, zi] : z) {
    outside2 += zi > 2.0 ? 1 : 0;
    worst = std::max(worst, zi);
  }
  std::cout << "white-noise sigma: " << outside2 << " of " << z.size() << " outside 2 sigma, worst " << worst << " sigma\n";
  EXPECT_GT(outside2, static_cast<int>(z.size()) / 2);
  EXPECT_GT(worst, 20.0);
  // same estimates, only sigma differs
  const auto& c = correlated_fit();
  for (int i = 0; i < white.net.param_count(); ++i)
    EXPECT_DOUBLE_EQ(white.fit.params[i], c.fit.params[i]) << white.net.params[static_cast<std::size_t>(i)].name;
}

TEST(ThermalFitSigma, ReferenceRecordingsWithWhiteNoiseKeepTheirSigma) {
  // tnm-reference: 5 mK white noise, so the correlated-residual sigma must stay near the classical
  // one. Summing the runs' scores (Driscoll-Kraay) adds their cross products, zero on average for
  // independent runs but noisy where a parameter's information sits in a few short transients
  // (the shaft's 60 s): measured 0.73 (rav3) .. 1.03 of the classical sigma on this set.
  const Network net = preset_network("spindle4");
  std::vector<Recording> recs;
  for (const auto& f : test::warmup_files()) recs.push_back(read_recording_csv(test::ref_dir() + "/" + f));
  FitOptions o;
  o.sum_capacitance_J_per_K = 20478.7;
  const FitResult hac = fit_network(net, recs, o);
  o.correlated_residuals = false;
  const FitResult white = fit_network(net, recs, o);
  const Eigen::VectorXd truth = test::true_parameters(net);
  for (std::size_t i = 0; i < hac.estimates.size(); ++i) {
    const auto& e = hac.estimates[i];
    if (e.status == Identifiability::Fixed) continue;
    const double ratio = e.sigma / white.estimates[i].sigma;
    EXPECT_GT(ratio, 0.65) << e.name;
    EXPECT_LT(ratio, 1.15) << e.name;
    EXPECT_LE(std::abs(e.value - truth[static_cast<Eigen::Index>(i)]), 2 * e.sigma) << e.name;
  }
  for (int b : hac.correlation_rows) EXPECT_LE(b, 30);  // noise alone: a few lags by chance
}

TEST(ThermalFitSigma, RunsScoresAreSummedAtEachTimeSinceTheirStart) {
  // Two runs with the same misfit count as one piece of evidence, not two independent ones: the
  // summed series has twice the scores, so its long-run covariance is four times one run's, where
  // the per-run sum gave two.
  std::mt19937 rng(5);
  std::normal_distribution<double> n01;
  const int rows = 400, shared = 2, per_run = 1;
  Eigen::MatrixXd g(rows, shared + per_run), h(rows - 100, shared + per_run);
  for (int k = 0; k < rows; ++k)
    for (int c = 0; c < shared + per_run; ++c) g(k, c) = n01(rng);
  for (int k = 0; k < h.rows(); ++k)
    for (int c = 0; c < shared + per_run; ++c) h(k, c) = n01(rng);
  const Eigen::MatrixXd s = fitting::scores_summed_over_runs({g, g}, shared, per_run);
  ASSERT_EQ(s.rows(), rows);
  ASSERT_EQ(s.cols(), shared + 2 * per_run);
  EXPECT_LT((s.leftCols(shared) - 2 * g.leftCols(shared)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((s.col(shared) - g.col(shared)).cwiseAbs().maxCoeff(), 1e-12);      // run 0's own state
  EXPECT_LT((s.col(shared + 1) - g.col(shared)).cwiseAbs().maxCoeff(), 1e-12);  // run 1's own state
  const Eigen::MatrixXd one = fitting::long_run_covariance(g.leftCols(shared), 10);
  const Eigen::MatrixXd both = fitting::long_run_covariance(s.leftCols(shared), 10);
  EXPECT_LT((both - 4 * one).cwiseAbs().maxCoeff(), 1e-9 * one.cwiseAbs().maxCoeff());
  // A shorter run ends early: its rows add to the first rows only.
  const Eigen::MatrixXd sh = fitting::scores_summed_over_runs({g, h}, shared, per_run);
  EXPECT_LT((sh.topRows(h.rows()).leftCols(shared) - g.topRows(h.rows()).leftCols(shared) - h.leftCols(shared)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((sh.bottomRows(100).leftCols(shared) - g.bottomRows(100).leftCols(shared)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(sh.bottomRows(100).col(shared + 1).cwiseAbs().maxCoeff(), 0.0);
}

TEST(ThermalFitSigma, CorrelationBandwidthFollowsTheSeries) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  const int rows = 20000;
  Eigen::MatrixXd white(rows, 2), ar(rows, 2);
  double a = 0, b = 0;
  for (int k = 0; k < rows; ++k) {
    white(k, 0) = n01(rng);
    white(k, 1) = k % 7 == 0 ? std::nan("") : n01(rng);  // missing cells are allowed
    a = 0.99 * a + n01(rng);
    b = 0.5 * b + n01(rng);
    ar(k, 0) = a;
    ar(k, 1) = b;
  }
  EXPECT_LE(fitting::residual_correlation_rows(white), 30);  // a few lags by chance
  // AR(1) with rho 0.99: integrated correlation time (1 + rho) / (1 - rho) = 199 rows; the widest
  // channel counts
  const int bw = fitting::residual_correlation_rows(ar);
  EXPECT_GT(bw, 100);
  EXPECT_LT(bw, 2000);
}

TEST(ThermalFitSigma, LongRunCovarianceIsTheBartlettSum) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n01;
  const int rows = 300, cols = 3, L = 17;
  Eigen::MatrixXd g(rows, cols);
  for (int k = 0; k < rows; ++k)
    for (int c = 0; c < cols; ++c) g(k, c) = n01(rng) + (k > 0 ? 0.6 * g(k - 1, c) : 0.0);
  Eigen::MatrixXd direct = Eigen::MatrixXd::Zero(cols, cols);
  for (int t = 0; t < rows; ++t)
    for (int s = 0; s < rows; ++s) {
      const int lag = std::abs(t - s);
      if (lag > L) continue;
      direct += (1.0 - static_cast<double>(lag) / (L + 1)) * g.row(t).transpose() * g.row(s);
    }
  const Eigen::MatrixXd fast = fitting::long_run_covariance(g, L);
  EXPECT_LT((fast - direct).cwiseAbs().maxCoeff(), 1e-9 * direct.cwiseAbs().maxCoeff());
  // bandwidth 0 = the plain sum of outer products
  EXPECT_LT((fitting::long_run_covariance(g, 0) - g.transpose() * g).cwiseAbs().maxCoeff(), 1e-9 * direct.cwiseAbs().maxCoeff());
}

}  // namespace
}  // namespace btsm::thermal
