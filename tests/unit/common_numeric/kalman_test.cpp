// Scalar Kalman filter: convergence to the closed-form steady state, the innovation gate (reject,
// count, re-initialise on a real step), reset, invalid input, and float (MCU) vs double.
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

// The steady-state option runs the full update through the transient (bit-identical to the full
// filter until P settles), then the precomputed gain in fixed point: the estimates then differ
// only by the settle tolerance and the 1/256 mK resolution of the fixed-point state.
TEST(Kalman, SteadyStateGainMatchesTheFullFilterOnceSettled) {
  KalmanParams<double> ps = params();
  ps.steady_state_gain = true;
  ScalarKalman<double> full(params()), steady(ps);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.01);
  double worst_after_settling = 0;
  int settled_at = -1;
  for (int i = 0; i < 3000; ++i) {
    const double z = 20.0 + 0.002 * i + noise(rng);
    full.update(z);
    steady.update(z);
    if (settled_at < 0) {
      if (steady.settled()) {
        settled_at = i;
      } else {
        ASSERT_EQ(full.estimate(), steady.estimate()) << i;  // the transient is the full filter's
        ASSERT_EQ(full.variance(), steady.variance()) << i;
      }
    }
    if (i > 50) worst_after_settling = std::max(worst_after_settling, std::fabs(full.estimate() - steady.estimate()));
  }
  std::printf("[kalman] steady-state (fixed point) vs full filter (double): settled after %d samples, "
              "then worst |dT| %.2e K\n", settled_at, worst_after_settling);
  EXPECT_GE(settled_at, 2);
  EXPECT_LE(settled_at, 6);
  EXPECT_LT(worst_after_settling, 1e-5);  // a few of the 3.9 uK steps
  EXPECT_EQ(steady.variance(), steady.steady_state_posterior());
}

// A rejection in the steady state hands over to the full update: P grows with every rejection, so
// without re-initialisation the gate opens by itself (as in the full filter), and the filter then
// settles again.
TEST(Kalman, SteadyStateRejectionGrowsTheVarianceAndResettles) {
  KalmanParams<double> p = params();
  p.steady_state_gain = true;
  p.max_consecutive_rejects = 0;
  ScalarKalman<double> f(p), full(params());
  KalmanParams<double> pf = params();
  pf.max_consecutive_rejects = 0;
  full.configure(pf);
  for (int i = 0; i < 20; ++i) {
    f.update(30.0);
    full.update(30.0);
  }
  ASSERT_TRUE(f.settled());
  int rejects = 0;
  while (f.update(33.0) == KalmanOutcome::kRejected) {
    EXPECT_FALSE(f.settled());
    ASSERT_EQ(full.update(33.0), KalmanOutcome::kRejected);
    ++rejects;
    ASSERT_LT(rejects, 1000);
  }
  EXPECT_EQ(full.update(33.0), KalmanOutcome::kAccepted);  // same number of rejections
  EXPECT_GT(rejects, 3);
  EXPECT_EQ(f.reinit_total(), 0);
  EXPECT_EQ(f.rejected_total(), rejects);
  EXPECT_NEAR(f.estimate(), full.estimate(), 1e-5);
  for (int i = 0; i < 20; ++i) f.update(33.0);
  EXPECT_TRUE(f.settled());
  EXPECT_NEAR(f.estimate(), 33.0, 1e-5);
}

// Reset on a sensor fault: the next measurement initialises the filter, the transient (full
// update) runs again, and the lifetime counters are kept.
TEST(Kalman, SteadyStateResetRestartsTheTransient) {
  KalmanParams<double> p = params();
  p.steady_state_gain = true;
  ScalarKalman<double> f(p);
  for (int i = 0; i < 20; ++i) f.update(30.0);
  f.update(40.0);  // one reject
  ASSERT_FALSE(f.settled());
  for (int i = 0; i < 20; ++i) f.update(30.0);
  ASSERT_TRUE(f.settled());
  f.reset();
  EXPECT_FALSE(f.initialized());
  EXPECT_FALSE(f.settled());
  EXPECT_EQ(f.update(25.0), KalmanOutcome::kInitialized);
  EXPECT_DOUBLE_EQ(f.estimate(), 25.0);
  EXPECT_DOUBLE_EQ(f.variance(), 1e-4);  // r^2: the transient starts over
  EXPECT_FALSE(f.settled());
  EXPECT_EQ(f.rejected_total(), 1);
  EXPECT_EQ(f.estimate_mk(), 25000);
}

