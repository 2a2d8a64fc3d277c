// Non-blocking AD7794 acquisition: chip bring-up, per-channel calibration, round-robin sweeps of
// the five RTD channels with an open-wire (burnout) check, and detection of a silently reset chip.
//
// poll() never waits: it performs at most one short SPI transaction sequence and returns how many
// milliseconds it can sleep before it needs to run again (DOUT/RDY or a timer wakes it earlier).
//
// Per sweep and enabled channel:
//   1. channel configuration -- for AIN4..AIN6, which share one calibration pair on the chip,
//      also this channel's pair (restored from RAM); AIN1..AIN3 keep their own --
//      single conversion at the configured FS, wait RDY
//   2. on the channels whose open-wire check is due (AcquisitionSetup::burnout_checks_per_sweep
//      per sweep, rotating): same channel (calibration pair left in place) with the burnout
//      currents on, single conversion at FS 1 (4 ms): an open input is driven to full scale (ERR)
//      -- a healthy one moves by 100 nA x R (ignored). The verdict holds until the channel's next
//      check, so a broken sense lead (which reads a plausible stale value) stays reported.
// Before and after each sweep the mode/configuration/IO registers are read back; a mismatch means
// the chip reset itself (supply glitch, ESD): it is counted and the chip re-initialised.
#ifndef BTSM_FIRMWARE_ACQUISITION_HPP
#define BTSM_FIRMWARE_ACQUISITION_HPP

#include <stdint.h>

#include "common/platform.hpp"
#include "common/ratiometric.hpp"
#include "common/wire_messages.hpp"
#include "firmware/ad7794.hpp"

namespace btsm {

struct AcquisitionSetup {
  uint8_t fs = 10;                 // AD7794 FS code of measurement conversions (10 = 16.7 Hz)
  uint8_t gain_code = 2;           // PGA gain code (2 = x4: 0..1.7 kOhm with R_ref 6.8 kOhm)
  uint8_t enabled_mask = 0x1F;     // bit j = channel j (AIN j+1) is measured
  uint32_t r_ref_milliohm = 6800000;  // mOhm, reference resistor on REFIN1 (< 65536 ohm)
  uint16_t recalibrate_sweeps = 720;  // sweeps between internal recalibrations (0 = never)
  // Open-wire (burnout) checks per sweep, 1..5, rotating over the enabled channels: with 2 and
  // five channels every channel is checked at least every third sweep, so a broken sense lead is
  // reported within 3 samples (15 s at the default period); 5 checks every channel every sweep.
  // Each check is a 4 ms conversion and ~930 CPU cycles: 2 keeps the costliest sweep (a speed
  // change into an interpolated model segment while the filters settle) within its 40,000-cycle
  // budget. Between its checks a channel keeps the verdict of its last one.
  uint8_t burnout_checks_per_sweep = 2;
};

// Fault bits use the wire encoding (common/wire_messages.hpp kFault*).
struct ChannelReading {
  uint8_t faults;   // 0 = good reading
  uint32_t code;    // raw 24-bit conversion result
  uint32_t r_q16;   // ratiometric resistance, ohm x 2^16, valid when faults == 0
};

struct AcquisitionCounters {
  uint16_t adc_timeouts;   // RDY did not come in time
  uint16_t silent_resets;  // register read-back mismatch (chip reset behind our back)
  uint16_t inits;          // chip (re)initialisations including the first
  uint16_t missing;        // identification failures (no chip answering)
};

namespace detail_acq {
// The acquisition's scalar state. All zero after construction but for the entropy seed: a base
// class value-initialised by Acquisition's constructor, which the AVR build turns into one clearing
// loop instead of a store per member (the module's App is a static object built at start-up).
struct AcquisitionScalars {
  enum State : uint8_t {
    kStart, kResetWait, kMissing, kCalStart, kCalZeroWait, kCalFullWait, kIdle, kConvStart,
    kConvWait, kBurnWait,
  };
  AcquisitionCounters counters_;
  uint32_t mark_;
  uint32_t entropy_;
  uint16_t timeout_ms_;
  uint16_t last_config_;
  uint16_t sweeps_since_cal_;
  State state_;                // kStart
  uint8_t channel_;
  uint8_t burnout_due_;        // bit j: channel j gets its open-wire check this sweep
  uint8_t burnout_next_;       // where the next sweep's checks start
  uint8_t open_latched_;       // bit j: channel j's last open-wire check found it open
  uint8_t unchecked_;          // bit j: channel j has had no open-wire check since configure()
  bool burnout_on_;            // the chip's configuration has the burnout currents on
  AdcChip chip_;               // kNone
  bool calibrated_;
  bool sweep_requested_;
  bool sweep_ready_;
};
static_assert(AcquisitionScalars::kStart == 0 && static_cast<uint8_t>(AdcChip::kNone) == 0,
              "the zero state must be the initial one");
}  // namespace detail_acq

template <class Spi>
class Acquisition : private detail_acq::AcquisitionScalars {
 public:
  static constexpr uint8_t kChannels = wire::kChannels;
  static constexpr uint8_t kBurnoutFs = 1;               // 470 Hz, 4 ms settling
  static constexpr uint32_t kBurnoutOpenCode = 0xFFF000;  // at/above: driven to full scale
  static constexpr uint32_t kShortBelowQ16 = 500UL << 16; // 500 ohm: a PT1000 at -125.15 degC (IEC 60751: 500.6 ohm at -125 degC)
  static constexpr uint16_t kRetryMs = 1000;              // chip missing: identify again after
  static constexpr uint32_t kRailMarginCodes = 16;        // codes this close to a rail: saturated

