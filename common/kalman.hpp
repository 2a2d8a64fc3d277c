// Scalar Kalman filter for one temperature channel, with an innovation gate: the reference filter
// (ScalarKalman<double>, host and tests) and the MCU's fixed-point filter (KalmanFixedSetup +
// KalmanFixedChannel, no float at all).
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
// The fixed-point filter (MCU) runs the same recursion on integers:
//   - temperatures in 1/256 mK (kFixPerK units per kelvin; int32 holds +-8388 K), the unit the
//     RTD inverse delivers (common/rtd.hpp pt1000_temperature_q), so a measurement needs no
//     conversion;
//   - the variance normalised by R = r^2 and scaled by 2^e ("P units": p = P / R 2^e), with e
//     chosen per configuration so that the largest prior the filter can reach (after
//     max_consecutive_rejects rejections) still fits 31 bits: in units of R the recursion is
//     prior = p + rho (rho = q dt / R), K = prior / (prior + 1), posterior = K -- one 32-bit
//     fraction per update (fx::frac_q32), no division instruction;
//   - the gate as |nu| <= gate_sigma r sqrt(S / R), with an integer square root.
// Its steady state (for a random walk the prior converges to M = R (rho + sqrt(rho^2 + 4 rho)) / 2,
// K = M / (M + R), whatever the initial P, geometrically with a factor of about (1 - K)^2 per
// accepted sample) is computed once by configure(): once P is within kSettleTolerance
// (relative) of the steady posterior it is set to it exactly and an update is a subtraction, a
// comparison and one 32x32 product. The first kSettleSteps gains after an initialisation are
// precomputed too (every filter initialised at the same sample follows the same P sequence), and
// filters whose P is equal share one gain computation per sample through a KalmanFixedGainMemo.
// So the transient is the full filter's, not an approximation, and the gate, the counters, the
// re-initialisation and the reset behave as in the reference filter.
// Measured against ScalarKalman<double> (the full filter): tests/unit/common_numeric/kalman_test.cpp.
//
// C++14, no standard library.
#ifndef BTSM_COMMON_KALMAN_HPP
#define BTSM_COMMON_KALMAN_HPP

#include <math.h>
#include <stdint.h>

#include "fixed_point.hpp"

namespace btsm {

template <class Real>
struct KalmanParams {
  Real process_noise_k2_per_s = Real(1e-4);  // q: random-walk density; 1e-4 K^2/s = 22 mK per 5 s
  Real measurement_noise_k = Real(0.01);     // r: 1-sigma noise of one measurement, K
  Real dt_s = Real(5);                       // sample period, s
  Real gate_sigma = Real(5);                 // reject |innovation| > gate_sigma * sqrt(S)
  uint8_t max_consecutive_rejects = 3;       // then re-initialise on the measurement (0 = never)
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

// ---- The reference filter (floating point) ---------------------------------------------------

template <class Real>
class ScalarKalman {
 public:
  ScalarKalman() { configure(KalmanParams<Real>()); }
  explicit ScalarKalman(const KalmanParams<Real>& p) { configure(p); }

  // Returns false (filter unusable, every update kInvalid) on non-positive noise/dt/gate.
  bool configure(const KalmanParams<Real>& p) {
    max_consecutive_rejects_ = p.max_consecutive_rejects;
    q_ = p.process_noise_k2_per_s * p.dt_s;
    r2_ = p.measurement_noise_k * p.measurement_noise_k;
    gate2_ = p.gate_sigma * p.gate_sigma;
    valid_ = q_ > Real(0) && r2_ > Real(0) && p.gate_sigma > Real(0) && p.dt_s > Real(0);
    if (valid_) steady_prior_ = (q_ + detail_kalman::ksqrt(q_ * q_ + Real(4) * q_ * r2_)) / Real(2);
    reset();
    return valid_;
  }

