// Per-channel thermal diagnosis: NORMAL / WARN / ALARM / SENSOR_FAULT with persistence,
// hysteresis, a latched ALARM, and an overall state; and the evidence of a persistent residual
// the model checks rest on.
//
// Evidence (ResidualEvidence below): the residual r = measured - predicted is accumulated per
// model step as two one-sided CUSUM statistics (Page 1954), in mK x samples,
//   high' = min(cap, max(0, high + r - drift)),   low' = min(cap, max(0, low - r - low_drift)).
// A residual within +-drift drains them; a persistent excess piles up at (r - drift) per sample,
// so a small lasting excess heat is flagged after a time that shrinks as it grows, and a short
// transient of the model (a stop, a speed change) is forgiven. `high` grows on heat the model
// does not expect (a bearing fault), `low` on a probe colder than its model (a probe losing
// contact). cap = 2 x the ALARM threshold keeps the time to drain after a fault bounded.
//
// Inputs per channel and sample: measured temperature (mK), the channel's evidence (kDiagNoValue
// when there is no prediction), rate of rise (mK/min or kDiagNoValue; RiseRate below computes it),
// and the channel's fault flag (ADC error, rail, RTD out of range ...).
//
// Conditions evaluated on each sample:
//   alarm_cond  high > alarm_evidence  OR  measured > abs_limit  OR  rise > max_rise (if > 0)
//   warn_cond   high > warn_evidence  OR  low > low_warn_evidence (if > 0)  (or alarm_cond)
//   alarm_clear high <= alarm_evidence*(1-h) AND measured <= abs_limit - abs_hysteresis AND
//               rise <= max_rise*(1-h)                           (h = hysteresis_permille / 1000)
//   normal      alarm_clear AND high <= warn_evidence*(1-h) AND low <= low_warn_evidence*(1-h)
// Between the entry threshold and the (lower) exit threshold the state does not change: that is
// the hysteresis band that stops a value hovering at a threshold from toggling the state.
//
//                         warn_cond x N                    alarm_cond x N
//            +--------+ ------------------> +------+ --------------------------+
//            |        |                     |      |                           v
//            | NORMAL | <------------------ | WARN |                    +-------------+
//            |        |  normal x Mw        |      | <----------------  |    ALARM    |
//            +--------+                     +------+  ack & alarm_clear |  (latched)  |
//              ^  ^  |            alarm_cond x N                        |             |
//              |  |  +----------------------------------------------->  |             |
//              |  +---------------------------------------------------- |             |
//              |        normal x Ma (auto-clear), or ack & normal       +-------------+
//              |                                                          |      ^
//              |  fault_clear x Mf, no latched alarm       fault (any)    |      | fault_clear x Mf,
//              |                                                          v      | alarm was latched
//            +------------------------------------------------------------------------+
//            |                      SENSOR_FAULT  (entered at once from any state)     |
//            +------------------------------------------------------------------------+
//   N  = enter_samples        consecutive samples to ENTER warn or alarm (persistence)
//   Mw = warn_clear_samples   consecutive "normal" samples to leave WARN
//   Ma = alarm_clear_samples  consecutive "normal" samples to auto-clear an ALARM; 0 = never
//        (a latched alarm in the strict sense: only an acknowledgement ends it)
//   Mf = fault_clear_samples  consecutive samples without the fault flag to leave SENSOR_FAULT
//   ack = acknowledge(): an ALARM whose condition is still present stays latched but is marked
//         acknowledged and then leaves as soon as alarm_clear holds (to WARN if |residual| is still
//         above its warn exit threshold, else NORMAL); an acknowledged alarm does not re-latch until
//         alarm_cond persists N samples again.
// A latched ALARM survives a sensor fault: when the fault clears the channel returns to ALARM.
//
// Overall state = the most severe channel state, ranked ALARM > SENSOR_FAULT > WARN > NORMAL: a
// real over-temperature on one probe must never be masked by a broken probe elsewhere.
//
// Integer-only (mK), no division per sample except the hysteresis scaling; C++14, no std library.
#ifndef BTSM_COMMON_DIAGNOSIS_HPP
#define BTSM_COMMON_DIAGNOSIS_HPP

#include <stdint.h>

#include "fixed_point.hpp"

