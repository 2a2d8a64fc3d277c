// Firmware glue around common/diagnosis.hpp: per-channel limits and detector parameters from the
// active reduced model (or the common defaults without a model), the residual evidence of every
// channel (accumulated per model step), rate of rise from a short sliding window, and the channel
// roles (ambient and spare channels are measured but get no thermal limits: only their sensor
// faults are reported).
#ifndef BTSM_FIRMWARE_DIAGNOSIS_STAGE_HPP
#define BTSM_FIRMWARE_DIAGNOSIS_STAGE_HPP

#include <stdint.h>

#include "common/diagnosis.hpp"
#include "common/model_blob.hpp"
#include "common/wire_messages.hpp"
#include "common/platform.hpp"

namespace btsm {

class DiagnosisStage {
 public:
  static constexpr uint8_t kChannels = wire::kChannels;
  // Rise-rate window: 4 samples (15 s at the default 5 s period); RAM 16 B per channel.
  static constexpr uint8_t kRiseWindow = 4;

  // latch: an ALARM is held until ACK_ALARM (then it clears as soon as its condition is gone);
  // without latch it clears after 60 consecutive normal samples (5 min at 5 s).
  void configure(bool latch) { timing_.alarm_clear_samples = latch ? 0 : 60; }

  // One model step's residuals into the evidence: per channel measured - predicted, with the
  // channel's drift from the model's limits; a channel without a reading or a prediction starts
  // its evidence afresh (a fault or a new model says nothing about what came before).
  BTSM_NOINLINE void accumulate(const ChannelLimits* limits, const int32_t* temp_mK, const int32_t* predicted_mK) {
    for (uint8_t j = 0; j < kChannels; ++j) {
      const ChannelLimits& l = limits[j];
      if (temp_mK[j] == wire::kMissing || predicted_mK[j] == wire::kMissing || l.alarm_evidence == 0) {
        evidence_[j].reset();
        continue;
      }
      // cap = 2 x the ALARM threshold (common/diagnosis.hpp).
      evidence_[j].add(temp_mK[j] - predicted_mK[j], l.drift_mK, l.low_drift_mK, evidence_cap_mk_samples(l.alarm_evidence));
    }
  }
  void reset_evidence() {
    for (uint8_t j = 0; j < kChannels; ++j) evidence_[j].reset();
  }
  const ResidualEvidence& evidence(uint8_t j) const { return evidence_[j]; }

  // limits: per-channel limits of the active model, or null without a model (common defaults).
  // Channels are updated one at a time with one DiagInput/DiagChannelLimits on the stack: an
  // array of them with default initialisers would cost an SRAM image on AVR.
  BTSM_NOINLINE void evaluate(const ChannelLimits* limits, const int32_t* temp_mK, const int32_t* predicted_mK,
                              const uint8_t* fault_bits, const uint8_t* roles, uint32_t dt_ms) {
    mask_ = 0;
    Sweep sw = {limits, temp_mK, predicted_mK, fault_bits, roles, dt_ms};
    for (uint8_t j = 0; j < kChannels; ++j) evaluate_channel(j, sw);
  }

  // Wire DiagState (2 bits) of a channel.
  uint8_t state(uint8_t j) const {
    if (((mask_ >> j) & 1U) == 0)
      return fault_[j] ? static_cast<uint8_t>(DiagState::kSensorFault) : static_cast<uint8_t>(DiagState::kNormal);
    return static_cast<uint8_t>(ch_[j].state());
  }
  // Most severe state by wire ranking (ALARM > SENSOR_FAULT > WARN > NORMAL).
  uint8_t overall() const {
    DiagState worst = DiagState::kNormal;
    for (uint8_t j = 0; j < kChannels; ++j) worst = diag_worst(worst, static_cast<DiagState>(state(j)));
    return static_cast<uint8_t>(worst);
  }
  bool alarm_latched() const {
    for (uint8_t j = 0; j < kChannels; ++j)
      if (ch_[j].alarm_latched()) return true;
    return false;
  }
  void acknowledge() {
    for (uint8_t j = 0; j < kChannels; ++j) ch_[j].acknowledge();
  }

