// Register-level AD7794 model; see the header for what is modelled and why.
#include "boards/sim/ad7794_model.hpp"

#include <algorithm>
#include <cmath>

#include "firmware/ad7794_regs.hpp"

namespace btsm::sim {
namespace {

constexpr double kTwo23 = 8388608.0;
constexpr double kTwo24 = 16777216.0;
constexpr double kInternalRefV = 1.17;         // V, internal band-gap reference
constexpr double kNoXrefThresholdV = 0.5;      // V, REF_DET trips below this (ADI EZ doc 2992)
constexpr double kMinUsableRefV = 0.1;         // V, below the specified reference range
constexpr double kBurnoutA = 100e-9;           // A, burnout current sources
constexpr double kShortOhm = 0.05;             // ohm, a shorted element
constexpr double kComplianceHeadroomV = 0.65;  // V, IOUT <= AVDD - 0.65 V (ADI DOC-13670)
constexpr double kTempSensorVPerK = 0.81e-3;   // V/K, internal temperature sensor slope
constexpr double kOscillatorStartS = 1e-3;     // s, leaving power-down
constexpr uint16_t kModeWritableMask = 0xF2DF;
constexpr uint8_t kIdValue = 0x3F;  // low nibble 0xF per datasheet; upper nibble is a model choice

double excitation_a(uint8_t code) {
  switch (code & 3) {
    case ad7794::kIexc10uA: return 10e-6;
    case ad7794::kIexc210uA: return 210e-6;
    case ad7794::kIexc1mA: return 1e-3;
    default: return 0.0;
  }
}

uint32_t clamp24(double v) {
  if (v <= 0.0) return 0;
  if (v >= kTwo24 - 1.0) return 0xFFFFFF;
  return static_cast<uint32_t>(std::llround(v));
}

}  // namespace

Ad7794Model::Ad7794Model(const Ad7794ModelOptions& options) : opt_(options) {
  // splitmix64 expands the seed into the xoshiro256** state.
  uint64_t s = opt_.seed;
  for (auto& word : rng_) {
    s += 0x9E3779B97F4A7C15ULL;
    uint64_t z = s;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    word = z ^ (z >> 31);
  }
  power_on_reset();
  reset_guard_until_s_ = 0.0;  // the board powers up long before the firmware talks to it
}

uint64_t Ad7794Model::next_random() {
  auto rotl = [](uint64_t x, int k) { return (x << k) | (x >> (64 - k)); };
  const uint64_t result = rotl(rng_[1] * 5, 7) * 9;
  const uint64_t t = rng_[1] << 17;
  rng_[2] ^= rng_[0];
  rng_[3] ^= rng_[1];
  rng_[1] ^= rng_[2];
  rng_[0] ^= rng_[3];
  rng_[2] ^= t;
  rng_[3] = rotl(rng_[3], 45);
  return result;
}

double Ad7794Model::gaussian() {
  // Marsaglia polar method: deterministic across standard libraries (unlike std::normal_distribution).
  if (have_spare_gauss_) {
    have_spare_gauss_ = false;
    return spare_gauss_;
  }
  double u, v, s;
  do {
    u = static_cast<double>(next_random() >> 11) * 0x1.0p-52 - 1.0;
    v = static_cast<double>(next_random() >> 11) * 0x1.0p-52 - 1.0;
    s = u * u + v * v;
  } while (s >= 1.0 || s == 0.0);
  const double f = std::sqrt(-2.0 * std::log(s) / s);
  spare_gauss_ = v * f;
  have_spare_gauss_ = true;
  return u * f;
}

// Input-referred rms noise. Datasheet anchors (AD7794/AD7795 Rev. D, front page, see
// https://vdocuments.us/ad7794ad7795-6-channel-low-noise-low-power-24-16-bit-6-channel-low-noise.html):
// 40 nV rms at 4.17 Hz and 85 nV rms at 16.7 Hz at high gain; the two anchors follow
// sqrt(f_ADC) (85 nV * sqrt(4.17/16.7) = 42 nV). The full noise-vs-gain table could not be
// retrieved, so the growth at low gain (in-amp bypassed at gain 1 and 2, fewer effective bits) is
// an ASSUMPTION: input-referred noise rises as sqrt(64/G) below gain 64. At gain 4 and 16.7 Hz this
// gives 0.34 uV rms, i.e. about 0.4 mK on a PT1000 at 210 uA.
double Ad7794Model::rms_noise_v(uint8_t gain_code, uint8_t fs) {
  const double f_hz = static_cast<double>(ad7794::rate_mhz(fs)) / 1000.0;
  if (f_hz <= 0.0) return 0.0;
  const double gain = static_cast<double>(ad7794::gain_of_code(gain_code));
  return 85e-9 * std::sqrt(f_hz / 16.7) * std::sqrt(std::max(1.0, 64.0 / gain));
}

void Ad7794Model::power_on_reset() { reset_registers(); }

void Ad7794Model::inject_silent_reset() { reset_registers(); }

void Ad7794Model::reset_registers() {
  mode_ = ad7794::kModePowerOn;
  config_ = ad7794::kConfPowerOn;
  io_ = 0;
  data_ = 0;
  data_unread_ = false;
  err_ = false;
  noxref_ = false;
  last_channel_ = 0;
  offset_.fill(ad7794::kOffsetPowerOn);
  // Factory full-scale trim at gain 1 (loaded at power-on).
  full_scale_.fill(static_cast<uint32_t>(
      std::llround(kFullScaleNominal / (1.0 + opt_.gain_error_ppm[0] * 1e-6))));
  phase_ = Phase::kComm;
  bytes_left_ = 0;
  ones_ = 0;
  cread_ = false;
  reset_guard_until_s_ = now_s_ + opt_.reset_guard_s;
  ++counters_.resets;
  start_job_for_mode(false);  // power-on default: continuous conversion
}

void Ad7794Model::set_cs(bool low) {
  if (cs_low_ && !low) {
    // Taking CS high ends a partial transfer (model choice: the interface returns to waiting for a
    // communications byte; continuous-read mode stays active).
    phase_ = cread_ ? Phase::kContinuousRead : Phase::kComm;
    bytes_left_ = 0;
  }
  cs_low_ = low;
}

bool Ad7794Model::rdy_low() const {
  if (fe_.chip_missing || !cs_low_) return false;
  if (phase_ == Phase::kRead && reg_ == ad7794::kRegData) return false;  // mid-read: DOUT is data
  return data_unread_;
}

uint8_t Ad7794Model::status_register() const {
  uint8_t s = 0;
  if (!data_unread_) s |= ad7794::kStatusNotReady;
  if (err_) s |= ad7794::kStatusErr;
  if (noxref_) s |= ad7794::kStatusNoXref;
  if (!opt_.ad7795) s |= ad7794::kStatusAd7794;
  s |= static_cast<uint8_t>(last_channel_ & ad7794::kStatusChannelMask);
  return s;
}

uint32_t Ad7794Model::register_value(uint8_t reg) const {
  const uint8_t pair = ad7794::cal_pair(ad7794::channel_of(config_));
  switch (reg) {
    case ad7794::kRegStatus: return status_register();
    case ad7794::kRegMode: return mode_;
    case ad7794::kRegConfig: return config_;
    case ad7794::kRegData: return opt_.ad7795 ? (data_ >> 8) : data_;
    case ad7794::kRegId: return kIdValue;
    case ad7794::kRegIo: return io_;
    case ad7794::kRegOffset: return offset_[pair];
    case ad7794::kRegFullScale: return full_scale_[pair];
    default: return 0;
  }
}

uint8_t Ad7794Model::transfer(uint8_t mosi) {
  if (fe_.chip_missing || !cs_low_) return 0xFF;  // nothing drives MISO: pulled up
  // 32 consecutive ones on DIN reset the whole part, whatever the interface state.
  if (mosi == 0xFF) {
    ones_ += 8;
    if (ones_ >= 32) {
      ones_ = 0;
      reset_registers();
      return 0xFF;
    }
  } else {
    ones_ = 0;
  }
  if (now_s_ < reset_guard_until_s_) {
    ++counters_.access_during_reset;
    return 0xFF;
  }
  const uint8_t data_width = opt_.ad7795 ? 2 : 3;
  switch (phase_) {
    case Phase::kComm: {
      if (mosi & ad7794::kCommWen) return 0xFF;  // WEN = 1: not a command (e.g. a run of ones)
      reg_ = static_cast<uint8_t>((mosi >> 3) & 7);
      if (mosi & ad7794::kCommRead) {
        if (reg_ == ad7794::kRegData && (mosi & ad7794::kCommCread)) {
          cread_ = true;
          phase_ = Phase::kContinuousRead;
          bytes_left_ = 0;
          return 0xFF;
        }
        shift_ = register_value(reg_);
        bytes_left_ = reg_ == ad7794::kRegData ? data_width : ad7794::width(reg_);
        phase_ = Phase::kRead;
      } else if (reg_ != ad7794::kRegComm) {
        shift_ = 0;
        bytes_left_ = reg_ == ad7794::kRegData ? data_width : ad7794::width(reg_);
        phase_ = Phase::kWrite;
      }
      return 0xFF;
    }
    case Phase::kRead: {
      --bytes_left_;
      const auto out = static_cast<uint8_t>(shift_ >> (8 * bytes_left_));
      if (bytes_left_ == 0) {
        phase_ = cread_ ? Phase::kContinuousRead : Phase::kComm;
        if (reg_ == ad7794::kRegData) data_unread_ = false;
      }
      return out;
    }
    case Phase::kWrite: {
      shift_ = (shift_ << 8) | mosi;
      if (--bytes_left_ == 0) {
        phase_ = Phase::kComm;
        apply_write(reg_, shift_);
      }
      return 0xFF;
    }
    case Phase::kContinuousRead: {
      if (bytes_left_ == 0) {
        if (mosi == ad7794::kCommLeaveContinuousRead && data_unread_) {
          // Leaving continuous read; the 0x58 byte itself is a "read data" command.
          cread_ = false;
          reg_ = ad7794::kRegData;
          shift_ = register_value(reg_);
          bytes_left_ = data_width;
          phase_ = Phase::kRead;
          return 0xFF;
        }
        if (!data_unread_) return 0xFF;
        reg_ = ad7794::kRegData;
        shift_ = register_value(reg_);
        bytes_left_ = data_width;
      }
      --bytes_left_;
      const auto out = static_cast<uint8_t>(shift_ >> (8 * bytes_left_));
      if (bytes_left_ == 0) data_unread_ = false;
      return out;
    }
  }
  return 0xFF;
}

void Ad7794Model::apply_write(uint8_t reg, uint32_t value) {
  const uint8_t md = ad7794::mode_of(mode_);
  switch (reg) {
    case ad7794::kRegMode: {
      mode_ = static_cast<uint16_t>(value & kModeWritableMask);
      data_unread_ = false;
      start_job_for_mode(md == ad7794::kModePowerDown);
      break;
    }
    case ad7794::kRegConfig: {
      config_ = static_cast<uint16_t>(value);
      data_unread_ = false;
      // A channel or setup change restarts a running conversion with full settling.
      if (job_ == Job::kConvert) start_job_for_mode(false);
      break;
    }
    case ad7794::kRegIo: io_ = static_cast<uint8_t>(value & 0x7F); break;
    case ad7794::kRegOffset:
    case ad7794::kRegFullScale: {
      if (md != ad7794::kModeIdle && md != ad7794::kModePowerDown) {
        ++counters_.ignored_cal_writes;
        break;
      }
      const uint8_t pair = ad7794::cal_pair(ad7794::channel_of(config_));
      (reg == ad7794::kRegOffset ? offset_ : full_scale_)[pair] = value & 0xFFFFFF;
      break;
    }
    default: break;  // status, data and ID are read-only
  }
}

void Ad7794Model::start_job_for_mode(bool leaving_power_down) {
  const uint8_t md = ad7794::mode_of(mode_);
  const uint8_t fs = static_cast<uint8_t>(mode_ & ad7794::kModeFsMask);
  const double settle_s = ad7794::settle_ms(fs) / 1000.0;
  const double start_s = now_s_ + (leaving_power_down ? kOscillatorStartS : 0.0);
  const uint8_t gain_code = ad7794::gain_code_of(config_);
  switch (md) {
    case ad7794::kModeContinuous:
    case ad7794::kModeSingle: job_ = Job::kConvert; break;
    case ad7794::kModeInternalZeroCal: job_ = Job::kZeroCal; break;
    case ad7794::kModeInternalFullCal: job_ = Job::kFullCal; break;
    case ad7794::kModeSystemZeroCal: job_ = Job::kSystemZeroCal; break;
    case ad7794::kModeSystemFullCal: job_ = Job::kSystemFullCal; break;
    default: job_ = Job::kNone; break;
  }
  if (job_ == Job::kNone || settle_s <= 0.0) {
    job_done_s_ = kNever;
    if (settle_s <= 0.0) job_ = Job::kNone;  // FS = 0 is reserved: nothing ever completes
    return;
  }
  // Calibrations take 2 conversion cycles (= settling time); internal full-scale at gains > 1 takes 4.
  double duration = settle_s;
  if (job_ == Job::kFullCal && gain_code > 0) duration *= 2.0;
  job_done_s_ = start_s + duration;
}

double Ad7794Model::chain_current_a() const {
  if (ad7794::mode_of(mode_) == ad7794::kModePowerDown) return 0.0;
  for (auto f : fe_.probe_fault)
    if (f == ProbeFault::kOpenElement) return 0.0;
  const double per_source = excitation_a(io_ & ad7794::kIoEnMask);
  const uint8_t dir = static_cast<uint8_t>((io_ & ad7794::kIoDirMask) >> ad7794::kIoDirShift);
  // Which IOUT pin each of IEXC1 and IEXC2 drives.
  int iexc1_pin = 1, iexc2_pin = 2;
  switch (dir) {
    case ad7794::kIexc1ToIout2: iexc1_pin = 2; iexc2_pin = 1; break;
    case ad7794::kIexcBothIout1: iexc1_pin = 1; iexc2_pin = 1; break;
    case ad7794::kIexcBothIout2: iexc1_pin = 2; iexc2_pin = 2; break;
    default: break;
  }
  double current = 0.0;
  if (iexc1_pin == fe_.chain_iout) current += per_source;
  if (iexc2_pin == fe_.chain_iout) current += per_source;
  // Compliance: the source saturates when the chain would need more than AVDD - 0.65 V.
  double r_total = fe_.r_ref_ohm + 2.0 * AnalogFrontEnd::kProbes * fe_.lead_ohm;
  for (int k = 0; k < AnalogFrontEnd::kProbes; ++k)
    r_total += fe_.probe_fault[k] == ProbeFault::kShort ? kShortOhm : fe_.probe_ohm[k];
  const double v_max = fe_.avdd_v - kComplianceHeadroomV;
  if (current * r_total > v_max) current = v_max / r_total;
  return current;
}

double Ad7794Model::reference_v(uint8_t channel) const {
  if (channel == ad7794::kTempSensor || channel == ad7794::kAvddMonitor) return kInternalRefV;
  switch (ad7794::refsel_of(config_)) {
    case ad7794::kRefIn1: return fe_.reference_lost ? 0.0 : chain_current_a() * fe_.r_ref_ohm;
    case ad7794::kRefIn2: return fe_.refin2_v;
    case ad7794::kRefInternal: return kInternalRefV;
    default: return 0.0;  // reserved code
  }
}

// Differential input voltage of a channel; *floating_high is set when the input is open and the
// burnout currents pull it beyond full scale.
double Ad7794Model::input_v(uint8_t channel, bool* floating_high) const {
  *floating_high = false;
  const bool burnout_active = (config_ & ad7794::kConfBurnout) &&
                              ((config_ & ad7794::kConfBuf) || ad7794::gain_code_of(config_) > 1);
  if (channel == ad7794::kTempSensor) return kTempSensorVPerK * (fe_.chip_temp_c + 273.15);
  if (channel == ad7794::kAvddMonitor) return fe_.avdd_v / 6.0;
  if (channel == ad7794::kAin1Shorted) return 0.0;
  if (channel >= AnalogFrontEnd::kProbes) {  // AIN6: not connected
    *floating_high = burnout_active;
    return 0.0;
  }
  const ProbeFault fault = fe_.probe_fault[channel];
  const double current = chain_current_a();
  if (fault == ProbeFault::kOpenSense || fault == ProbeFault::kOpenElement) {
    // An open input holds whatever charge its filter capacitor had: without burnout currents the
    // reading stays at a plausible stale value (here: the healthy element's voltage) -- which is
    // why the firmware runs a separate burnout conversion.
    *floating_high = burnout_active;
    return fault == ProbeFault::kOpenSense ? current * fe_.probe_ohm[channel] : 0.0;
  }
  const double r = fault == ProbeFault::kShort ? kShortOhm : fe_.probe_ohm[channel];
  return (current + (burnout_active ? kBurnoutA : 0.0)) * r;
}

// Modulator output normalised to the full-scale input (1.0 = V_ref / G), before the
// offset/full-scale coefficients are applied.
double Ad7794Model::modulator_output(uint8_t channel, bool internal_zero, bool internal_full,
                                     bool* no_ref, bool* over_range) {
  *no_ref = false;
  *over_range = false;
  const bool internal_channel = channel == ad7794::kTempSensor || channel == ad7794::kAvddMonitor;
  const uint8_t gain_code = internal_channel ? 0 : ad7794::gain_code_of(config_);
  const double gain = ad7794::gain_of_code(gain_code);
  const double v_ref = reference_v(channel);
  const bool external_ref = !internal_channel && ad7794::refsel_of(config_) != ad7794::kRefInternal;
  noxref_ = external_ref && (config_ & ad7794::kConfRefDet) && v_ref < kNoXrefThresholdV;
  if (noxref_ || v_ref < kMinUsableRefV) {
    *no_ref = true;
    return 0.0;
  }
  bool floating_high = false;
  double v_in = internal_zero ? 0.0 : (internal_full ? v_ref / gain : input_v(channel, &floating_high));
  if (floating_high) {
    *over_range = true;
    return 2.0;
  }
  const uint8_t fs = static_cast<uint8_t>(mode_ & ad7794::kModeFsMask);
  const double gain_actual = gain * (1.0 + opt_.gain_error_ppm[gain_code] * 1e-6);
  const double offset_v = opt_.offset_error_uv[std::min<uint8_t>(channel, 8)] * 1e-6;
  const double noise_v = opt_.noise_scale * rms_noise_v(gain_code, fs) * gaussian();
  return (gain_actual * v_in + gain * (offset_v + noise_v)) / v_ref;
}

void Ad7794Model::complete_job() {
  const uint8_t channel = ad7794::channel_of(config_);
  const uint8_t pair = ad7794::cal_pair(channel);
  const bool unipolar = config_ & ad7794::kConfUnipolar;
  const double off = (static_cast<double>(offset_[pair]) - kTwo23) / kTwo24;
  const double fs_gain = static_cast<double>(full_scale_[pair]) / kFullScaleNominal;
  bool no_ref = false, over = false;
  const uint8_t md = ad7794::mode_of(mode_);
  switch (job_) {
    case Job::kConvert: {
      const double m = modulator_output(channel, false, false, &no_ref, &over);
      const double y = (m - off) * fs_gain;
      const double code = unipolar ? y * kTwo24 : kTwo23 + y * kTwo23;
      if (no_ref || over) {
        data_ = 0xFFFFFF;
        err_ = true;
      } else {
        data_ = clamp24(code);
        err_ = code < 0.0 || code > kTwo24 - 1.0;
      }
      if (data_unread_) ++counters_.overwritten_results;
      data_unread_ = true;
      last_channel_ = channel;
      ++counters_.conversions;
      if (md == ad7794::kModeContinuous) {
        const double rate = ad7794::rate_mhz(static_cast<uint8_t>(mode_ & ad7794::kModeFsMask)) / 1000.0;
        job_done_s_ += 1.0 / rate;
      } else {
        mode_ = static_cast<uint16_t>((mode_ & ~ad7794::kModeMdMask) |
                                      (uint16_t(ad7794::kModePowerDown) << ad7794::kModeMdShift));
        job_ = Job::kNone;
        job_done_s_ = kNever;
      }
      return;
    }
    case Job::kZeroCal:
    case Job::kSystemZeroCal: {
      const double m = modulator_output(channel, job_ == Job::kZeroCal, false, &no_ref, &over);
      if (!no_ref && !over) offset_[pair] = clamp24(kTwo23 + m * kTwo24);
      break;
    }
    case Job::kFullCal:
    case Job::kSystemFullCal: {
      const bool internal = job_ == Job::kFullCal;
      if (internal && ad7794::gain_code_of(config_) == 7) {
        ++counters_.invalid_calibrations;  // internal full-scale calibration impossible at gain 128
        break;
      }
      const double m = modulator_output(channel, false, internal, &no_ref, &over);
      if (!no_ref && !over && m - off > 0.01)
        full_scale_[pair] = clamp24(kFullScaleNominal / (m - off));
      break;
    }
    case Job::kNone: return;
  }
  // Calibrations end in idle mode with DOUT/RDY low.
  ++counters_.calibrations;
  mode_ = static_cast<uint16_t>((mode_ & ~ad7794::kModeMdMask) |
                                (uint16_t(ad7794::kModeIdle) << ad7794::kModeMdShift));
  job_ = Job::kNone;
  job_done_s_ = kNever;
  data_unread_ = true;
}

void Ad7794Model::advance(double seconds) {
  if (seconds < 0.0) seconds = 0.0;
  const double t_end = now_s_ + seconds;
  while (job_done_s_ <= t_end) {
    now_s_ = job_done_s_;
    complete_job();
  }
  now_s_ = t_end;
}

double Ad7794Model::time_to_next_event() const {
  if (job_done_s_ == kNever) return kNever;
  return std::max(0.0, job_done_s_ - now_s_);
}

}  // namespace btsm::sim