  explicit Acquisition(Spi& spi) : AcquisitionScalars(), adc_(spi) {
    entropy_ = 0x9E3779B9UL;
    update_scale();
    for (uint8_t i = 0; i < kChannels; ++i) {
      readings_[i].faults = wire::kFaultAdc;
      readings_[i].code = 0;
      readings_[i].r_q16 = 0;
      cal_[i].offset = ad7794::kOffsetPowerOn;
      cal_[i].full_scale = 0;
    }
  }

  // New settings take effect with a full re-initialisation (reset + calibration).
  // A sweep in progress is restarted after the re-initialisation.
  void configure(const AcquisitionSetup& s) {
    setup_ = s;
    update_scale();
    open_latched_ = static_cast<uint8_t>(open_latched_ & s.enabled_mask);
    unchecked_ = s.enabled_mask;  // each channel is checked in the first sweep
    if (state_ == kConvStart || state_ == kConvWait || state_ == kBurnWait) {
      adc_.finish();
      sweep_requested_ = true;
    }
    state_ = kStart;
  }
  const AcquisitionSetup& setup() const { return setup_; }

  // Asks for one sweep; sweep_ready() turns true when its readings are available.
  void request_sweep() { sweep_requested_ = true; }
  bool sweep_ready() const { return sweep_ready_; }
  void take_sweep() { sweep_ready_ = false; }
  const ChannelReading& reading(uint8_t ch) const { return readings_[ch]; }
  bool calibrated() const { return calibrated_; }
  AdcChip chip() const { return chip_; }
  const AcquisitionCounters& counters() const { return counters_; }
  // Low bits of recent conversion results: noise, used as nonce entropy.
  uint32_t entropy() const { return entropy_; }
  const AdcCalibration& calibration(uint8_t ch) const { return cal_[ch]; }

  // Config register of a channel (unipolar, buffered, REFIN1 with reference detection).
  uint16_t channel_config(uint8_t ch, bool burnout) const {
    return static_cast<uint16_t>(ad7794::kConfUnipolar | (uint16_t(setup_.gain_code & 7) << ad7794::kConfGainShift) |
                                 (uint16_t(ad7794::kRefIn1) << ad7794::kConfRefselShift) |
                                 ad7794::kConfRefDet | ad7794::kConfBuf | (burnout ? ad7794::kConfBurnout : 0) |
                                 (ch & ad7794::kConfChannelMask));
  }
  // IO register: IEXC1 210 uA on IOUT1 (drives the chain), IEXC2 routed to IOUT2 (unused pin,
  // but both sources run: the routing with both on IOUT1 would double the current).
  static constexpr uint8_t kIoWord = ad7794::io_word(ad7794::kIexc1ToIout1, ad7794::kIexc210uA);

