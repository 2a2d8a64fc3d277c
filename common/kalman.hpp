// Scalar Kalman filter for one temperature channel, with an innovation gate.
//
// Model (random walk, fixed sample period dt):
//   T_k = T_{k-1} + w_k,   w ~ N(0, q dt)     q: process noise density in K^2/s
//   z_k = T_k + v_k,       v ~ N(0, r^2)      r: measurement noise in K (ADC + reference noise)
// Each sample:  predict  P- = P + q dt
//               innovate nu = z - T, S = P- + r^2
//               gate     |nu| > n_sigma sqrt(S)  -> reject: T kept, P = P- (grows), counters++
//               update   K = P-/S, T += K nu, P = (1 - K) P-
// After `max_consecutive_rejects` rejects in a row the filter re-initialises on the current
// measurement (T = z, P = r^2): a real step (e.g. a probe moved, a genuine fast rise) is followed
// after that many samples instead of being rejected for ever. reset() (on a sensor fault) forgets
// everything; the next accepted measurement initialises the filter.
//
// Steady-state gain option (MCU): for a random walk the prior variance converges to
//   M = (Q + sqrt(Q^2 + 4 Q R)) / 2   (Q = q dt, R = r^2),   K = M / (M + R)
// (the positive root of M^2 - Q M - Q R = 0). With steady_state_gain the filter uses this
// precomputed K and S = M + R every sample: no division per sample, and identical behaviour to the
// full filter once it has settled (a few 1/K samples).
//
// Gain memo (MCU): the gain, the posterior variance and the gate threshold depend only on the
// parameters and on P, not on the measurement. Filters with the same parameters whose P is the same
// (every channel of a module initialised at the same sample and without a rejection since, which
// is the usual case, settled or not) can share them: update(z, &memo) computes them for the first
// filter and reuses them for the others when their P is bit-identical, so the result is exactly
// update(z). On the MCU that is one division per sweep instead of one per channel (~1000 cycles
// less per reused channel). A memo must only be shared by filters with identical parameters and
// must not outlive a configure(): make it a local of the sweep.
//
// Template over Real (float on the MCU, double on the host). Measured float-vs-double difference:
// tests/unit/common_numeric/kalman_test.cpp prints it. C++14, no standard library.
#ifndef BTSM_COMMON_KALMAN_HPP
#define BTSM_COMMON_KALMAN_HPP

#include <math.h>
#include <stdint.h>

namespace btsm {

template <class Real>
struct KalmanParams {
  Real process_noise_k2_per_s = Real(1e-4);  // q: random-walk density; 1e-4 K^2/s = 22 mK per 5 s
  Real measurement_noise_k = Real(0.01);     // r: 1-sigma noise of one measurement, K
  Real dt_s = Real(5);                       // sample period, s
  Real gate_sigma = Real(5);                 // reject |innovation| > gate_sigma * sqrt(S)
  uint8_t max_consecutive_rejects = 3;       // then re-initialise on the measurement (0 = never)
  bool steady_state_gain = false;            // use the precomputed steady-state gain
};

enum class KalmanOutcome : uint8_t {
  kInitialized = 0,    // first measurement after construction/reset: T = z
  kAccepted = 1,       // measurement used
  kRejected = 2,       // outside the gate: estimate unchanged
  kReinitialized = 3,  // too many rejects in a row: T = z (a real step is being followed)
  kInvalid = 4,        // NaN measurement or unusable parameters: nothing changed
};

namespace detail_kalman {
inline float ksqrt(float v) { return sqrtf(v); }
inline double ksqrt(double v) { return sqrt(v); }
}  // namespace detail_kalman

template <class Real>
struct KalmanGainMemo {
  bool valid = false;
  Real p;          // P before the update (the key)
  Real gate_s;     // gate_sigma^2 * S
  Real gain;       // K
  Real p_post;     // P after an accepted update
};

template <class Real>
class ScalarKalman {
 public:
  ScalarKalman() { configure(KalmanParams<Real>()); }
  explicit ScalarKalman(const KalmanParams<Real>& p) { configure(p); }