// estimate_mk(): nearest mK, halves away from zero, in the float state and in the fixed-point one.
TEST(Kalman, EstimateInMillikelvin) {
  KalmanParams<float> p;
  p.process_noise_k2_per_s = 4e-4f;
  p.measurement_noise_k = 0.05f;
  p.steady_state_gain = true;
  for (float t : {21.4996f, 21.5004f, -3.2506f, -0.0004f, 0.0f, 849.9f, -199.9f}) {
    ScalarKalman<float> f(p);
    f.update(t);
    EXPECT_FALSE(f.settled());
    EXPECT_EQ(f.estimate_mk(), static_cast<int32_t>(std::lround(double(t) * 1000.0))) << t;
    for (int i = 0; i < 30; ++i) f.update(t);
    ASSERT_TRUE(f.settled()) << t;
    EXPECT_NEAR(f.estimate_mk(), std::lround(double(t) * 1000.0), 1) << t;
    EXPECT_NEAR(f.estimate(), t, 2e-5) << t;  // float ulp at 200 degC: 1.5e-5
  }
}

// The gain memo (several filters with the same parameters sharing one gain computation per
// sample) gives bit-identical results to independent updates, through initialisation, rejects,
// re-initialisation and a reset of one filter (which then has a different variance than the rest).
TEST(Kalman, GainMemoIsBitIdenticalToIndependentFilters) {
  KalmanParams<float> p;
  p.process_noise_k2_per_s = 4e-4f;
  p.measurement_noise_k = 0.05f;
  p.dt_s = 5.0f;
  ScalarKalman<float> plain[5], memo_f[5];
  for (int j = 0; j < 5; ++j) {
    plain[j].configure(p);
    memo_f[j].configure(p);
  }
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  int hits = 0;
  for (int k = 0; k < 400; ++k) {
    KalmanGainMemo<float> memo;
    for (int j = 0; j < 5; ++j) {
      float z = 20.0f + 3.0f * j + 0.001f * k + noise(rng);
      if ((k * 7 + j) % 53 == 0) z += 5.0f;            // outliers: rejected, P differs afterwards
      if (k >= 200 && k < 204 && j == 2) z += 4.0f;    // a real step: re-initialisation
      if (k == 300 && j == 4) {
        plain[j].reset();
        memo_f[j].reset();
      }
      const float p_before = memo_f[j].variance();
      const bool hit = memo.valid && memo.p == p_before;
      const KalmanOutcome a = plain[j].update(z);
      const KalmanOutcome b = memo_f[j].update(z, &memo);
      ASSERT_EQ(a, b) << k << " " << j;
      ASSERT_EQ(plain[j].estimate(), memo_f[j].estimate()) << k << " " << j;
      ASSERT_EQ(plain[j].variance(), memo_f[j].variance()) << k << " " << j;
      if (hit) ++hits;
    }
  }
  EXPECT_GT(hits, 800);  // about half of the updates reuse another channel's gain here (many outliers)
}

// Run the same data through the float (MCU) and double filters: a 24 h warm-up ramp 20 -> 60 degC
// with 10 mK noise, 1 % outliers of +-2 K and one real 4 K step; print and bound the difference.
template <class Real>
std::vector<Real> run_filter(const std::vector<double>& z, bool steady) {
  KalmanParams<Real> p;
  p.process_noise_k2_per_s = Real(1e-4);
  p.measurement_noise_k = Real(0.01);
  p.dt_s = Real(5);
  p.gate_sigma = Real(5);
  p.max_consecutive_rejects = 3;
  p.steady_state_gain = steady;
  ScalarKalman<Real> f(p);
  std::vector<Real> out;
  out.reserve(z.size());
  for (double v : z) {
    f.update(static_cast<Real>(v));
    out.push_back(f.estimate());
  }
  return out;
}

