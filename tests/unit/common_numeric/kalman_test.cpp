// Scalar Kalman filter: the reference filter (convergence to the closed-form steady state, the
// innovation gate: reject, count, re-initialise on a real step; reset, invalid input) and the MCU's
// fixed-point filter against it (setup over the configuration range, transient, steady state,
// rejections, reset, the shared gain memo, 24 h of measurements).
#include "common/kalman.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

namespace btsm {
namespace {

KalmanParams<double> params() {
  KalmanParams<double> p;
  p.process_noise_k2_per_s = 1e-4;
  p.measurement_noise_k = 0.01;
  p.dt_s = 5.0;
  p.gate_sigma = 5.0;
  p.max_consecutive_rejects = 3;
  return p;
}

TEST(Kalman, FirstMeasurementInitialises) {
  ScalarKalman<double> f(params());
  EXPECT_FALSE(f.initialized());
  EXPECT_EQ(f.update(21.5), KalmanOutcome::kInitialized);
  EXPECT_TRUE(f.initialized());
  EXPECT_DOUBLE_EQ(f.estimate(), 21.5);
  EXPECT_DOUBLE_EQ(f.variance(), 1e-4);  // r^2
}

TEST(Kalman, VarianceAndGainConvergeToTheClosedForm) {
  ScalarKalman<double> f(params());
  const double q = 1e-4 * 5.0, r2 = 1e-4;
  const double m = (q + std::sqrt(q * q + 4 * q * r2)) / 2;
  EXPECT_NEAR(f.steady_state_prior(), m, 1e-15);
  EXPECT_NEAR(f.steady_state_gain(), m / (m + r2), 1e-15);
  f.update(20.0);
  for (int i = 0; i < 50; ++i) EXPECT_EQ(f.update(20.0), KalmanOutcome::kAccepted);
  EXPECT_NEAR(f.variance(), m * (1 - m / (m + r2)), 1e-12);
}

TEST(Kalman, FiltersNoiseOnAConstantTemperature) {
  KalmanParams<double> p = params();
  p.process_noise_k2_per_s = 1e-8;  // nearly constant: strong averaging
  ScalarKalman<double> f(p);
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.01);
  double sum_sq = 0;
  int n = 0;
  for (int i = 0; i < 2000; ++i) {
    f.update(40.0 + noise(rng));
    if (i >= 1000) sum_sq += (f.estimate() - 40.0) * (f.estimate() - 40.0), ++n;
  }
  const double rms = std::sqrt(sum_sq / n);
  EXPECT_LT(rms, 0.01 / 3);  // far below the raw noise
  EXPECT_NEAR(rms * rms, f.variance(), 3 * f.variance());  // consistent with its own variance
  EXPECT_EQ(f.rejected_total(), 0);  // 5-sigma gate: no false rejects in 2000 samples expected
}

TEST(Kalman, SingleOutlierIsRejectedAndCounted) {
  ScalarKalman<double> f(params());
  for (int i = 0; i < 20; ++i) f.update(30.0);
  const double before = f.estimate();
  EXPECT_EQ(f.update(35.0), KalmanOutcome::kRejected);
  EXPECT_DOUBLE_EQ(f.estimate(), before);
  EXPECT_EQ(f.rejected_total(), 1);
  EXPECT_EQ(f.consecutive_rejects(), 1);
  EXPECT_EQ(f.update(30.0), KalmanOutcome::kAccepted);
  EXPECT_EQ(f.consecutive_rejects(), 0);
  EXPECT_EQ(f.rejected_total(), 1);
}

TEST(Kalman, RealStepIsFollowedAfterNConsecutiveRejects) {
  ScalarKalman<double> f(params());
  for (int i = 0; i < 20; ++i) f.update(30.0);
  EXPECT_EQ(f.update(33.0), KalmanOutcome::kRejected);
  EXPECT_EQ(f.update(33.0), KalmanOutcome::kRejected);
  EXPECT_EQ(f.update(33.0), KalmanOutcome::kReinitialized);
  EXPECT_DOUBLE_EQ(f.estimate(), 33.0);
  EXPECT_EQ(f.reinit_total(), 1);
  EXPECT_EQ(f.rejected_total(), 3);
  EXPECT_EQ(f.update(33.001), KalmanOutcome::kAccepted);
}

TEST(Kalman, NoReinitialisationWhenDisabled) {
  KalmanParams<double> p = params();
  p.max_consecutive_rejects = 0;
  ScalarKalman<double> f(p);
  for (int i = 0; i < 20; ++i) f.update(30.0);
  // The prior grows while rejecting, so the gate eventually opens on its own: count until it does.
  int rejects = 0;
  while (f.update(33.0) == KalmanOutcome::kRejected) ++rejects;
  EXPECT_GT(rejects, 3);
  EXPECT_EQ(f.reinit_total(), 0);
}

TEST(Kalman, ResetOnFaultForgetsTheEstimateButKeepsCounters) {
  ScalarKalman<double> f(params());
  for (int i = 0; i < 5; ++i) f.update(30.0);
  f.update(40.0);  // one reject
  f.reset();
  EXPECT_FALSE(f.initialized());
  EXPECT_EQ(f.update(25.0), KalmanOutcome::kInitialized);
  EXPECT_DOUBLE_EQ(f.estimate(), 25.0);
  EXPECT_EQ(f.rejected_total(), 1);
}

TEST(Kalman, NanMeasurementAndBadParametersChangeNothing) {
  ScalarKalman<double> f(params());
  f.update(30.0);
  EXPECT_EQ(f.update(NAN), KalmanOutcome::kInvalid);
  EXPECT_DOUBLE_EQ(f.estimate(), 30.0);
  KalmanParams<double> bad = params();
  bad.measurement_noise_k = 0.0;
  EXPECT_FALSE(f.configure(bad));
  EXPECT_EQ(f.update(30.0), KalmanOutcome::kInvalid);
  bad = params();
  bad.dt_s = -1;
  EXPECT_FALSE(f.configure(bad));
  EXPECT_TRUE(f.configure(params()));
}

TEST(Kalman, PredictOnlyGrowsTheUncertainty) {
  ScalarKalman<double> f(params());
  for (int i = 0; i < 20; ++i) f.update(30.0);
  const double p = f.variance();
  f.predict_only();
  EXPECT_NEAR(f.variance(), p + 5e-4, 1e-15);
}

// ---- The MCU's fixed-point filter ---------------------------------------------------------------

// The module's configuration (mK^2/s, mK^2, ms) and the same filter in double (K^2/s, K, s).
KalmanFixedParams fixed_params(uint32_t q = 400, uint32_t r = 2500, uint32_t dt_ms = 5000) {
  KalmanFixedParams p;
  p.q_mk2_per_s = q;
  p.r_mk2 = r;
  p.dt_ms = dt_ms;
  return p;
}
KalmanParams<double> double_params(const KalmanFixedParams& f) {
  KalmanParams<double> p;
  p.process_noise_k2_per_s = f.q_mk2_per_s * 1e-6;
  p.measurement_noise_k = std::sqrt(double(f.r_mk2)) * 1e-3;
  p.dt_s = f.dt_ms * 1e-3;
  p.gate_sigma = f.gate_sigma;
  p.max_consecutive_rejects = f.max_consecutive_rejects;
  return p;
}
int32_t to_q(double t_c) { return static_cast<int32_t>(std::lround(t_c * kKalmanFixPerK)); }
double from_q(int32_t q) { return q / double(kKalmanFixPerK); }

// configure() derives rho, the steady state and the gates from the integers alone: against the
// closed form in double over the whole configuration range (q, r in 1 ... 1e8, dt 1 ... 600 s).
TEST(KalmanFixed, SetupMatchesTheClosedFormOverTheConfigurationRange) {
  double worst_gain = 0, worst_gate = 0, worst_rho = 0, worst_slow = 0;
  for (uint32_t q : {1u, 7u, 400u, 2500u, 123457u, 100000000u})
    for (uint32_t r : {1u, 3u, 2500u, 99991u, 100000000u})
      for (uint32_t dt : {1000u, 5000u, 60000u, 600000u}) {
        KalmanFixedSetup k;
        ASSERT_TRUE(k.configure(fixed_params(q, r, dt)));
        const double rho = double(q) * dt / (1000.0 * r);
        const double m = (rho + std::sqrt(rho * rho + 4 * rho)) / 2, gain = m / (m + 1);
        const double one = k.one();
        // rho within the range (beyond it saturates: K within 1e-8 of 1) and resolved to 2^-e R:
        // ~1e-4 relative from rho = 2^-15 on (slower filters: coarser, printed).
        const double rho_err = std::fabs(k.rho() / one - rho) / rho, gain_err = std::fabs(k.steady_post() / one - gain) / gain;
        if (rho * one < 1e9 && rho >= std::ldexp(1.0, -15)) {
          worst_rho = std::max(worst_rho, rho_err);
          worst_gain = std::max(worst_gain, gain_err);
        } else if (rho < std::ldexp(1.0, -15)) {
          worst_slow = std::max(worst_slow, gain_err);
        }
        const double gate = 5 * std::sqrt(double(r)) * 256 * std::sqrt(m + 1);
        // An integer of 1/256 mK: beyond its rounding (one unit), relative.
        if (rho * one < 1e9) worst_gate = std::max(worst_gate, std::max(0.0, std::fabs(k.steady_gate() - gate) - 1) / gate);
      }
  std::printf("[kalman] fixed setup vs closed form, rho >= 2^-15: rho %.1e, steady gain %.1e, gate %.1e (relative); "
              "steady gain of the slower filters (rho down to 1e-8): %.1e\n",
              worst_rho, worst_gain, worst_gate, worst_slow);
  EXPECT_LT(worst_rho, 1.2e-4);
  EXPECT_LT(worst_gain, 1e-4);
  EXPECT_LT(worst_gate, 1e-4);
  EXPECT_LT(worst_slow, 0.1);
  KalmanFixedSetup bad;
  KalmanFixedParams never = fixed_params();
  never.max_consecutive_rejects = 0;  // "never re-initialise" needs an unbounded variance: refused
  for (auto p : {fixed_params(0, 2500, 5000), fixed_params(400, 0, 5000), fixed_params(400, 2500, 0), never}) {
    EXPECT_FALSE(bad.configure(p));
    KalmanFixedChannel c;
    EXPECT_EQ(c.update(bad, to_q(20.0)), KalmanOutcome::kInvalid);
  }
}

// The transient after an initialisation is the full filter's recursion in fixed point; the filter
// settles on the precomputed steady gain after a few samples and then differs from the double full
// filter only by its 3.9 uK resolution and the settle tolerance.
TEST(KalmanFixed, SettlesOnTheSteadyGainAndMatchesTheFullFilter) {
  const KalmanFixedParams fp = fixed_params(100, 100);  // q 1e-4 K^2/s, r 10 mK
  KalmanFixedSetup k;
  ASSERT_TRUE(k.configure(fp));
  KalmanFixedChannel f;
  ScalarKalman<double> full(double_params(fp));
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.01);
  double worst = 0;
  int settled_at = -1;
  for (int i = 0; i < 3000; ++i) {
    const int32_t z = to_q(20.0 + 0.002 * i + noise(rng));
    ASSERT_EQ(f.update(k, z), full.update(from_q(z))) << i;
    if (settled_at < 0 && f.settled(k)) settled_at = i;
    // P in units of R against the double filter's.
    if (settled_at < 0) {
      EXPECT_NEAR(f.variance() / double(k.one()), full.variance() / 1e-4, 1e-6) << i;
    }
    worst = std::max(worst, std::fabs(from_q(f.estimate()) - full.estimate()));
  }
  std::printf("[kalman] fixed point vs double full filter: settled after %d samples, worst |dT| %.2e K\n",
              settled_at, worst);
  EXPECT_GE(settled_at, 2);
  EXPECT_LE(settled_at, 6);
  EXPECT_LT(worst, 1e-5);  // a few of the 3.9 uK units
  EXPECT_EQ(f.variance(), k.steady_post());
}