  // Forget the estimate (sensor fault, probe replaced, new parameters). Reject counters are kept:
  // they are diagnostics over the module's lifetime.
  void reset() {
    initialized_ = false;
    consecutive_rejects_ = 0;
    t_ = Real(0);
    p_ = Real(0);
  }

  KalmanOutcome update(Real z) {
    if (!valid_ || !(z == z)) return KalmanOutcome::kInvalid;
    if (!initialized_) {
      init_on(z);
      return KalmanOutcome::kInitialized;
    }
    const Real prior = p_ + q_;
    const Real s = prior + r2_;
    const Real nu = z - t_;
    if (nu * nu > gate2_ * s) {
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
    const Real gain = prior / s;
    t_ += gain * nu;
    p_ = (Real(1) - gain) * prior;
    return KalmanOutcome::kAccepted;
  }

  // A sample without a measurement (e.g. conversion timed out): uncertainty grows.
  void predict_only() {
    if (initialized_) p_ += q_;
  }

  bool initialized() const { return initialized_; }
  Real estimate() const { return t_; }
  Real variance() const { return p_; }
  // The closed-form steady state: prior M, gain K = M / (M + R), posterior (1 - K) M.
  Real steady_state_prior() const { return steady_prior_; }
  Real steady_state_gain() const { return steady_prior_ / (steady_prior_ + r2_); }
  Real steady_state_posterior() const { return (Real(1) - steady_state_gain()) * steady_prior_; }
  uint16_t rejected_total() const { return rejected_total_; }
  uint16_t reinit_total() const { return reinit_total_; }
  uint8_t consecutive_rejects() const { return consecutive_rejects_; }

 private:
  void init_on(Real z) {
    initialized_ = true;
    consecutive_rejects_ = 0;
    t_ = z;
    p_ = r2_;
  }

  Real q_ = Real(0), r2_ = Real(0), gate2_ = Real(0), steady_prior_ = Real(0);
  Real t_ = Real(0), p_ = Real(0);
  uint16_t rejected_total_ = 0;
  uint16_t reinit_total_ = 0;
  uint8_t consecutive_rejects_ = 0;
  uint8_t max_consecutive_rejects_ = 0;
  bool initialized_ = false;
  bool valid_ = false;
};

// ---- The MCU's filter (fixed point) ------------------------------------------------------------

// The configuration as the module stores it (FirmwareConfig: integers, no float).
struct KalmanFixedParams {
  uint32_t q_mk2_per_s = 400;           // q: process noise density, (mK)^2/s
  uint32_t r_mk2 = 2500;                // r^2: measurement noise variance, (mK)^2
  uint32_t dt_ms = 5000;                // sample period, ms
  uint8_t gate_sigma = 5;               // reject |innovation| > gate_sigma sqrt(S)
  uint8_t max_consecutive_rejects = 3;  // then re-initialise on the measurement, 1..255 (the
                                        // variance's range is sized for it; 0 is refused)
};

const int32_t kKalmanFixPerK = 256000;  // estimate units (1/256 mK) per kelvin

// Gate, gain and posterior of an update from variance p (P units): a function of p alone, so
// filters with the same setup and the same p share it.
// Only `valid` is initialised (the rest is written before it is read): a setup holds four of
// these, and every initialised member costs start-up code on the AVR.
struct KalmanFixedGainMemo {
  KalmanFixedGainMemo() : valid(false) {}
  bool valid;
  uint32_t p;        // P before the update (the key), P units
  uint32_t gain;     // K as a 32-bit fraction
  uint32_t p_post;   // P after an accepted update, P units
  uint32_t gate;     // |nu| threshold, 1/256 mK
  bool settles;      // p_post is the steady posterior
};

class KalmanFixedSetup {
 public:
  // Unusable until configure() (which sets every member): only `valid_` is initialised, so that a
  // static setup costs no start-up code on the AVR.
  KalmanFixedSetup() : valid_(false) {}

  static const uint8_t kSettleSteps = 4;          // precomputed gains after an initialisation
  static const uint16_t kSettleTolerance = 1024;  // settled within 1/1024 of the steady posterior