TEST(KalmanFloat, FloatMatchesDoubleOver24Hours) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::vector<double> z;
  for (int k = 0; k < 17280; ++k) {
    double t = 20.0 + 40.0 * (1.0 - std::exp(-k / 4000.0));
    if (k >= 12000) t += 4.0;  // a real step
    double v = t + noise(rng);
    if (uni(rng) < 0.01) v += uni(rng) < 0.5 ? 2.0 : -2.0;
    z.push_back(v);
  }
  for (bool steady : {false, true}) {
    const auto d = run_filter<double>(z, steady);
    const auto f = run_filter<float>(z, steady);
    double worst = 0;
    for (size_t i = 0; i < z.size(); ++i) worst = std::max(worst, std::fabs(double(f[i]) - d[i]));
    std::printf("[kalman] float vs double, 17280 samples 20->64 degC, %s gain: worst |dT| %.2e K\n",
                steady ? "steady-state" : "full", worst);
    // float ulp at 64 degC is 3.8e-6 K; the filter does not accumulate it (|1 - K| < 1): ~1 ulp.
    EXPECT_LT(worst, 1e-5) << (steady ? "steady" : "full");
  }
}

// The firmware's filter (float, steady-state option, default configuration q = 400 mK^2/s,
// r = 50 mK, 5 s) against the double-precision full filter on the same 24 h of measurements
// (warm-up ramp, 50 mK noise, 1 % outliers, a real step, and a sensor fault with reset every
// 3 h): worst difference of the estimate and of the reported mK.
TEST(KalmanFloat, McuSteadyStateFilterMatchesTheDoubleFullFilter) {
  KalmanParams<float> pf;
  pf.process_noise_k2_per_s = 4e-4f;
  pf.measurement_noise_k = 0.05f;
  pf.dt_s = 5.0f;
  pf.steady_state_gain = true;
  KalmanParams<double> pd;
  pd.process_noise_k2_per_s = 4e-4;
  pd.measurement_noise_k = 0.05;
  pd.dt_s = 5.0;
  ScalarKalman<float> mcu(pf);
  ScalarKalman<double> ref(pd);
  std::mt19937 rng(21);
  std::normal_distribution<double> noise(0.0, 0.05);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  double worst = 0, worst_settled = 0;
  long worst_mk = 0, settled_samples = 0;
  for (int k = 0; k < 17280; ++k) {
    if (k % 2160 == 1000) {  // sensor fault: both filters reset
      mcu.reset();
      ref.reset();
      continue;
    }
    double t = 20.0 + 40.0 * (1.0 - std::exp(-k / 4000.0));
    if (k >= 12000) t += 4.0;
    double z = t + noise(rng);
    if (uni(rng) < 0.01) z += uni(rng) < 0.5 ? 2.0 : -2.0;
    const float zf = static_cast<float>(z);
    const KalmanOutcome a = mcu.update(zf);
    const KalmanOutcome b = ref.update(static_cast<double>(zf));
    ASSERT_EQ(a, b) << k;
    const double d = std::fabs(double(mcu.estimate()) - ref.estimate());
    worst = std::max(worst, d);
    if (mcu.settled()) worst_settled = std::max(worst_settled, d), ++settled_samples;
    worst_mk = std::max(worst_mk, std::labs(mcu.estimate_mk() - std::lround(ref.estimate() * 1000.0)));
  }
  std::printf("[kalman] MCU filter (float, steady-state gain) vs double full filter, 24 h: worst |dT| "
              "%.2e K (%.2e K while settled, %ld of 17280 samples), worst reported difference %ld mK\n",
              worst, worst_settled, settled_samples, worst_mk);
  EXPECT_GT(settled_samples, 15000);
  EXPECT_LT(worst, 5e-5);
  EXPECT_LE(worst_mk, 1);
}

}  // namespace
}  // namespace btsm