// A rejection in the steady state: P grows by q dt per rejection (as in the full filter), so with
// re-initialisation only after 255 rejections the gate opens by itself after as many rejections as
// in the double filter (177 for a 3 K step at the default noise), and the filter settles again.
TEST(KalmanFixed, RejectionGrowsTheVarianceAndResettles) {
  KalmanFixedParams fp = fixed_params();
  fp.max_consecutive_rejects = 255;
  KalmanFixedSetup k;
  ASSERT_TRUE(k.configure(fp));
  KalmanFixedChannel f;
  ScalarKalman<double> full(double_params(fp));
  for (int i = 0; i < 20; ++i) {
    f.update(k, to_q(30.0));
    full.update(30.0);
  }
  ASSERT_TRUE(f.settled(k));
  int rejects = 0;
  while (f.update(k, to_q(33.0)) == KalmanOutcome::kRejected) {
    EXPECT_FALSE(f.settled(k));
    ASSERT_EQ(full.update(33.0), KalmanOutcome::kRejected);
    ++rejects;
    ASSERT_LT(rejects, 1000);
  }
  EXPECT_EQ(full.update(33.0), KalmanOutcome::kAccepted);  // same number of rejections
  EXPECT_GT(rejects, 3);
  EXPECT_EQ(f.reinit_total(), 0);
  EXPECT_EQ(f.rejected_total(), rejects);
  EXPECT_NEAR(from_q(f.estimate()), full.estimate(), 1e-5);
  for (int i = 0; i < 20; ++i) f.update(k, to_q(33.0));
  EXPECT_TRUE(f.settled(k));
  EXPECT_NEAR(from_q(f.estimate()), 33.0, 1e-5);
  // Re-initialisation after the configured number of rejections in a row (default 3).
  KalmanFixedSetup k3;
  ASSERT_TRUE(k3.configure(fixed_params(100, 100)));
  KalmanFixedChannel g;
  for (int i = 0; i < 20; ++i) g.update(k3, to_q(30.0));
  EXPECT_EQ(g.update(k3, to_q(33.0)), KalmanOutcome::kRejected);
  EXPECT_EQ(g.update(k3, to_q(33.0)), KalmanOutcome::kRejected);
  EXPECT_EQ(g.update(k3, to_q(33.0)), KalmanOutcome::kReinitialized);
  EXPECT_EQ(g.estimate(), to_q(33.0));
  EXPECT_EQ(g.reinit_total(), 1);
  EXPECT_EQ(g.update(k3, to_q(33.001)), KalmanOutcome::kAccepted);
}