  // Advances the state machine. Returns the longest sleep (ms) before it must run again.
  uint32_t poll(uint32_t now_ms) {
    switch (state_) {
      case kStart:
        calibrated_ = false;
        ++counters_.inits;
        adc_.reset();
        mark_ = now_ms;
        state_ = kResetWait;
        return 2;
      case kResetWait:
        if (now_ms - mark_ < 2) return 1;  // >= 500 us after the reset (1 ms tick granularity)
        chip_ = adc_.identify();
        if (chip_ == AdcChip::kNone) {
          ++counters_.missing;
          fail_sweep(wire::kFaultAdc);
          mark_ = now_ms;
          state_ = kMissing;
          return kRetryMs;
        }
        adc_.write(ad7794::kRegIo, kIoWord, 1);
        channel_ = first_enabled(0);
        if (channel_ >= kChannels) {
          calibrated_ = true;
          state_ = kIdle;
          return 0;
        }
        state_ = kCalStart;
        return 0;
      case kMissing:
        if (sweep_requested_) fail_sweep(wire::kFaultAdc);
        if (now_ms - mark_ < kRetryMs) return kRetryMs - (now_ms - mark_);
        state_ = kStart;
        return 0;
      case kCalStart:
        adc_.prepare_channel(channel_config(channel_, false), setup_.fs);
        begin_wait(ad7794::kModeInternalZeroCal, setup_.fs, now_ms, ad7794::settle_ms(setup_.fs));
        state_ = kCalZeroWait;
        return wait_budget(now_ms);
      case kCalZeroWait:
        if (!adc_.ready()) return check_timeout(now_ms);
        adc_.finish();
        // Internal full-scale calibration takes 4 conversion cycles at gains above 1.
        begin_wait(ad7794::kModeInternalFullCal, setup_.fs, now_ms,
                   static_cast<uint16_t>(ad7794::settle_ms(setup_.fs) * (setup_.gain_code > 0 ? 2 : 1)));
        state_ = kCalFullWait;
        return wait_budget(now_ms);
      case kCalFullWait:
        if (!adc_.ready()) return check_timeout(now_ms);
        adc_.finish();
        cal_[channel_] = adc_.read_calibration();
        channel_ = first_enabled(channel_ + 1);
        if (channel_ < kChannels) {
          state_ = kCalStart;
          return 0;
        }
        calibrated_ = true;
        sweeps_since_cal_ = 0;
        last_config_ = channel_config(cal_channel_last(), false);
        state_ = kIdle;
        return 0;
      case kIdle:
        if (!sweep_requested_) return 0xFFFFFFFFUL;
        sweep_requested_ = false;
        if (!registers_intact()) {
          ++counters_.silent_resets;
          sweep_requested_ = true;  // serve it after the re-initialisation
          state_ = kStart;
          return 0;
        }
        channel_ = first_enabled(0);
        for (uint8_t i = 0; i < kChannels; ++i) {
          readings_[i].faults = 0;
          readings_[i].code = 0;
          readings_[i].r_q16 = 0;
        }
        plan_burnout_checks();
        if (channel_ >= kChannels) {
          sweep_ready_ = true;
          return 0;
        }
        return start_channel(now_ms);
      case kConvStart:
        return start_channel(now_ms);
      case kConvWait: {
        if (!adc_.ready()) return check_timeout(now_ms);
        uint8_t status = 0;
        uint32_t code = 0;
        adc_.finish_conversion(status, code, data_width());
        const bool check = ((burnout_due_ >> channel_) & 1U) != 0;
        if (check) {
          // Same channel with the burnout currents on: only the configuration changes (its
          // calibration pair is still in the chip). Started before the reading is evaluated, so
          // the conversion runs meanwhile.
          adc_.start_conversion(channel_config(channel_, true), 0, kBurnoutFs);
          arm_timeout(now_ms, ad7794::settle_ms(kBurnoutFs));
          burnout_on_ = true;
          state_ = kBurnWait;
        }
        // Rotate by whole bytes (register moves on AVR; a rotate by 3 is a ~250-cycle shift loop).
        entropy_ = ((entropy_ << 8) | (entropy_ >> 24)) ^ (code & 0xFF) ^ (code >> 8 & 0xFF);
        evaluate(channel_, status, code);
        if (check) return wait_budget(now_ms);
        // Not checked this sweep: the verdict of its last check stands (unless the reference is
        // missing, which makes every input look open).
        if ((open_latched_ >> channel_) & 1U) mark_open(readings_[channel_]);
        return next_channel(now_ms);
      }
      case kBurnWait: {
        if (!adc_.ready()) return check_timeout(now_ms);
        uint8_t status = 0;
        uint32_t code = 0;
        adc_.finish_conversion(status, code, data_width());
        const bool reference_missing = (status & ad7794::kStatusNoXref) != 0;
        if (!reference_missing) {
          const uint8_t bit = static_cast<uint8_t>(1U << channel_);
          unchecked_ = static_cast<uint8_t>(unchecked_ & ~bit);
          if ((status & ad7794::kStatusErr) || code >= kBurnoutOpenCode) {
            open_latched_ |= bit;
            mark_open(readings_[channel_]);
          } else {
            open_latched_ = static_cast<uint8_t>(open_latched_ & ~bit);
          }
        }
        return next_channel(now_ms);
      }
    }
    return 0;
  }

