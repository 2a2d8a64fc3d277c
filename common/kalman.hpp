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
// (the positive root of M^2 - Q M - Q R = 0), whatever the initial P, geometrically with a factor
// of about (1 - K)^2 per accepted sample. With steady_state_gain the filter precomputes K, the
// posterior variance P = (1 - K) M and the gate threshold gate_sigma sqrt(M + R) once (configure),
// and once P has settled an update is a subtraction, a comparison and a multiply-add: no division,
// no square (|nu| is compared with the precomputed threshold instead of nu^2 with gate^2 S).
// The transient is NOT approximated: after (re)initialisation, after a rejection (P grows) and
// after predict_only() the full update runs until P is back within kSteadyTolerance (relative)
// of the steady posterior, then the filter switches to the precomputed gain. So the innovation
// gate, the rejection counters, the re-initialisation after max_consecutive_rejects and the reset
// on a sensor fault behave exactly as in the full filter, and the estimate differs from the full
// filter's only by the gain error of that tolerance (tests/unit/common_numeric/kalman_test.cpp
// measures it against the double-precision full filter).
//
// Layout: KalmanSetup holds what configure() derives from the parameters, KalmanChannel the state
// of one filter (estimate, variance, counters); several channels with the same parameters share
// one setup (the firmware: one setup for its five channels, 15 B of state per channel).
// ScalarKalman is one setup plus one channel, for single filters.
//
// Gain memo (MCU): the gain, the posterior variance and the gate threshold depend only on the
// parameters and on P, not on the measurement. Filters with the same parameters whose P is the same
// (every channel of a module initialised at the same sample and without a rejection since, which
// is the usual case) can share them: update(z, &memo) computes them for the first filter and
// reuses them for the others when their P is bit-identical, so the result is exactly update(z).
// On the MCU that is one division per sweep instead of one per channel while the filters settle
// (settled filters with the steady-state gain need no division at all). A memo must only be
// shared by filters with identical parameters and must not outlive a configure(): make it a local
// of the sweep.
//
// Template over Real (float on the MCU, double on the host). Measured float-vs-double difference:
// tests/unit/common_numeric/kalman_test.cpp prints it. C++14, no standard library.
#ifndef BTSM_COMMON_KALMAN_HPP
#define BTSM_COMMON_KALMAN_HPP

#include <math.h>
#include <stdint.h>
#include <string.h>