  // False (every update kInvalid) on zero noise, period, gate or max_consecutive_rejects.
  bool configure(const KalmanFixedParams& p) {
    max_consecutive_rejects_ = p.max_consecutive_rejects;
    valid_ = p.q_mk2_per_s != 0 && p.r_mk2 != 0 && p.dt_ms != 0 && p.gate_sigma != 0 && p.max_consecutive_rejects != 0;
    for (uint8_t i = 0; i < kSettleSteps; ++i) settle_[i].valid = false;
    if (!valid_) return false;
    // rho = q dt / R = f 2^x with f normalised: q / R as a 32-bit fraction of the normalised
    // operands (frac_q32), then times dt and 1/1000 through two products -- 32-bit integers only,
    // ~2^-29 relative.
    uint8_t a, b, c;
    const uint32_t qn = fx::normalize(p.q_mk2_per_s, &a), rn = fx::normalize(p.r_mk2, &b),
                   dn = fx::normalize(p.dt_ms, &c);
    uint32_t f;
    int16_t x;
    if (qn < rn) {
      f = fx::frac_q32(qn, rn);
      x = static_cast<int16_t>(b - a - 32);
    } else {
      f = fx::frac_q32(qn >> 1, rn);
      x = static_cast<int16_t>(b - a - 31);
    }
    f = fx::mul_hi_round(f, dn);          // x dt_ms
    f = fx::mul_hi_round(f, 2199023256UL);  // x 2^41 / 1000 (ms -> s)
    x = static_cast<int16_t>(x + 32 - c + 32 - 41);
    // P units 2^e: the largest even e <= 28 (even: the gate's square root of s / 2^e needs no
    // half-bit; <= 28: rho + 4 R fits 32 bits for the steady state) for which the largest prior
    // the filter can reach, R + max_consecutive_rejects rho (then it re-initialises), plus R
    // stays below 2^31. A rho beyond that range at e = 0 (q dt > 2^28 R: K within 1e-8 of 1, no
    // filtering) saturates. rho itself is then resolved to 2^-e R: ~1e-4 relative for
    // rho >= 2^-15 (K >= 0.5 %); slower filters get a coarser rho (K 6 % off at rho = 1e-8, the
    // slowest the configuration ranges allow: q 1 mK^2/s, r 1e8 mK^2, 1 s).
    const uint32_t steps = (p.max_consecutive_rejects > 3 ? p.max_consecutive_rejects : 3) + 1U;
    for (e_ = 28;; e_ = static_cast<uint8_t>(e_ - 2)) {
      const uint32_t limit = (0x7FFFFFFFUL - (2UL << e_)) / steps;
      rho_ = fx::shift_round_sat(f, static_cast<int8_t>(x + e_ > 32 ? 32 : x + e_ < -32 ? -32 : x + e_));
      if (rho_ <= limit) break;
      if (e_ == 0) {
        rho_ = limit;
        break;
      }
    }
    one_ = 1UL << e_;
    // gate_sigma r in estimate units (gate_sigma sqrt(r^2) x 256), kept normalised: gu 2^-gx.
    // From r^2 normalised (rn = r^2 4^m) so that its root keeps 23 bits: sqrt(rn 2^14) =
    // r 2^(m + 7) in [2^22, 2^23), times gate_sigma < 2^31, so gate_sigma r 256 = that 2^(1 - m).
    uint8_t m2;
    const uint32_t r2n = fx::normalize_even(p.r_mk2, &m2);
    gate_mant_ = fx::normalize(p.gate_sigma * fx::sqrt_mul(r2n, 16384UL), &gate_shift_);
    gate_shift_ = static_cast<uint8_t>(gate_shift_ + (m2 >> 1) - 1U);
    // Steady prior M = (rho + sqrt(rho^2 + 4 rho)) / 2 in P units, rounded.
    const uint32_t m = rho_ == 0 ? 0 : (rho_ + fx::sqrt_mul(rho_, rho_ + 4U * one_) + 1U) >> 1;
    steady_gain_ = fx::frac_q32(m, m + one_);
    steady_post_ = fx::mul_hi_round(one_, steady_gain_);
    steady_gate_ = gate_for(m + one_);
    settle_lo_ = steady_post_ - steady_post_ / kSettleTolerance;
    settle_hi_ = steady_post_ + steady_post_ / kSettleTolerance;
    uint32_t pv = one_;  // P after an initialisation: R
    for (uint8_t i = 0; i < kSettleSteps; ++i) {
      gain_for(pv, settle_[i]);
      pv = settle_[i].p_post;
    }
    return true;
  }

