// Firmware glue around common/diagnosis.hpp: per-channel limits from the active reduced model
// (or the common defaults without a model), rate of rise from a short sliding window, and the
// channel roles (ambient and spare channels are measured but get no thermal limits: only their
// sensor faults are reported).
#ifndef BTSM_FIRMWARE_DIAGNOSIS_STAGE_HPP
#define BTSM_FIRMWARE_DIAGNOSIS_STAGE_HPP

#include <stdint.h>

#include "common/diagnosis.hpp"
#include "common/reduced_model.hpp"
#include "common/wire_messages.hpp"

namespace btsm {

class DiagnosisStage {
 public:
  static constexpr uint8_t kChannels = wire::kChannels;
  // Rise-rate window: 6 samples (25 s at the default 5 s period); RAM 24 B per channel.
  static constexpr uint8_t kRiseWindow = 6;

  // latch: ALARM auto-clears only after the longest run the counter allows (255 samples, > 21 min
  // at 5 s) -- in practice it waits for ACK_ALARM; without latch after 60 samples (5 min).
  void configure(bool latch) { diag_.timing.alarm_clear_samples = latch ? 255 : 60; }

  void evaluate(const ReducedModel* model, const int32_t* temp_mK, const int32_t* predicted_mK,
                const uint8_t* fault_bits, const uint8_t* roles, uint32_t dt_ms) {
    DiagInput in[kChannels];
    uint8_t mask = 0;
    for (uint8_t j = 0; j < kChannels; ++j) {
      const uint8_t role = roles[j];
      const bool thermal = role != static_cast<uint8_t>(wire::ChannelRole::Disabled) &&
                           role != static_cast<uint8_t>(wire::ChannelRole::Ambient) &&
                           role != static_cast<uint8_t>(wire::ChannelRole::Spare);
      const bool fault = (fault_bits[j] & static_cast<uint8_t>(~wire::kFaultKalmanReject & ~wire::kStatusDisabled)) != 0;
      fault_[j] = fault && role != static_cast<uint8_t>(wire::ChannelRole::Disabled);
      if (!thermal) continue;
      mask = static_cast<uint8_t>(mask | (1u << j));
      if (dt_ms > 0 && dt_ms < 65536UL) rise_[j].set_dt_ms_keep(static_cast<uint16_t>(dt_ms));
      in[j].fault = fault;
      in[j].measured_mK = temp_mK[j];
      in[j].predicted_mK = model != 0 ? predicted_mK[j] : kDiagNoValue;
      if (fault || temp_mK[j] == wire::kMissing) {
        rise_[j].reset();
        in[j].rise_mK_per_min = kDiagNoValue;
      } else {
        in[j].rise_mK_per_min = rise_[j].push(temp_mK[j]);
      }
      if (model != 0) {
        diag_.limits[j].warn_band_mK = model->limits[j].warn_band_mK;
        diag_.limits[j].alarm_band_mK = model->limits[j].alarm_band_mK;
        diag_.limits[j].abs_limit_mK = model->limits[j].abs_limit_mK;
        diag_.limits[j].max_rise_mK_per_min = model->limits[j].max_rise_mK_per_min;
      } else {
        diag_.limits[j] = DiagChannelLimits();
      }
    }
    diag_.enabled_mask = mask;
    diag_.update(in);
  }

  // Wire DiagState (2 bits) of a channel.
  uint8_t state(uint8_t j) const {
    if (((diag_.enabled_mask >> j) & 1U) == 0)
      return fault_[j] ? static_cast<uint8_t>(DiagState::kSensorFault) : static_cast<uint8_t>(DiagState::kNormal);
    return static_cast<uint8_t>(diag_.channel(j).state());
  }
  // Most severe state by wire ranking (ALARM > SENSOR_FAULT > WARN > NORMAL).
  uint8_t overall() const {
    DiagState worst = DiagState::kNormal;
    for (uint8_t j = 0; j < kChannels; ++j) worst = diag_worst(worst, static_cast<DiagState>(state(j)));
    return static_cast<uint8_t>(worst);
  }
  bool alarm_latched() const {
    for (uint8_t j = 0; j < kChannels; ++j)
      if (diag_.channel(j).alarm_latched()) return true;
    return false;
  }
  void acknowledge() { diag_.acknowledge_all(); }

 private:
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

  Diagnosis<kChannels> diag_;
  Rise rise_[kChannels];
  bool fault_[kChannels] = {false, false, false, false, false};
};

}  // namespace btsm

#endif