 private:


  uint8_t data_width() const { return chip_ == AdcChip::kAd7795 ? 2 : 3; }

  // The channels whose open-wire check is due this sweep: the next burnout_checks_per_sweep
  // enabled channels from where the last sweep's checks stopped, and every channel not checked
  // yet since configure() (the first sweep after start-up checks them all: an unconnected input
  // never reports a temperature).
  void plan_burnout_checks() {
    uint8_t left = setup_.burnout_checks_per_sweep;
    uint8_t due = 0;
    uint8_t ch = burnout_next_ < kChannels ? burnout_next_ : 0;
    for (uint8_t k = 0; k < kChannels && left != 0; ++k) {
      if ((setup_.enabled_mask >> ch) & 1U) {
        due = static_cast<uint8_t>(due | (1U << ch));
        --left;
      }
      ch = static_cast<uint8_t>(ch + 1 == kChannels ? 0 : ch + 1);
    }
    burnout_due_ = static_cast<uint8_t>(due | unchecked_);
    burnout_next_ = ch;
  }

  // An open input: open replaces a short verdict of the measurement (an open input may read 0).
  static void mark_open(ChannelReading& r) {
    if (r.faults & wire::kFaultReference) return;
    r.faults = static_cast<uint8_t>((r.faults & ~wire::kFaultShort) | wire::kFaultOpen);
  }

  // The next enabled channel in the same poll (its configuration write also switches the
  // burnout currents off), or the end of the sweep.
  uint32_t next_channel(uint32_t now_ms) {
    channel_ = first_enabled(channel_ + 1);
    if (channel_ < kChannels) return start_channel(now_ms);
    if (burnout_on_) adc_.write(ad7794::kRegConfig, last_config_, 2);  // the image the read-back expects
    end_sweep();
    return 0;
  }

  uint8_t first_enabled(uint8_t from) const {
    uint8_t ch = from;
    while (ch < kChannels && ((setup_.enabled_mask >> ch) & 1U) == 0) ++ch;
    return ch;
  }
  uint8_t cal_channel_last() const {
    uint8_t last = 0;
    for (uint8_t ch = 0; ch < kChannels; ++ch)
      if ((setup_.enabled_mask >> ch) & 1U) last = ch;
    return last;
  }

  // Measurement conversion of channel_: its configuration and, for AIN4..AIN6 (one shared pair
  // on the chip), its calibration pair restored from RAM; AIN1..AIN3 keep their own pair from the
  // calibration, so they need only the configuration (8 SPI bytes less each). The chip is in
  // power-down or idle here, where the pair may be written: the previous conversion of the sweep
  // has finished, or the read-back before the sweep has just checked the mode.
  BTSM_NOINLINE uint32_t start_channel(uint32_t now_ms) {
    const uint16_t config = channel_config(channel_, false);
    adc_.start_conversion(config, channel_ >= ad7794::kFirstSharedCalChannel ? &cal_[channel_] : 0, setup_.fs);
    last_config_ = config;
    burnout_on_ = false;
    arm_timeout(now_ms, ad7794::settle_ms(setup_.fs));
    state_ = kConvWait;
    return wait_budget(now_ms);
  }

  // A calibration: mode write, then wait for DOUT/RDY.
  void begin_wait(uint8_t mode, uint8_t fs, uint32_t now_ms, uint16_t expected_ms) {
    adc_.start(mode, fs);
    arm_timeout(now_ms, expected_ms);
  }
  BTSM_NOINLINE void arm_timeout(uint32_t now_ms, uint16_t expected_ms) {
    mark_ = now_ms;
    // Generous: twice the datasheet time plus the 1 ms oscillator start and tick jitter.
    timeout_ms_ = static_cast<uint16_t>(2 * expected_ms + 10);
  }
  uint32_t wait_budget(uint32_t now_ms) const {
    const uint32_t elapsed = now_ms - mark_;
    return elapsed >= timeout_ms_ ? 0 : timeout_ms_ - elapsed;
  }
  uint32_t check_timeout(uint32_t now_ms) {
    if (now_ms - mark_ <= timeout_ms_) return wait_budget(now_ms) + 1;
    adc_.finish();
    ++counters_.adc_timeouts;
    fail_sweep(wire::kFaultAdc);
    state_ = kStart;  // reset and re-identify: the chip may have vanished or locked up
    return 0;
  }