  // Returns false (filter unusable, every update kInvalid) on non-positive noise/dt/gate.
  bool configure(const KalmanParams<Real>& p) {
    max_consecutive_rejects_ = p.max_consecutive_rejects;
    steady_state_gain_mode_ = p.steady_state_gain;
    q_ = p.process_noise_k2_per_s * p.dt_s;
    r2_ = p.measurement_noise_k * p.measurement_noise_k;
    valid_ = q_ > Real(0) && r2_ > Real(0) && p.gate_sigma > Real(0) && p.dt_s > Real(0);
    if (valid_) {
      steady_prior_ = (q_ + detail_kalman::ksqrt(q_ * q_ + Real(4) * q_ * r2_)) / Real(2);
      steady_gain_ = steady_prior_ / (steady_prior_ + r2_);
    }
    gate2_ = p.gate_sigma * p.gate_sigma;
    reset();
    return valid_;
  }

  // Forget the estimate (sensor fault, probe replaced). Reject counters are kept: they are
  // diagnostics over the module's lifetime.
  void reset() {
    initialized_ = false;
    consecutive_rejects_ = 0;
    t_ = Real(0);
    p_ = Real(0);
  }

  KalmanOutcome update(Real z) { return update(z, 0); }

  // With a memo shared by filters of identical parameters (see above); memo may be null.
  KalmanOutcome update(Real z, KalmanGainMemo<Real>* memo) {
    if (!valid_ || !(z == z)) return KalmanOutcome::kInvalid;
    if (!initialized_) {
      init_on(z);
      return KalmanOutcome::kInitialized;
    }
    const Real nu = z - t_;
    if (memo != 0 && memo->valid && memo->p == p_) {
      if (!(nu * nu > memo->gate_s)) {
        consecutive_rejects_ = 0;
        t_ += memo->gain * nu;
        p_ = memo->p_post;
        return KalmanOutcome::kAccepted;
      }
      memo = 0;  // a rejection: the full path below handles it (and leaves the memo alone)
    }
    const Real p_before = p_;
    const Real prior = steady_state_gain_mode_ ? steady_prior_ : p_ + q_;
    const Real s = prior + r2_;
    const Real gate_s = gate2_ * s;
    if (nu * nu > gate_s) {
      if (rejected_total_ != 0xFFFFU) ++rejected_total_;  // saturating lifetime counters
      ++consecutive_rejects_;
      if (max_consecutive_rejects_ != 0 && consecutive_rejects_ >= max_consecutive_rejects_) {
        if (reinit_total_ != 0xFFFFU) ++reinit_total_;
        init_on(z);
        return KalmanOutcome::kReinitialized;
      }
      p_ = prior;
      return KalmanOutcome::kRejected;
    }
    consecutive_rejects_ = 0;
    const Real k = steady_state_gain_mode_ ? steady_gain_ : prior / s;
    t_ += k * nu;
    p_ = steady_state_gain_mode_ ? steady_prior_ * (Real(1) - steady_gain_) : (Real(1) - k) * prior;
    if (memo != 0) {
      memo->valid = true;
      memo->p = p_before;
      memo->gate_s = gate_s;
      memo->gain = k;
      memo->p_post = p_;
    }
    return KalmanOutcome::kAccepted;
  }

  // A sample without a measurement (e.g. conversion timed out): uncertainty grows.
  void predict_only() {
    if (initialized_ && !steady_state_gain_mode_) p_ += q_;
  }

  bool initialized() const { return initialized_; }
  Real estimate() const { return t_; }
  Real variance() const { return p_; }
  Real steady_state_gain() const { return steady_gain_; }
  Real steady_state_prior() const { return steady_prior_; }
  uint16_t rejected_total() const { return rejected_total_; }
  uint16_t reinit_total() const { return reinit_total_; }
  uint8_t consecutive_rejects() const { return consecutive_rejects_; }

 private:
  void init_on(Real z) {
    initialized_ = true;
    consecutive_rejects_ = 0;
    t_ = z;
    p_ = steady_state_gain_mode_ ? steady_prior_ * (Real(1) - steady_gain_) : r2_;
  }

  // Only what update() needs is kept (RAM: 7 Real + 6 bytes per channel, 34 B in float).
  Real q_ = Real(0), r2_ = Real(0), gate2_ = Real(0);
  Real steady_prior_ = Real(0), steady_gain_ = Real(0);
  Real t_ = Real(0), p_ = Real(0);
  bool valid_ = false;
  bool steady_state_gain_mode_ = false;
  uint8_t max_consecutive_rejects_ = 0;
  bool initialized_ = false;
  uint8_t consecutive_rejects_ = 0;
  uint16_t rejected_total_ = 0;
  uint16_t reinit_total_ = 0;
};

}  // namespace btsm

#endif  // BTSM_COMMON_KALMAN_HPP