// Reset on a sensor fault: the next measurement initialises the filter, the transient runs again,
// and the lifetime counters are kept; predict_only() grows P by q dt.
TEST(KalmanFixed, ResetRestartsTheTransient) {
  KalmanFixedSetup k;
  ASSERT_TRUE(k.configure(fixed_params(100, 100)));
  KalmanFixedChannel f;
  for (int i = 0; i < 20; ++i) f.update(k, to_q(30.0));
  f.update(k, to_q(40.0));  // one reject
  ASSERT_FALSE(f.settled(k));
  for (int i = 0; i < 20; ++i) f.update(k, to_q(30.0));
  ASSERT_TRUE(f.settled(k));
  const uint32_t p = f.variance();
  f.predict_only(k);
  EXPECT_EQ(f.variance(), p + k.rho());
  f.reset();
  EXPECT_FALSE(f.initialized());
  EXPECT_FALSE(f.settled(k));
  EXPECT_EQ(f.update(k, to_q(25.0)), KalmanOutcome::kInitialized);
  EXPECT_EQ(f.estimate(), to_q(25.0));
  EXPECT_EQ(f.variance(), k.one());  // R: the transient starts over
  EXPECT_EQ(f.rejected_total(), 1);
  EXPECT_EQ(f.estimate_mk(), 25000);
}