namespace btsm {

// Wire values (2 bits).
enum class DiagState : uint8_t { kNormal = 0, kWarn = 1, kAlarm = 2, kSensorFault = 3 };

// Why the channel is (or is heading) where it is: bit set = condition true on the last sample.
enum DiagReason : uint8_t {
  kReasonResidualWarn = 0x01,
  kReasonResidualAlarm = 0x02,
  kReasonAbsLimit = 0x04,
  kReasonRise = 0x08,
  kReasonFault = 0x10,
  kReasonAcknowledged = 0x20,  // ALARM acknowledged, waiting for the condition to clear
  kReasonNoPrediction = 0x40,  // residual checks skipped (no model / no ambient)
};

const int32_t kDiagNoValue = -8388608L;  // same code as the wire's kMissing
const int32_t kDiagMaxRate = 8388607L;   // |rate of rise| clamp, mK/min (the wire's i24)

inline const char* diag_state_name(DiagState s) {
  switch (s) {
    case DiagState::kNormal: return "NORMAL";
    case DiagState::kWarn: return "WARN";
    case DiagState::kAlarm: return "ALARM";
    case DiagState::kSensorFault: return "SENSOR_FAULT";
  }
  return "?";
}

// Rank for the overall state: ALARM > SENSOR_FAULT > WARN > NORMAL.
inline uint8_t diag_severity(DiagState s) {
  switch (s) {
    case DiagState::kNormal: return 0;
    case DiagState::kWarn: return 1;
    case DiagState::kSensorFault: return 2;
    case DiagState::kAlarm: return 3;
  }
  return 0;
}

inline DiagState diag_worst(DiagState a, DiagState b) { return diag_severity(b) > diag_severity(a) ? b : a; }

struct DiagChannelLimits {
  int32_t warn_evidence = 12000;        // upper evidence entry threshold for WARN, mK x samples
  int32_t alarm_evidence = 24000;       // upper evidence entry threshold for ALARM, mK x samples
  int32_t low_warn_evidence = 12000;    // lower evidence entry threshold for WARN; 0 = off
  int32_t abs_limit_mK = 80000;         // absolute temperature limit, degC * 1000
  uint16_t max_rise_mK_per_min = 3000;  // 0 = rate check disabled
};

// The two CUSUM statistics of one channel (see the header), kept in 24 bits each (they are never
// negative and capped below 2^24: 6 bytes per channel of the ATmega328P's 2 KB instead of 8).
class ResidualEvidence {
 public:
  static constexpr int32_t kMax = 16777215L;  // 2^24 - 1, mK x samples

  int32_t high() const { return get(high_); }  // mK x samples
  int32_t low() const { return get(low_); }
  void reset() {
    set(high_, 0);
    set(low_, 0);
  }
  // One model step with residual r (mK). |r| is clamped to 2^22 mK and the cap to kMax, so no
  // sum leaves int32.
  void add(int32_t residual_mK, uint16_t drift_mK, uint16_t low_drift_mK, int32_t cap) {
    const int32_t limit = 4194304L;
    const int32_t r = residual_mK > limit ? limit : (residual_mK < -limit ? -limit : residual_mK);
    const int32_t c = cap > kMax ? kMax : cap;
    set(high_, accumulate(get(high_), r - drift_mK, c));
    set(low_, accumulate(get(low_), -r - low_drift_mK, c));
  }

 private:
  static int32_t accumulate(int32_t s, int32_t v, int32_t cap) {
    s += v;
    return s < 0 ? 0 : (s > cap ? cap : s);
  }
  static int32_t get(const uint8_t* b) {
    return static_cast<int32_t>(static_cast<uint32_t>(b[0]) | (static_cast<uint32_t>(b[1]) << 8) |
                                (static_cast<uint32_t>(b[2]) << 16));
  }
  static void set(uint8_t* b, int32_t v) {
    const uint32_t u = static_cast<uint32_t>(v);
    b[0] = static_cast<uint8_t>(u);
    b[1] = static_cast<uint8_t>(u >> 8);
    b[2] = static_cast<uint8_t>(u >> 16);
  }
  uint8_t high_[3] = {0, 0, 0};
  uint8_t low_[3] = {0, 0, 0};
};

struct DiagTiming {
  uint8_t enter_samples = 3;         // N: persistence to enter WARN/ALARM (>= 1)
  uint8_t warn_clear_samples = 3;    // Mw
  uint8_t alarm_clear_samples = 60;  // Ma: 5 min at 5 s; 0 = never (held until acknowledged)
  uint8_t fault_clear_samples = 3;   // Mf
  uint16_t hysteresis_permille = 200;  // exit threshold = entry * (1 - h); 200 = 20 % below entry
  uint16_t abs_hysteresis_mK = 1000;   // absolute limit exit = limit - this
};

struct DiagInput {
  int32_t measured_mK = kDiagNoValue;      // filtered temperature, degC * 1000
  int32_t evidence_high = kDiagNoValue;    // ResidualEvidence::high(), or kDiagNoValue without a prediction
  int32_t evidence_low = kDiagNoValue;     // ResidualEvidence::low()
  int32_t rise_mK_per_min = kDiagNoValue;  // or kDiagNoValue (not yet known)
  bool fault = false;                      // channel fault flag for this sample
};

class DiagChannel {
 public:
  DiagState state() const { return state_; }
  uint8_t reasons() const { return reasons_; }
  bool alarm_latched() const { return latched_; }