 private:
  struct Sweep {
    const ChannelLimits* limits;
    const int32_t* temp_mK;
    const int32_t* predicted_mK;
    const uint8_t* fault_bits;
    const uint8_t* roles;
    uint32_t dt_ms;
  };

  // One channel out of line: inlined into the channel loop the body ran out of registers and
  // spent ~150 cycles per channel moving spilled loop pointers.
  BTSM_NOINLINE void evaluate_channel(uint8_t j, Sweep& sw) {
    const uint8_t role = sw.roles[j];
    const bool thermal = wire::is_thermal_role(role);
    const bool fault =
        (sw.fault_bits[j] & static_cast<uint8_t>(~wire::kFaultKalmanReject & ~wire::kStatusDisabled)) != 0;
    fault_[j] = fault && role != static_cast<uint8_t>(wire::ChannelRole::Disabled);
    if (!thermal) {
      ch_[j].reset();
      return;
    }
    mask_ = static_cast<uint8_t>(mask_ | (1u << j));
    if (sw.dt_ms > 0 && sw.dt_ms < 65536UL) rise_[j].set_dt_ms_keep(static_cast<uint16_t>(sw.dt_ms));
    const int32_t t_mK = sw.temp_mK[j];
    DiagChannelLimits lim;
    if (sw.limits != 0) {
      const ChannelLimits& l = sw.limits[j];
      lim.warn_evidence = evidence_mk_samples(l.warn_evidence);
      lim.alarm_evidence = evidence_mk_samples(l.alarm_evidence);
      lim.low_warn_evidence = evidence_mk_samples(l.low_warn_evidence);
      lim.abs_limit_mK = l.abs_limit_mK;
      lim.max_rise_mK_per_min = l.max_rise_mK_per_min;
    }
    DiagInput in;
    in.fault = fault;
    in.measured_mK = t_mK;
    if (sw.limits != 0 && sw.predicted_mK[j] != wire::kMissing && sw.limits[j].alarm_evidence != 0) {
      in.evidence_high = evidence_[j].high();
      in.evidence_low = evidence_[j].low();
    }
    in.rise_mK_per_min = kDiagNoValue;
    int32_t oldest;
    if (fault || t_mK == wire::kMissing) {
      rise_[j].reset();
    } else if (rise_[j].store(t_mK, oldest) && lim.max_rise_mK_per_min != 0) {
      // The rate (two integer products) only where a limit checks it, and its scale (a division
      // and a 32-step fraction) only once a rate is due: the channels share the sample period, so
      // the scale is computed when the window dt changes (scale_dt_ = 0: none yet).
      if (rise_[j].dt_ms() != scale_dt_) {
        scale_dt_ = rise_[j].dt_ms();
        scale_ = RiseRate<kRiseWindow>::scale_for(scale_dt_);
      }
      in.rise_mK_per_min = RiseRate<kRiseWindow>::scaled_rate(t_mK - oldest, scale_);
    }
    ch_[j].update(in, lim, timing_);
  }

  // RiseRate with a dt that can follow the measured sweep interval without losing its window
  // when the interval is unchanged.
  class Rise : public RiseRate<kRiseWindow> {
   public:
    void set_dt_ms_keep(uint16_t dt) {
      // Sweeps jitter by a tick or two; only a real period change restarts the window.
      if (dt + 50 < dt_ || dt > dt_ + 50) {
        dt_ = dt;
        set_dt_ms(dt);
      }
    }

   private:
    uint16_t dt_ = 5000;
  };

  DiagChannel ch_[kChannels];
  ResidualEvidence evidence_[kChannels];
  DiagTiming timing_;
  Rise rise_[kChannels];
  RiseRate<kRiseWindow>::Scale scale_ = {0, 0, 0};
  uint16_t scale_dt_ = 0;
  uint8_t mask_ = 0;
  bool fault_[kChannels] = {false, false, false, false, false};
};

}  // namespace btsm

#endif