// estimate_mk(): nearest mK, halves away from zero.
TEST(KalmanFixed, EstimateInMillikelvin) {
  KalmanFixedSetup k;
  ASSERT_TRUE(k.configure(fixed_params()));
  for (double t : {21.4996, 21.5004, -3.2506, -0.0004, 0.0, 849.9, -199.9, 21.0005, -21.0005}) {
    KalmanFixedChannel f;
    f.update(k, to_q(t));
    EXPECT_EQ(f.estimate_mk(), static_cast<int32_t>(std::lround(t * 1000.0))) << t;
    for (int i = 0; i < 30; ++i) f.update(k, to_q(t));
    ASSERT_TRUE(f.settled(k)) << t;
    EXPECT_NEAR(f.estimate_mk(), std::lround(t * 1000.0), 1) << t;
  }
}

// The gain memo (several filters with the same setup sharing one gain computation per sample)
// gives bit-identical results to independent updates, through initialisation, rejects,
// re-initialisation and a reset of one filter (which then has a different variance than the rest).
TEST(KalmanFixed, GainMemoIsBitIdenticalToIndependentFilters) {
  KalmanFixedSetup k;
  ASSERT_TRUE(k.configure(fixed_params()));
  KalmanFixedChannel plain[5], memo_f[5];
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.05);
  int hits = 0;
  for (int n = 0; n < 400; ++n) {
    KalmanFixedGainMemo memo;
    for (int j = 0; j < 5; ++j) {
      double z = 20.0 + 3.0 * j + 0.001 * n + noise(rng);
      if ((n * 7 + j) % 53 == 0) z += 5.0;            // outliers: rejected, P differs afterwards
      if (n >= 200 && n < 204 && j == 2) z += 4.0;    // a real step: re-initialisation
      if (n == 300 && j == 4) {
        plain[j].reset();
        memo_f[j].reset();
      }
      const bool hit = memo.valid && memo.p == memo_f[j].variance() && !memo_f[j].settled(k);
      const KalmanOutcome a = plain[j].update(k, to_q(z));
      const KalmanOutcome b = memo_f[j].update(k, to_q(z), &memo);
      ASSERT_EQ(a, b) << n << " " << j;
      ASSERT_EQ(plain[j].estimate(), memo_f[j].estimate()) << n << " " << j;
      ASSERT_EQ(plain[j].variance(), memo_f[j].variance()) << n << " " << j;
      if (hit) ++hits;
    }
  }
  EXPECT_GT(hits, 5);  // the settle gains are precomputed: the memo serves the recovery after rejections
}