  void acknowledge() {
    if (state_ == DiagState::kAlarm || (state_ == DiagState::kSensorFault && latched_)) acked_ = true;
  }

  // Back to NORMAL with all counters cleared (e.g. a new model was flashed).
  void reset() { *this = DiagChannel(); }

  DiagState update(const DiagInput& in, const DiagChannelLimits& lim, const DiagTiming& t) {
    const uint8_t n_enter = t.enter_samples == 0 ? 1 : t.enter_samples;
    if (in.fault || in.measured_mK == kDiagNoValue) {
      reasons_ = kReasonFault;
      if (state_ != DiagState::kSensorFault) {
        latched_ = state_ == DiagState::kAlarm;
        state_ = DiagState::kSensorFault;
      }
      count_ = 0;
      alarm_run_ = 0;
      warn_run_ = 0;
      return state_;
    }
    // The exit thresholds (three 32-bit divisions, ~600 cycles each on AVR) only matter when
    // leaving WARN, ALARM or SENSOR_FAULT; NORMAL, the usual state, skips them.
    const Conditions c = evaluate(in, lim, t, state_ != DiagState::kNormal);
    reasons_ = c.reasons;
    switch (state_) {
      case DiagState::kSensorFault:
        if (++count_ >= (t.fault_clear_samples == 0 ? 1 : t.fault_clear_samples)) {
          count_ = 0;
          if (latched_ && !(acked_ && c.alarm_clear)) {
            state_ = DiagState::kAlarm;
          } else {
            latched_ = false;
            acked_ = false;
            state_ = DiagState::kNormal;
          }
        }
        break;
      case DiagState::kNormal:
      case DiagState::kWarn:
        // Persistence: count consecutive samples of the strongest condition present.
        if (c.alarm) {
          alarm_run_ = sat_inc(alarm_run_);
        } else {
          alarm_run_ = 0;
        }
        if (c.warn) {
          warn_run_ = sat_inc(warn_run_);
        } else {
          warn_run_ = 0;
        }
        if (alarm_run_ >= n_enter) {
          enter_alarm();
        } else if (state_ == DiagState::kNormal) {
          if (warn_run_ >= n_enter) {
            state_ = DiagState::kWarn;
            count_ = 0;
          }
        } else {  // WARN: leave after Mw consecutive normal samples
          count_ = c.normal ? sat_inc(count_) : 0;
          if (count_ >= (t.warn_clear_samples == 0 ? 1 : t.warn_clear_samples)) {
            state_ = DiagState::kNormal;
            count_ = 0;
          }
        }
        break;
      case DiagState::kAlarm:
        if (acked_) reasons_ |= kReasonAcknowledged;
        if (acked_ && c.alarm_clear) {
          latched_ = false;
          acked_ = false;
          alarm_run_ = 0;
          warn_run_ = 0;
          count_ = 0;
          state_ = c.normal ? DiagState::kNormal : DiagState::kWarn;
          break;
        }
        if (t.alarm_clear_samples == 0) break;  // held until acknowledged
        count_ = c.normal ? sat_inc(count_) : 0;
        if (count_ >= t.alarm_clear_samples) {
          latched_ = false;
          acked_ = false;
          alarm_run_ = 0;
          warn_run_ = 0;
          count_ = 0;
          state_ = DiagState::kNormal;
        }
        break;
    }
    return state_;
  }

 private:
  struct Conditions {
    bool alarm;
    bool warn;
    bool alarm_clear;
    bool normal;
    uint8_t reasons;
  };

  static uint8_t sat_inc(uint8_t v) { return v == 0xFF ? v : static_cast<uint8_t>(v + 1); }

  // x * (1000 - h) / 1000 for the exit thresholds (x >= 0), in 32 bits: split at 1000 so the
  // evidence thresholds (up to 2^24) cannot overflow the product.
  static int32_t exit_threshold(int32_t entry, uint16_t h_permille) {
    const int32_t keep = 1000 - (h_permille > 1000 ? 1000 : static_cast<int32_t>(h_permille));
    const int32_t thousands = entry / 1000;
    return thousands * keep + ((entry - thousands * 1000) * keep) / 1000;
  }

