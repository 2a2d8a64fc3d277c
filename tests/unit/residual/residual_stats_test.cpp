// Whiteness and correlation statistics against known distributions.
#include "host/residual/residual_stats.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace btsm::residual {
namespace {

TEST(ResidualStats, ChiSquareSurvivalMatchesTables) {
  EXPECT_NEAR(chi2_survival(3.841458820694124, 1), 0.05, 1e-9);
  EXPECT_NEAR(chi2_survival(31.410432844230918, 20), 0.05, 1e-9);
  EXPECT_NEAR(chi2_survival(37.56623478662507, 20), 0.01, 1e-9);
  EXPECT_NEAR(chi2_survival(2.0, 2), std::exp(-1.0), 1e-12);
  EXPECT_DOUBLE_EQ(chi2_survival(0.0, 5), 1.0);
}

TEST(ResidualStats, LjungBoxAcceptsWhiteNoiseAndRejectsAr1) {
  std::mt19937 rng(42);
  std::normal_distribution<double> n01(0.0, 1.0);
  int rejected = 0;
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<double> x(500);
    for (double& v : x) v = n01(rng);
    if (ljung_box(x).p_value < 0.01) ++rejected;
  }
  EXPECT_LE(rejected, 8);  // nominal 1 % of 200 = 2
  std::vector<double> ar(500);
  double s = 0;
  for (double& v : ar) { s = 0.5 * s + n01(rng); v = s; }
  const WhitenessTest t = ljung_box(ar);
  EXPECT_LT(t.p_value, 1e-6);
  EXPECT_NEAR(t.lag1, 0.5, 0.1);
}

TEST(ResidualStats, GapsAreSkippedNotBridged) {
  std::vector<double> x = {1, -1, 1, -1, NAN, NAN, 1, -1, 1, -1, 1, -1};
  const std::vector<double> r = autocorrelation(x, 2);
  EXPECT_LT(r[0], -0.6);
  EXPECT_GT(r[1], 0.5);
}

TEST(ResidualStats, CorrelationSignificanceAccountsForAutocorrelation) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  // two independent random walks correlate strongly by chance; the effective-n test must not trust it
  std::vector<double> a(2000), b(2000);
  double sa = 0, sb = 0;
  for (int i = 0; i < 2000; ++i) { sa = 0.999 * sa + n01(rng); sb = 0.999 * sb + n01(rng); a[i] = sa; b[i] = sb; }
  const CorrelationTest spurious = correlation_test("b", a, b);
  EXPECT_GT(spurious.p_value, 1e-3) << spurious.r << " n_eff " << spurious.n_eff;
  std::vector<double> c(2000);
  for (int i = 0; i < 2000; ++i) c[i] = a[i] + 5.0 * n01(rng);
  EXPECT_LT(correlation_test("c", c, a).p_value, 1e-6);
  EXPECT_TRUE(std::isnan(pearson({1, 1, 1}, {1, 2, 3})));
}

}  // namespace
}  // namespace btsm::residual
