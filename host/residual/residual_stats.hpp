#pragma once
// Statistics of model residuals: whiteness (autocorrelation, Ljung-Box) and correlation with
// candidate explanatory signals, with significance corrected for autocorrelation.
#include <string>
#include <vector>

namespace btsm::residual {

// Sample autocorrelation r_1..r_max_lag of a series; NaN entries are skipped (a lag pair counts only
// when both values are finite). The mean is removed first.
std::vector<double> autocorrelation(const std::vector<double>& x, int max_lag);

// Upper tail of the chi-square distribution with k degrees of freedom, P(X > x).
double chi2_survival(double x, double k);

// Ljung-Box portmanteau test of whiteness.
struct WhitenessTest {
  int samples = 0;        // finite samples used
  int lags = 0;           // h
  double q = 0;           // Q = n(n+2) sum r_k^2/(n-k)
  double p_value = 1;     // P(chi2_h > Q)
  double lag1 = 0;        // r_1
  double rms = 0;         // rms of the series (mean included), same unit as x
};
// lags <= 0: h = min(20, n/5).
WhitenessTest ljung_box(const std::vector<double>& x, int lags = 0);

// Pearson correlation over pairs where both are finite; NaN if fewer than 3 pairs or a constant.
double pearson(const std::vector<double>& a, const std::vector<double>& b);

// Two-sided p-value of a correlation r between two autocorrelated series, using Bartlett's
// effective sample size n_eff = n (1 - r1a r1b) / (1 + r1a r1b) and Fisher's z.
struct CorrelationTest {
  std::string signal;
  double r = 0;
  double n_eff = 0;
  double p_value = 1;
};
CorrelationTest correlation_test(const std::string& name, const std::vector<double>& residual,
                                 const std::vector<double>& signal);

// Standard normal upper tail P(Z > z).
double normal_survival(double z);

}  // namespace btsm::residual