namespace btsm {

template <class Real>
struct KalmanParams {
  Real process_noise_k2_per_s = Real(1e-4);  // q: random-walk density; 1e-4 K^2/s = 22 mK per 5 s
  Real measurement_noise_k = Real(0.01);     // r: 1-sigma noise of one measurement, K
  Real dt_s = Real(5);                       // sample period, s
  Real gate_sigma = Real(5);                 // reject |innovation| > gate_sigma * sqrt(S)
  uint8_t max_consecutive_rejects = 3;       // then re-initialise on the measurement (0 = never)
  bool steady_state_gain = false;            // precomputed steady-state gain once settled (MCU)
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
// fabs: on the AVR a sign-bit clear, not a float comparison.
inline float kabs(float v) { return fabsf(v); }
inline double kabs(double v) { return fabs(v); }
// |v| < 2048, the range of the fixed-point steady state (float: one integer test of the bits).
inline bool fix_range(float v) {
  uint32_t bits;
  memcpy(&bits, &v, sizeof bits);
  return (bits & 0x7FFFFFFFUL) < 0x45000000UL;  // 0x45000000 = 2048.0f; NaN and inf are above
}
inline bool fix_range(double v) { return fabs(v) < 2048.0; }
// Bit-identical (the memo key): the memo holds a function of P alone, so identical bits give
// identical results whatever the values (no NaN or signed-zero cases to think about); on the AVR an
// integer compare instead of a float comparison call per channel.
inline bool same_bits(float a, float b) {
  uint32_t x, y;
  memcpy(&x, &a, sizeof x);
  memcpy(&y, &b, sizeof y);
  return x == y;
}
inline bool same_bits(double a, double b) {
  uint64_t x, y;
  memcpy(&x, &a, sizeof x);
  memcpy(&y, &b, sizeof y);
  return x == y;
}
// The innovation gate test nu^2 > gate_s. Float: without the multiplication (and the float
// comparison) when |nu| is clearly inside the gate, which is nearly always: with the biased
// exponents en of nu and eg >= 1 of a positive gate_s, |nu| < 2^(en - 126), so nu^2 and its
// rounding are <= 2^(2 en - 252) <= 2^(eg - 127) <= gate_s whenever 2 en <= eg + 125. Otherwise
// (and for inf/NaN, en = 255) the product decides as before, so the outcome never differs.
inline bool outside_gate(float nu, float gate_s) {
  uint32_t n, g;
  memcpy(&n, &nu, sizeof n);
  memcpy(&g, &gate_s, sizeof g);
  // Through the high words: on the AVR a 32-bit shift by 23 is a bit loop, by 16 a register move.
  const uint16_t en = static_cast<uint8_t>(static_cast<uint16_t>(n >> 16) >> 7);  // sign dropped
  const uint16_t eg = static_cast<uint16_t>(static_cast<uint16_t>(g >> 16) >> 7);  // sign: > 255
  if (eg >= 1 && eg <= 255 && 2 * en <= eg + 125) return false;
  return nu * nu > gate_s;
}
inline bool outside_gate(double nu, double gate_s) { return nu * nu > gate_s; }
// round(u * f / 2^32) for a 32-bit fraction f (the high word of the 64-bit product, rounded).
inline uint32_t mul_frac(uint32_t u, uint32_t f) {
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  union {
    uint64_t v;
    uint32_t w[2];  // w[0] low, w[1] high: no 64-bit shift (a bit loop on the AVR)
  } p;
  p.v = static_cast<uint64_t>(u) * f;
  return p.w[1] + (p.w[0] >> 31);
#else
  const uint64_t v = static_cast<uint64_t>(u) * f;
  return static_cast<uint32_t>(v >> 32) + static_cast<uint32_t>((v >> 31) & 1U);
#endif
}
}  // namespace detail_kalman

template <class Real>
struct KalmanGainMemo {
  bool valid = false;  // filled by KalmanSetup::gain_for
  Real p;          // P before the update (the key)
  Real gate_s;     // gate_sigma^2 * S
  Real gain;       // K
  Real p_post;     // P after an accepted update
  bool settles;    // that P is the steady posterior (steady-state gain from the next update on)
};

// What configure() derives from KalmanParams: shared by all channels with these parameters.
template <class Real>
struct KalmanSetup {
  // Relative distance of P from the steady posterior below which the steady-state gain is used.
  // The full filter's gain then differs from K by less than K (1 - K)^2 / 1024, and its estimate
  // from the steady one by less than (1 - K)^2 / (2 - K) / 1024 of an innovation (~1e-5 K at the
  // default noise settings, 5e-5 K for a 5-sigma innovation); with the default K = 0.58 P settles
  // in 4 samples after a (re)initialisation.
  static constexpr float kSteadyTolerance = 1.0f / 1024;
  // Fixed-point units of the settled estimate: 1/256 mK (3.9 uK, finer than a float's ulp at
  // 64 degC), so +-2048 degC fit an int32 with room for the innovation.
  static constexpr float kFixPerK = 256000.0f;

  Real q = Real(0), r2 = Real(0), gate2 = Real(0);
  Real steady_prior = Real(0);  // M
  Real steady_gain = Real(0);   // K = M / (M + R)
  Real steady_post = Real(0);   // (1 - K) M
  Real steady_gate = Real(0);   // gate_sigma sqrt(M + R)
  Real settle_lo = Real(0), settle_hi = Real(0);  // steady_post (1 -+ kSteadyTolerance)
  // The settled filter runs in fixed point (KalmanChannel): K as a 32-bit fraction, the gate in
  // estimate units (1/256 mK).
  uint32_t steady_gain_q32 = 0;
  uint32_t steady_gate_q = 0;
  uint8_t max_consecutive_rejects = 0;
  bool steady_state_gain = false;
  bool valid = false;

  // False (every update kInvalid) on non-positive noise, dt or gate.
  bool configure(const KalmanParams<Real>& p) {
    max_consecutive_rejects = p.max_consecutive_rejects;
    steady_state_gain = p.steady_state_gain;
    q = p.process_noise_k2_per_s * p.dt_s;
    r2 = p.measurement_noise_k * p.measurement_noise_k;
    gate2 = p.gate_sigma * p.gate_sigma;
    valid = q > Real(0) && r2 > Real(0) && p.gate_sigma > Real(0) && p.dt_s > Real(0);
    if (valid) {
      steady_prior = (q + detail_kalman::ksqrt(q * q + Real(4) * q * r2)) / Real(2);
      steady_gain = steady_prior / (steady_prior + r2);
      steady_post = (Real(1) - steady_gain) * steady_prior;
      steady_gate = p.gate_sigma * detail_kalman::ksqrt(steady_prior + r2);
      settle_lo = steady_post - Real(kSteadyTolerance) * steady_post;
      settle_hi = steady_post + Real(kSteadyTolerance) * steady_post;
      steady_gain_q32 = static_cast<uint32_t>(steady_gain * Real(4294967296.0));  // K < 1
      const Real gate_q = steady_gate * Real(kFixPerK);
      steady_gate_q = gate_q < Real(2147483647.0) ? static_cast<uint32_t>(gate_q) : 0x7FFFFFFFUL;
    }
    return valid;
  }