  // Marks every channel of the current (or next requested) sweep as failed and publishes it.
  BTSM_NOINLINE void fail_sweep(uint8_t fault) {
    for (uint8_t i = 0; i < kChannels; ++i) {
      readings_[i].faults = fault;
      readings_[i].code = 0;
      readings_[i].r_q16 = 0;
    }
    const bool in_sweep = state_ == kConvStart || state_ == kConvWait || state_ == kBurnWait;
    if (in_sweep || sweep_requested_) {
      sweep_requested_ = false;
      sweep_ready_ = true;
    }
  }

  BTSM_NOINLINE void evaluate(uint8_t ch, uint8_t status, uint32_t code) {
    ChannelReading& r = readings_[ch];
    r.code = code;
    uint8_t faults = 0;
    if ((status & ad7794::kStatusChannelMask) != (ch & ad7794::kStatusChannelMask) ||
        (status & ad7794::kStatusNotReady)) {
      faults |= wire::kFaultAdc;  // not the conversion we asked for
    }
    if (status & ad7794::kStatusNoXref) {
      faults |= wire::kFaultReference;
    } else if (status & ad7794::kStatusErr) {
      faults |= code == 0 ? wire::kFaultShort : wire::kFaultOpen;
    }
    if (chip_ == AdcChip::kAd7795) code <<= 8;
    // The AD7794 applied its own offset/full-scale calibration, the coding is unipolar: this is
    // code_to_resistance() (common/ratiometric.hpp) with an identity software calibration, whose
    // checks reduce to the configuration and the rails (a code between the rails cannot be negative
    // or beyond the gain's range), in fixed point: R_ref x 2^16 prepared in configure(), a reading
    // is one 32x32 product (code_to_ohm_q16), rounded once, no float.
    // Same statuses, the resistance within 2^-17 ohm (tests/unit/firmware/acquisition_test.cpp).
    const uint32_t margin = kRailMarginCodes;
    r.r_q16 = 0;
    RatioStatus rs = RatioStatus::kOk;
    if (!ref_ok_) {
      rs = RatioStatus::kBadConfig;
    } else if (status & ad7794::kStatusErr) {
      rs = RatioStatus::kAdcError;
    } else if (code <= margin) {
      rs = RatioStatus::kRailLow;
    } else if (code >= kAdcFullScaleCode - margin) {
      rs = RatioStatus::kRailHigh;
    } else {
      r.r_q16 = code_to_ohm_q16(code, static_cast<uint8_t>(setup_.gain_code & 7U), r_ref_q16_);
    }
    if (faults == 0) {
      switch (rs) {
        case RatioStatus::kOk:
          if (r.r_q16 < kShortBelowQ16) faults |= wire::kFaultShort;
          break;
        case RatioStatus::kRailLow: faults |= wire::kFaultShort; break;
        case RatioStatus::kRailHigh: faults |= wire::kFaultOpen; break;
        default: faults |= wire::kFaultAdc; break;
      }
    }
    r.faults = faults;
  }

  bool registers_intact() {
    const uint16_t mode = adc_.read16(ad7794::kRegMode);
    const uint16_t config = adc_.read16(ad7794::kRegConfig);
    const uint8_t io = adc_.read8(ad7794::kRegIo);
    const uint8_t md = ad7794::mode_of(mode);
    const bool mode_ok = (md == ad7794::kModeIdle || md == ad7794::kModePowerDown) &&
                         (mode & ~ad7794::kModeMdMask & ~ad7794::kModeFsMask) == 0;
    return mode_ok && config == last_config_ && io == kIoWord;
  }

  void end_sweep() {
    sweep_ready_ = true;
    if (!registers_intact()) {
      ++counters_.silent_resets;
      for (uint8_t i = 0; i < kChannels; ++i) readings_[i].faults |= wire::kFaultAdc;
      state_ = kStart;
      return;
    }
    ++sweeps_since_cal_;
    if (setup_.recalibrate_sweeps != 0 && sweeps_since_cal_ >= setup_.recalibrate_sweeps) {
      channel_ = first_enabled(0);
      state_ = kCalStart;
      return;
    }
    state_ = kIdle;
  }

  // R_ref in ohm x 2^16 for code_to_ohm_q16.
  void update_scale() {
    r_ref_q16_ = ohm_q16_from_milliohm(setup_.r_ref_milliohm);
    ref_ok_ = r_ref_q16_ != 0;  // checked once here, not per reading
  }

  Ad7794<Spi> adc_;
  AcquisitionSetup setup_;
  uint32_t r_ref_q16_;
  bool ref_ok_;
  AdcCalibration cal_[kChannels];
  ChannelReading readings_[kChannels];
};

}  // namespace btsm

#endif
