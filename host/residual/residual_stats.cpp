// Residual statistics (see residual_stats.hpp).
#include "host/residual/residual_stats.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace btsm::residual {
namespace {

// Regularised lower incomplete gamma P(a, x) by its series (x < a + 1) or Q by the continued
// fraction (Lentz), as in every numerical text; accurate to ~1e-14.
double gamma_q(double a, double x) {
  if (x <= 0) return 1.0;
  const double lg = std::lgamma(a);
  if (x < a + 1.0) {
    double sum = 1.0 / a, term = sum, ap = a;
    for (int i = 0; i < 1000; ++i) {
      ap += 1.0;
      term *= x / ap;
      sum += term;
      if (std::abs(term) < std::abs(sum) * 1e-15) break;
    }
    return 1.0 - sum * std::exp(-x + a * std::log(x) - lg);
  }
  const double tiny = 1e-300;
  double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
  for (int i = 1; i < 1000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < tiny) d = tiny;
    c = b + an / c;
    if (std::abs(c) < tiny) c = tiny;
    d = 1.0 / d;
    const double del = d * c;
    h *= del;
    if (std::abs(del - 1.0) < 1e-15) break;
  }
  return std::exp(-x + a * std::log(x) - lg) * h;
}

}  // namespace

double chi2_survival(double x, double k) { return std::clamp(gamma_q(0.5 * k, 0.5 * x), 0.0, 1.0); }

double normal_survival(double z) { return 0.5 * std::erfc(z / std::sqrt(2.0)); }

std::vector<double> autocorrelation(const std::vector<double>& x, int max_lag) {
  double sum = 0;
  int n = 0;
  for (double v : x)
    if (std::isfinite(v)) { sum += v; ++n; }
  std::vector<double> r(std::max(max_lag, 0), std::numeric_limits<double>::quiet_NaN());
  if (n < 3) return r;
  const double mean = sum / n;
  double c0 = 0;
  for (double v : x)
    if (std::isfinite(v)) c0 += (v - mean) * (v - mean);
  if (!(c0 > 0)) return r;
  for (int lag = 1; lag <= max_lag; ++lag) {
    double c = 0;
    for (size_t k = lag; k < x.size(); ++k)
      if (std::isfinite(x[k]) && std::isfinite(x[k - lag])) c += (x[k] - mean) * (x[k - lag] - mean);
    r[lag - 1] = c / c0;
  }
  return r;
}

WhitenessTest ljung_box(const std::vector<double>& x, int lags) {
  WhitenessTest t;
  double ss = 0;
  for (double v : x)
    if (std::isfinite(v)) { ++t.samples; ss += v * v; }
  t.rms = t.samples ? std::sqrt(ss / t.samples) : std::numeric_limits<double>::quiet_NaN();
  const int n = t.samples;
  t.lags = lags > 0 ? lags : std::min(20, n / 5);
  if (n < 10 || t.lags < 1) { t.p_value = std::numeric_limits<double>::quiet_NaN(); return t; }
  const std::vector<double> r = autocorrelation(x, t.lags);
  double q = 0;
  for (int k = 1; k <= t.lags; ++k)
    if (std::isfinite(r[k - 1])) q += r[k - 1] * r[k - 1] / (n - k);
  t.q = n * (n + 2.0) * q;
  t.lag1 = r.empty() ? 0 : r[0];
  t.p_value = chi2_survival(t.q, t.lags);
  return t;
}

double pearson(const std::vector<double>& a, const std::vector<double>& b) {
  const size_t n = std::min(a.size(), b.size());
  double sa = 0, sb = 0;
  int m = 0;
  for (size_t i = 0; i < n; ++i)
    if (std::isfinite(a[i]) && std::isfinite(b[i])) { sa += a[i]; sb += b[i]; ++m; }
  if (m < 3) return std::numeric_limits<double>::quiet_NaN();
  const double ma = sa / m, mb = sb / m;
  double saa = 0, sbb = 0, sab = 0;
  for (size_t i = 0; i < n; ++i)
    if (std::isfinite(a[i]) && std::isfinite(b[i])) {
      saa += (a[i] - ma) * (a[i] - ma);
      sbb += (b[i] - mb) * (b[i] - mb);
      sab += (a[i] - ma) * (b[i] - mb);
    }
  if (!(saa > 0) || !(sbb > 0)) return std::numeric_limits<double>::quiet_NaN();
  return sab / std::sqrt(saa * sbb);
}

CorrelationTest correlation_test(const std::string& name, const std::vector<double>& residual,
                                 const std::vector<double>& signal) {
  CorrelationTest t;
  t.signal = name;
  t.r = pearson(residual, signal);
  if (!std::isfinite(t.r)) { t.p_value = 1; return t; }
  int n = 0;
  for (size_t i = 0; i < std::min(residual.size(), signal.size()); ++i)
    if (std::isfinite(residual[i]) && std::isfinite(signal[i])) ++n;
  const std::vector<double> ra = autocorrelation(residual, 1), rb = autocorrelation(signal, 1);
  const double r1a = std::isfinite(ra[0]) ? ra[0] : 0, r1b = std::isfinite(rb[0]) ? rb[0] : 0;
  const double prod = std::clamp(r1a * r1b, -0.999, 0.999);
  t.n_eff = std::max(3.0, n * (1 - prod) / (1 + prod));
  const double z = std::atanh(std::clamp(t.r, -0.999999, 0.999999)) * std::sqrt(std::max(t.n_eff - 3.0, 1e-9));
  t.p_value = 2 * normal_survival(std::abs(z));
  return t;
}

}  // namespace btsm::residual