  // Gate, gain and posterior of an update from variance p (what the full update computes).
  void gain_for(Real p, KalmanGainMemo<Real>& m) const {
    const Real prior = p + q;
    const Real s = prior + r2;
    m.valid = true;
    m.p = p;
    m.gate_s = gate2 * s;
    m.gain = prior / s;
    const Real post = (Real(1) - m.gain) * prior;
    // Settled once P is within the tolerance of the steady posterior; P is then set to it
    // exactly (and stays there while settled).
    m.settles = steady_state_gain && post >= settle_lo && post <= settle_hi;
    m.p_post = m.settles ? steady_post : post;
  }
};

// The gains of the first kSize updates after an initialisation (P = r^2) without a rejection
// (MCU): P follows the same sequence in every filter, so configure() computes them once and the
// transient, where every sample ran a float division and five more float operations, looks them
// up like the memo. Bit-identical: gain_for() is the update's own computation. Four: the default K
// settles in four updates (the last entry then belongs to the steady posterior, which a settled
// filter falls back to after a rejection). 72 bytes on the AVR, one table for the channels that
// share a setup; configure() again after every KalmanSetup::configure().
template <class Real>
struct KalmanSettleGains {
  static constexpr uint8_t kSize = 4;
  KalmanGainMemo<Real> gain[kSize];

  void configure(const KalmanSetup<Real>& k) {
    Real p = k.r2;  // P after an initialisation
    for (uint8_t i = 0; i < kSize; ++i) {
      gain[i].valid = false;
      if (!k.valid) continue;
      k.gain_for(p, gain[i]);
      p = gain[i].p_post;
    }
  }
  // The precomputed gains for variance p, or null.
  const KalmanGainMemo<Real>* find(Real p) const {
    for (uint8_t i = 0; i < kSize; ++i)
      if (gain[i].valid && detail_kalman::same_bits(gain[i].p, p)) return &gain[i];
    return 0;
  }
};

// State of one filter; every call passes the setup it was configured with.
template <class Real>
class KalmanChannel {
 public:
  // Forget the estimate (sensor fault, probe replaced, new parameters). Reject counters are kept:
  // they are diagnostics over the module's lifetime.
  void reset() {
    initialized_ = false;
    settled_ = false;
    consecutive_rejects_ = 0;
    t_ = Real(0);
    p_ = Real(0);
  }

  // memo and settle may be null (see above); settle must be configured from k.
  KalmanOutcome update(const KalmanSetup<Real>& k, Real z, KalmanGainMemo<Real>* memo = 0,
                       const KalmanSettleGains<Real>* settle = 0) {
    if (!k.valid || !(z == z)) return KalmanOutcome::kInvalid;
    if (!initialized_) {
      init_on(k, z);
      return KalmanOutcome::kInitialized;
    }
    if (settled_) {
      // Steady state, in fixed point: P stays at the steady posterior while measurements are
      // accepted, so an update is nu = z - T, |nu| <= gate, T += K nu -- integers apart from the
      // conversion of z (on the AVR ~300 cycles instead of ~600 with float arithmetic and the
      // output conversion). Rounding to nearest: no drift of T, whatever K.
      if (detail_kalman::fix_range(z)) {
        const int32_t nu_q = static_cast<int32_t>(z * Real(KalmanSetup<Real>::kFixPerK)) - tq_;
        const uint32_t mag = nu_q < 0 ? 0U - static_cast<uint32_t>(nu_q) : static_cast<uint32_t>(nu_q);
        if (mag <= k.steady_gate_q) {
          consecutive_rejects_ = 0;
          const int32_t step = static_cast<int32_t>(detail_kalman::mul_frac(mag, k.steady_gain_q32));
          tq_ += nu_q < 0 ? -step : step;
          return KalmanOutcome::kAccepted;
        }
      }
      // A rejection (P grows) or a value beyond the fixed range: the full update takes over on the
      // float estimate until P settles again.
      t_ = estimate();
      settled_ = false;
      memo = 0;
    }
    const Real nu = z - t_;
    KalmanGainMemo<Real> local;
    if (memo == 0) memo = &local;
    if (!memo->valid || !detail_kalman::same_bits(memo->p, p_)) {
      // Kept in the memo for the other channels: one comparison for them instead of a search.
      const KalmanGainMemo<Real>* known = settle != 0 ? settle->find(p_) : 0;
      if (known != 0) {
        *memo = *known;
      } else {
        k.gain_for(p_, *memo);  // the full computation
      }
    }
    if (detail_kalman::outside_gate(nu, memo->gate_s)) {
      if (rejected_total_ != 0xFFFFU) ++rejected_total_;  // saturating lifetime counters
      ++consecutive_rejects_;
      if (k.max_consecutive_rejects != 0 && consecutive_rejects_ >= k.max_consecutive_rejects) {
        if (reinit_total_ != 0xFFFFU) ++reinit_total_;
        init_on(k, z);
        return KalmanOutcome::kReinitialized;
      }
      p_ += k.q;  // the prior
      return KalmanOutcome::kRejected;
    }
    consecutive_rejects_ = 0;
    t_ += memo->gain * nu;
    p_ = memo->p_post;
    if (memo->settles) enter_steady();
    return KalmanOutcome::kAccepted;
  }