  bool valid() const { return valid_; }
  uint8_t max_consecutive_rejects() const { return max_consecutive_rejects_; }
  uint32_t one() const { return one_; }           // R in P units (2^e)
  uint32_t rho() const { return rho_; }           // q dt in P units
  uint32_t steady_gain() const { return steady_gain_; }
  uint32_t steady_post() const { return steady_post_; }
  uint32_t steady_gate() const { return steady_gate_; }

  // The update's gate, gain and posterior for variance p (what the full update computes).
  void gain_for(uint32_t p, KalmanFixedGainMemo& m) const {
    const uint32_t prior = add_sat(p, rho_);
    const uint32_t s = add_sat(prior, one_);
    m.valid = true;
    m.p = p;
    m.gain = fx::frac_q32(prior, s);
    const uint32_t post = fx::mul_hi_round(one_, m.gain);
    m.settles = post >= settle_lo_ && post <= settle_hi_;
    m.p_post = m.settles ? steady_post_ : post;
    m.gate = gate_for(s);
  }

  // The precomputed gains of the first updates after an initialisation for variance p, or null.
  const KalmanFixedGainMemo* settle_gain(uint32_t p) const {
    for (uint8_t i = 0; i < kSettleSteps; ++i)
      if (settle_[i].valid && settle_[i].p == p) return &settle_[i];
    return 0;
  }

  static uint32_t add_sat(uint32_t a, uint32_t b) { return a + b < a ? 0xFFFFFFFFUL : a + b; }

 private:
  // gate_sigma r sqrt(s / R) in estimate units for s in P units: with the 16-bit root of s
  // normalised (sqrt(s) = sq 2^-(16 + j/2), sq = isqrt 2^16) and gate_sigma r = gu 2^-gx, it is
  // (gu sq / 2^32) 2^(16 - gx - j/2 - e/2), to 2^-15 relative.
  uint32_t gate_for(uint32_t s) const {
    uint8_t j;
    const uint32_t sq = static_cast<uint32_t>(fx::isqrt32(fx::normalize_even(s, &j))) << 16;
    const int8_t sh = static_cast<int8_t>(16 - gate_shift_ - (j >> 1) - (e_ >> 1));
    const uint32_t g = fx::shift_round_sat(fx::mul_hi_round(gate_mant_, sq), sh);
    return g > 0x7FFFFFFFUL ? 0x7FFFFFFFUL : g;
  }

  KalmanFixedGainMemo settle_[kSettleSteps];
  uint32_t one_, rho_;         // R and q dt in P units (R = 2^e_)
  uint32_t gate_mant_;         // gate_sigma r (estimate units) = gate_mant_ 2^-gate_shift_
  uint8_t gate_shift_;
  uint32_t steady_gain_, steady_post_, steady_gate_;
  uint32_t settle_lo_, settle_hi_;
  uint8_t e_;
  uint8_t max_consecutive_rejects_;
  bool valid_;
};

// State of one filter; every call passes the setup it was configured with.
class KalmanFixedChannel {
 public:
  // Forget the estimate (sensor fault, probe replaced, new parameters). Reject counters are kept.
  void reset() {
    initialized_ = false;
    consecutive_rejects_ = 0;
    t_ = 0;
    p_ = 0;
  }