  // alarm_clear and normal are only computed with need_exit (false otherwise).
  static Conditions evaluate(const DiagInput& in, const DiagChannelLimits& lim, const DiagTiming& t,
                             bool need_exit) {
    Conditions c;
    c.reasons = 0;
    const bool have_res = in.evidence_high != kDiagNoValue;
    if (!have_res) c.reasons |= kReasonNoPrediction;
    const bool low_on = lim.low_warn_evidence > 0;
    const bool res_alarm = have_res && in.evidence_high > lim.alarm_evidence;
    const bool res_warn =
        have_res && (in.evidence_high > lim.warn_evidence || (low_on && in.evidence_low > lim.low_warn_evidence));
    const bool abs_alarm = in.measured_mK > lim.abs_limit_mK;
    const bool have_rise = lim.max_rise_mK_per_min != 0 && in.rise_mK_per_min != kDiagNoValue;
    const bool rise_alarm = have_rise && in.rise_mK_per_min > static_cast<int32_t>(lim.max_rise_mK_per_min);
    if (res_warn) c.reasons |= kReasonResidualWarn;
    if (res_alarm) c.reasons |= kReasonResidualAlarm;
    if (abs_alarm) c.reasons |= kReasonAbsLimit;
    if (rise_alarm) c.reasons |= kReasonRise;
    c.alarm = res_alarm || abs_alarm || rise_alarm;
    c.warn = res_warn || c.alarm;
    c.alarm_clear = false;
    c.normal = false;
    if (!need_exit) return c;
    const int32_t h = t.hysteresis_permille;
    c.alarm_clear = (!have_res || in.evidence_high <= exit_threshold(lim.alarm_evidence, static_cast<uint16_t>(h))) &&
                    in.measured_mK <= lim.abs_limit_mK - static_cast<int32_t>(t.abs_hysteresis_mK) &&
                    (!have_rise || in.rise_mK_per_min <= exit_threshold(lim.max_rise_mK_per_min,
                                                                         static_cast<uint16_t>(h)));
    c.normal = c.alarm_clear &&
               (!have_res || (in.evidence_high <= exit_threshold(lim.warn_evidence, static_cast<uint16_t>(h)) &&
                              (!low_on || in.evidence_low <= exit_threshold(lim.low_warn_evidence, static_cast<uint16_t>(h)))));
    return c;
  }

  void enter_alarm() {
    state_ = DiagState::kAlarm;
    latched_ = true;
    acked_ = false;
    count_ = 0;
  }

  DiagState state_ = DiagState::kNormal;
  uint8_t reasons_ = 0;
  uint8_t count_ = 0;      // clear/exit counter of the current state
  uint8_t alarm_run_ = 0;  // consecutive alarm_cond samples
  uint8_t warn_run_ = 0;   // consecutive warn_cond samples
  bool latched_ = false;
  bool acked_ = false;
};

// All channels of a module; disabled channels stay NORMAL and do not count for the overall state.
template <uint8_t kChannels>
class Diagnosis {
 public:
  DiagTiming timing;
  DiagChannelLimits limits[kChannels];
  uint8_t enabled_mask = static_cast<uint8_t>((1U << kChannels) - 1U);

  DiagState update(const DiagInput* in) {
    overall_ = DiagState::kNormal;
    for (uint8_t j = 0; j < kChannels; ++j) {
      if (((enabled_mask >> j) & 1U) == 0) continue;
      overall_ = diag_worst(overall_, ch_[j].update(in[j], limits[j], timing));
    }
    return overall_;
  }
  void acknowledge_all() {
    for (uint8_t j = 0; j < kChannels; ++j) ch_[j].acknowledge();
  }
  void reset() {
    for (uint8_t j = 0; j < kChannels; ++j) ch_[j].reset();
    overall_ = DiagState::kNormal;
  }
  const DiagChannel& channel(uint8_t j) const { return ch_[j]; }
  DiagState overall() const { return overall_; }

 private:
  DiagChannel ch_[kChannels];
  DiagState overall_ = DiagState::kNormal;
};

// Rate of rise over a sliding window of kWindow samples: (T_now - T_oldest) scaled to mK/min.
// kDiagNoValue until the window is full, and again after reset() (call it on a sensor fault).
template <uint8_t kWindow>
class RiseRate {
  static_assert(kWindow >= 2, "window needs two samples");

 public:
  explicit RiseRate(uint16_t dt_ms = 5000) : dt_ms_(dt_ms) {}
  void set_dt_ms(uint16_t dt_ms) { dt_ms_ = dt_ms; reset(); }
  void reset() { count_ = 0; head_ = 0; }