// The firmware's filter (default configuration q = 400 mK^2/s, r = 50 mK, 5 s) against the
// double-precision full filter on the same 24 h of measurements (warm-up ramp, 50 mK noise, 1 %
// outliers, a real step, and a sensor fault with reset every 3 h): the outcome of every sample,
// the worst difference of the estimate and of the reported mK.
TEST(KalmanFixed, McuFilterMatchesTheDoubleFullFilterOver24Hours) {
  for (const KalmanFixedParams fp : {fixed_params(400, 2500), fixed_params(100, 100)}) {
    KalmanFixedSetup k;
    ASSERT_TRUE(k.configure(fp));
    KalmanFixedChannel mcu;
    ScalarKalman<double> ref(double_params(fp));
    const double r = std::sqrt(double(fp.r_mk2)) * 1e-3;
    std::mt19937 rng(21);
    std::normal_distribution<double> noise(0.0, r);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    double worst = 0, worst_settled = 0;
    long worst_mk = 0, settled_samples = 0;
    for (int n = 0; n < 17280; ++n) {
      if (n % 2160 == 1000) {  // sensor fault: both filters reset
        mcu.reset();
        ref.reset();
        continue;
      }
      double t = 20.0 + 40.0 * (1.0 - std::exp(-n / 4000.0));
      if (n >= 12000) t += 4.0;
      double z = t + noise(rng);
      if (uni(rng) < 0.01) z += uni(rng) < 0.5 ? 40 * r : -40 * r;
      const int32_t zq = to_q(z);
      const KalmanOutcome a = mcu.update(k, zq);
      const KalmanOutcome b = ref.update(from_q(zq));
      ASSERT_EQ(a, b) << n;
      const double d = std::fabs(from_q(mcu.estimate()) - ref.estimate());
      worst = std::max(worst, d);
      if (mcu.settled(k)) worst_settled = std::max(worst_settled, d), ++settled_samples;
      worst_mk = std::max(worst_mk, std::labs(mcu.estimate_mk() - std::lround(ref.estimate() * 1000.0)));
    }
    std::printf("[kalman] MCU filter (fixed point) vs double full filter, 24 h, q %u mK^2/s r %u mK^2: worst |dT| "
                "%.2e K (%.2e K while settled, %ld of 17280 samples), worst reported difference %ld mK\n",
                fp.q_mk2_per_s, fp.r_mk2, worst, worst_settled, settled_samples, worst_mk);
    EXPECT_GT(settled_samples, 15000);
    EXPECT_LT(worst, 5e-5);
    EXPECT_LE(worst_mk, 1);
  }
}

}  // namespace
}  // namespace btsm