  // z in 1/256 mK (|z| < 2^30). memo may be null; share one among the filters of one setup for one
  // sample (make it a local of the sweep). Out of line: inlined into the caller's channel loop, its
  // state's address was recomputed for every member access on the AVR.
  __attribute__((noinline)) KalmanOutcome update(const KalmanFixedSetup& k, int32_t z, KalmanFixedGainMemo* memo = 0) {
    if (!k.valid()) return KalmanOutcome::kInvalid;
    if (!initialized_) {
      init_on(k, z);
      return KalmanOutcome::kInitialized;
    }
    const int32_t nu = z - t_;
    const uint32_t mag = nu < 0 ? 0U - static_cast<uint32_t>(nu) : static_cast<uint32_t>(nu);
    uint32_t gain, gate;
    uint32_t p_post = p_;
    const bool settled = p_ == k.steady_post();
    if (settled) {
      // Steady state: P stays at the steady posterior while measurements are accepted.
      gain = k.steady_gain();
      gate = k.steady_gate();
    } else {
      KalmanFixedGainMemo local;
      if (memo == 0) memo = &local;
      if (!memo->valid || memo->p != p_) {
        const KalmanFixedGainMemo* known = k.settle_gain(p_);
        if (known != 0) {
          *memo = *known;
        } else {
          k.gain_for(p_, *memo);  // the full computation
        }
      }
      gain = memo->gain;
      gate = memo->gate;
      p_post = memo->p_post;
    }
    if (mag > gate) {
      if (rejected_total_ != 0xFFFFU) ++rejected_total_;  // saturating lifetime counters
      if (consecutive_rejects_ != 0xFFU) ++consecutive_rejects_;
      if (k.max_consecutive_rejects() != 0 && consecutive_rejects_ >= k.max_consecutive_rejects()) {
        if (reinit_total_ != 0xFFFFU) ++reinit_total_;
        init_on(k, z);
        return KalmanOutcome::kReinitialized;
      }
      p_ = KalmanFixedSetup::add_sat(p_, k.rho());  // the prior
      return KalmanOutcome::kRejected;
    }
    consecutive_rejects_ = 0;
    // T += K nu, rounded to nearest (no drift whatever K).
    const int32_t step = static_cast<int32_t>(fx::mul_hi_round(mag, gain));
    t_ += nu < 0 ? -step : step;
    p_ = p_post;
    return KalmanOutcome::kAccepted;
  }

  // A sample without a measurement (e.g. conversion timed out): uncertainty grows.
  void predict_only(const KalmanFixedSetup& k) {
    if (initialized_) p_ = KalmanFixedSetup::add_sat(p_, k.rho());
  }

  bool initialized() const { return initialized_; }
  // True while the steady-state gain is in use.
  bool settled(const KalmanFixedSetup& k) const { return initialized_ && p_ == k.steady_post(); }
  int32_t estimate() const { return t_; }  // 1/256 mK
  // The estimate in mK (degC * 1000), nearest, halves away from zero.
  int32_t estimate_mk() const { return t_ >= 0 ? (t_ + 128) >> 8 : -((128 - t_) >> 8); }
  uint32_t variance() const { return p_; }  // P units (KalmanFixedSetup::one() = R)
  uint16_t rejected_total() const { return rejected_total_; }
  uint16_t reinit_total() const { return reinit_total_; }
  uint8_t consecutive_rejects() const { return consecutive_rejects_; }

 private:
  void init_on(const KalmanFixedSetup& k, int32_t z) {
    initialized_ = true;
    consecutive_rejects_ = 0;
    t_ = z;
    p_ = k.one();
  }

  int32_t t_ = 0;   // estimate, 1/256 mK
  uint32_t p_ = 0;  // variance, P units
  uint16_t rejected_total_ = 0;
  uint16_t reinit_total_ = 0;
  uint8_t consecutive_rejects_ = 0;
  bool initialized_ = false;
};

}  // namespace btsm

#endif  // BTSM_COMMON_KALMAN_HPP