  // A sample without a measurement (e.g. conversion timed out): uncertainty grows.
  void predict_only(const KalmanSetup<Real>& k) {
    if (!initialized_) return;
    t_ = estimate();
    settled_ = false;
    p_ += k.q;
  }

  bool initialized() const { return initialized_; }
  // True while the steady-state gain is in use (steady_state_gain and P settled).
  bool settled() const { return settled_; }
  Real estimate() const {
    return settled_ ? static_cast<Real>(tq_) * (Real(1) / Real(KalmanSetup<Real>::kFixPerK)) : t_;
  }
  // The estimate in mK (degC * 1000), nearest, halves away from zero; |estimate| < 2^31 mK.
  int32_t estimate_mk() const {
    if (settled_) return tq_ >= 0 ? (tq_ + 128) >> 8 : -((128 - tq_) >> 8);
    // Truncate 2000 T (exactly twice T * 1000 in binary floating point), then halve in integers:
    // one multiplication and conversion.
    const int32_t twice = static_cast<int32_t>(t_ * Real(2000));
    return twice >= 0 ? (twice + 1) >> 1 : -((1 - twice) >> 1);
  }
  Real variance() const { return p_; }
  uint16_t rejected_total() const { return rejected_total_; }
  uint16_t reinit_total() const { return reinit_total_; }
  uint8_t consecutive_rejects() const { return consecutive_rejects_; }

 private:
  void init_on(const KalmanSetup<Real>& k, Real z) {
    initialized_ = true;
    settled_ = false;
    consecutive_rejects_ = 0;
    t_ = z;
    p_ = k.r2;
  }

  // Moves the estimate into the fixed-point steady state (if it is inside its range).
  void enter_steady() {
    if (!detail_kalman::fix_range(t_)) return;
    tq_ = static_cast<int32_t>(t_ * Real(KalmanSetup<Real>::kFixPerK));
    settled_ = true;
  }

  Real t_ = Real(0), p_ = Real(0);
  int32_t tq_ = 0;  // the estimate while settled, 1/256 mK
  uint16_t rejected_total_ = 0;
  uint16_t reinit_total_ = 0;
  uint8_t consecutive_rejects_ = 0;
  bool initialized_ = false;
  bool settled_ = false;
};

// One filter with its own setup.
template <class Real>
class ScalarKalman {
 public:
  ScalarKalman() { configure(KalmanParams<Real>()); }
  explicit ScalarKalman(const KalmanParams<Real>& p) { configure(p); }

  // Returns false (filter unusable, every update kInvalid) on non-positive noise/dt/gate.
  bool configure(const KalmanParams<Real>& p) {
    const bool ok = setup_.configure(p);
    ch_.reset();
    return ok;
  }
  void reset() { ch_.reset(); }
  KalmanOutcome update(Real z) { return ch_.update(setup_, z, 0); }
  KalmanOutcome update(Real z, KalmanGainMemo<Real>* memo) { return ch_.update(setup_, z, memo); }
  void predict_only() { ch_.predict_only(setup_); }

  bool initialized() const { return ch_.initialized(); }
  bool settled() const { return ch_.settled(); }
  Real estimate() const { return ch_.estimate(); }
  int32_t estimate_mk() const { return ch_.estimate_mk(); }
  Real variance() const { return ch_.variance(); }
  Real steady_state_gain() const { return setup_.steady_gain; }
  Real steady_state_prior() const { return setup_.steady_prior; }
  Real steady_state_posterior() const { return setup_.steady_post; }
  uint16_t rejected_total() const { return ch_.rejected_total(); }
  uint16_t reinit_total() const { return ch_.reinit_total(); }
  uint8_t consecutive_rejects() const { return ch_.consecutive_rejects(); }

 private:
  KalmanSetup<Real> setup_;
  KalmanChannel<Real> ch_;
};

}  // namespace btsm

#endif  // BTSM_COMMON_KALMAN_HPP