  // Returns the current rate in mK/min (or kDiagNoValue): push_scaled() with the Scale of dt_ms().
  int32_t push(int32_t t_mK) { return push_scaled(t_mK, scale_for(dt_ms_)); }

  // What push_scaled() needs for one dt, in integers: the factor per_min = 60000 / (dt (kWindow - 1))
  // (1 / the window span in minutes) as its integer part and a 32-bit fraction, and the largest
  // |window difference| whose rate is computed (a larger one is clamped). The firmware's channels
  // share the sample period, so it is computed when the period changes (one 32-bit division and
  // a shift-and-subtract fraction), never per sample. Integers, not float: the soft-float library
  // costs the image ~1.1 KB of flash wherever one float operation remains.
  struct Scale {
    uint32_t per_min_frac;  // fractional part of per_min, x 2^32 (rounded)
    uint32_t max_diff;      // |diff| above this gives +-kDiagMaxRate
    uint16_t per_min_int;   // integer part of per_min (<= 60000)
  };
  static Scale scale_for(uint16_t dt_ms) {
    Scale s = {0, 0, 0};  // dt 0: every non-zero difference clamps (store() yields no rate then)
    const uint32_t span = static_cast<uint32_t>(dt_ms) * static_cast<uint32_t>(kWindow - 1);
    if (span == 0) return s;
    s.per_min_int = static_cast<uint16_t>(60000UL / span);
    s.per_min_frac = fx::frac_q32(60000UL % span, span);
    // |diff| <= max_diff keeps |diff| per_min_int <= 2^23 (the sum in scaled_rate() stays below
    // 2^24), and |diff| > max_diff means a rate above 2^23, which clamps anyway. Without an
    // integer part, (span / 60000 + 1) 2^23 >= 2^23 / per_min (< 2^32 for every uint16 dt and
    // kWindow <= 255).
    s.max_diff = s.per_min_int != 0 ? (1UL << 23) / s.per_min_int : (span / 60000UL + 1U) << 23;
    return s;
  }

  // Same as push(), with the Scale of dt_ms() supplied by the caller (see Scale).
  int32_t push_scaled(int32_t t_mK, const Scale& s) {
    int32_t oldest;
    if (!store(t_mK, oldest)) return kDiagNoValue;
    return scaled_rate(t_mK - oldest, s);
  }
  uint16_t dt_ms() const { return dt_ms_; }

  // push_scaled() in two steps, for a caller that needs the rate (and its Scale) only sometimes:
  // store() keeps the sample and says whether a rate is due (the window is full), giving the
  // oldest sample; scaled_rate(t_mK - oldest, s) is then the rate push_scaled() returns.
  bool store(int32_t t_mK, int32_t& oldest) {
    buf_[head_] = t_mK;
    head_ = static_cast<uint8_t>((head_ + 1) % kWindow);
    if (count_ < kWindow) ++count_;
    if (count_ < kWindow || dt_ms_ == 0) return false;
    oldest = buf_[head_];  // next slot to be overwritten = oldest sample
    return true;
  }

  // diff x per_min rounded to nearest (ties away from zero) and clamped to +-kDiagMaxRate:
  // |diff| per_min_int exactly plus round(|diff| per_min_frac / 2^32) (an integer added to a
  // rounded part is the rounded sum). per_min_frac is within 2^-33 of the true fraction, so the
  // result is the exactly rounded rate unless that lies within |diff| 2^-33 of a tie (the rates
  // that are not clamped: <= 2^-10 mK/min when per_min >= 1, <= 2^-10 / per_min otherwise, i.e.
  // <= 2^-8 for kWindow <= 4 and every uint16 dt); then it may be 1 mK/min off.
  // One 32 x 16 and one 32 x 32 product (fx::mul_hi_round), no division.
  static int32_t scaled_rate(int32_t diff, const Scale& s) {
    const bool negative = diff < 0;
    const uint32_t mag = negative ? 0U - static_cast<uint32_t>(diff) : static_cast<uint32_t>(diff);
    uint32_t rate = static_cast<uint32_t>(kDiagMaxRate);
    if (mag <= s.max_diff) {
      rate = mag * s.per_min_int + fx::mul_hi_round(mag, s.per_min_frac);
      if (rate > static_cast<uint32_t>(kDiagMaxRate)) rate = static_cast<uint32_t>(kDiagMaxRate);
    }
    return negative ? -static_cast<int32_t>(rate) : static_cast<int32_t>(rate);
  }

 private:
  int32_t buf_[kWindow] = {};
  uint16_t dt_ms_;
  uint8_t count_ = 0;
  uint8_t head_ = 0;
};

}  // namespace btsm

#endif  // BTSM_COMMON_DIAGNOSIS_HPP
