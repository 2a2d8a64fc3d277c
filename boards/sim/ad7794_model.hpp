// Register-level, time-driven model of the AD7794 24-bit sigma-delta ADC and of the BTSM analog
// front end around it (five PT1000 probes in a 4-wire series chain with R_ref on REFIN1, driven
// by the chip's excitation current).
//
// One model serves the native simulated board (boards/sim/native_board.hpp) and the simavr
// harness: the MCU side only sees chip select, byte transfers and the DOUT/RDY level; the plant
// side writes probe resistances and faults into `front_end()`. Time is explicit: the owner calls
// `advance(seconds)`; `time_to_next_event()` says when the next conversion or calibration ends so
// a simulation can jump there (faster than real time).
//
// What is modelled (facts from the AD7794/AD7795 datasheet, Rev. D):
//  - all 8 registers with AD7794 widths (AD7795 option: 16-bit data, status bit 3 = 0), POR values
//  - communications state machine, WEN bit, read/write, continuous read (CREAD 0x5C / exit 0x58),
//    reset on 32 consecutive ones on DIN; serial accesses within 500 us of a reset are ignored
//  - conversion timing from FS (settling 2/f_ADC after mode/config writes, 1/f_ADC afterwards in
//    continuous mode, +1 ms oscillator start leaving power-down), single mode returns to power-down
//  - DOUT/RDY (low while CS low and a fresh result is unread; reading the data register sets it)
//  - gain 1..128, unipolar / bipolar (offset binary) coding, ERR clamping, REFSEL (REFIN1, REFIN2,
//    internal 1.17 V), REF_DET/NOXREF (< 0.5 V), burnout currents (100 nA, need buffer or in-amp)
//  - excitation currents (10 uA/210 uA/1 mA) and routing IEXCDIR to IOUT1/IOUT2, compliance limit
//  - internal and system zero/full-scale calibration into per-channel register pairs, with AIN4,
//    AIN5 and AIN6 sharing one pair; offset/full-scale writes accepted only in idle or power-down
//  - untrimmed offset and gain errors (so calibration matters), seeded Gaussian noise
//  - faults: open sense lead, open element (chain broken), shorted probe, lost reference, missing
//    chip (MISO stuck high, no RDY), silent reset (e.g. supply glitch: registers back to POR)
#ifndef BTSM_BOARDS_SIM_AD7794_MODEL_HPP
#define BTSM_BOARDS_SIM_AD7794_MODEL_HPP

#include "common/channels.hpp"
#include "firmware/ad7794_regs.hpp"

#include <array>
#include <cstdint>
#include <limits>

namespace btsm::sim {

// Fault of one probe in the series chain.
enum class ProbeFault : uint8_t {
  kNone,
  kOpenSense,    // a sense lead is broken: the AIN pair floats, excitation still flows
  kOpenElement,  // the element or a force lead is broken: no excitation current anywhere
  kShort,        // element shorted: ~0.05 ohm between the sense leads
};

// The analog world around the chip. The plant writes these at any time; a conversion uses the
// values current at its completion time.
struct AnalogFrontEnd {
  static constexpr int kProbes = kChannels;  // one probe per module channel on AIN1..AIN5; AIN6 floats
  std::array<double, kProbes> probe_ohm{1000.0, 1000.0, 1000.0, 1000.0, 1000.0};  // ohm
  std::array<ProbeFault, kProbes> probe_fault{};
  double r_ref_ohm = 6800.0;       // ohm, reference resistor across REFIN1(+)/REFIN1(-)
  int chain_iout = 1;              // IOUT pin (1 or 2) that drives the probe chain
  double avdd_v = 5.0;             // V, analog supply (excitation compliance = AVDD - 0.65 V)
  double refin2_v = 0.0;           // V, nothing connected to REFIN2 on the BTSM board
  double chip_temp_c = 25.0;       // degC, die temperature (internal temperature sensor channel)
  double lead_ohm = 0.5;           // ohm per force lead; 4-wire sensing makes it irrelevant
  bool reference_lost = false;     // REFIN1 connection broken (reference reads 0 V)
  bool chip_missing = false;       // no chip on the bus: MISO stuck high, DOUT/RDY never low
};

struct Ad7794ModelOptions {
  uint64_t seed = 1;              // noise RNG seed (deterministic runs)
  double noise_scale = 1.0;       // multiplies the rms noise model; 0 = noiseless
  bool ad7795 = false;            // model the 16-bit AD7795 (status bit 3 = 0, 16-bit data)
  // Untrimmed errors, removed by calibration: input-referred offset per channel code (uV) and
  // gain error per gain code (ppm) relative to the factory gain-1 trim.
  std::array<double, 9> offset_error_uv{3.0, -2.0, 4.0, -5.0, 1.5, 2.5, 0.0, 0.0, 3.0};
  std::array<double, 8> gain_error_ppm{0.0, 150.0, -220.0, 310.0, -260.0, 400.0, -350.0, 520.0};
  double reset_guard_s = 500e-6;  // s, serial interface ignored after a reset
};

class Ad7794Model {
 public:
  static constexpr double kNever = std::numeric_limits<double>::infinity();
  // Full-scale register value that means "gain exactly 1" in this model. The real chip's coefficient
  // scaling is not published; its factory value reads 0x5XXXX0, so the model uses 0x500000.
  static constexpr uint32_t kFullScaleNominal = 0x500000;

  struct Counters {
    uint64_t resets = 0;                // by 32 ones, power-on or injected
    uint64_t conversions = 0;           // results placed in the data register
    uint64_t calibrations = 0;          // completed calibrations
    uint64_t ignored_cal_writes = 0;    // offset/full-scale writes outside idle/power-down
    uint64_t access_during_reset = 0;   // bytes clocked within the reset guard time
    uint64_t overwritten_results = 0;   // a result replaced an unread one
    uint64_t invalid_calibrations = 0;  // internal full-scale at gain 128 (not possible)
  };

  explicit Ad7794Model(const Ad7794ModelOptions& options = {});

  // Plant side.
  AnalogFrontEnd& front_end() { return fe_; }
  const AnalogFrontEnd& front_end() const { return fe_; }

  // MCU side (SPI mode 3, one byte per call).
  void set_cs(bool low);
  bool cs_low() const { return cs_low_; }
  uint8_t transfer(uint8_t mosi);
  // DOUT/RDY is low: chip present, CS low, an unread result available.
  bool rdy_low() const;
  // Level of the MISO line as the MCU sees it (pulled up when the chip does not drive it).
  bool miso_high() const { return !rdy_low(); }

  // Time.
  void advance(double seconds);
  double now() const { return now_s_; }
  // Seconds until the next internal event (conversion or calibration end), kNever when idle.
  double time_to_next_event() const;

  // Fault injection and power.
  void power_on_reset();        // power cycle: registers, calibration pairs and interface
  void inject_silent_reset();   // same register effect, e.g. an ESD or supply glitch

  // Inspection (tests, harness diagnostics).
  uint16_t mode_register() const { return mode_; }
  uint16_t config_register() const { return config_; }
  uint8_t io_register() const { return io_; }
  uint8_t status_register() const;
  uint32_t data_register() const { return data_; }
  uint32_t offset_register(int pair) const { return offset_.at(pair); }
  uint32_t full_scale_register(int pair) const { return full_scale_.at(pair); }
  const Counters& counters() const { return counters_; }
  // Current through the probe chain with the present IO register and mode (A).
  double chain_current_a() const;
  // Input-referred rms noise (V) for a gain code and FS code, see the .cpp for its basis.
  static double rms_noise_v(uint8_t gain_code, uint8_t fs);

 private:
  enum class Phase : uint8_t { kComm, kRead, kWrite, kContinuousRead };
  enum class Job : uint8_t { kNone, kConvert, kZeroCal, kFullCal, kSystemZeroCal, kSystemFullCal };

  void reset_registers();
  void apply_write(uint8_t reg, uint32_t value);
  void start_job_for_mode(bool leaving_power_down);
  void complete_job();
  double modulator_output(uint8_t channel, bool internal_zero, bool internal_full, bool* no_ref,
                          bool* over_range);
  double reference_v(uint8_t channel) const;
  double input_v(uint8_t channel, bool* floating_high) const;
  uint32_t register_value(uint8_t reg) const;
  double gaussian();
  uint64_t next_random();

  Ad7794ModelOptions opt_;
  AnalogFrontEnd fe_;
  double now_s_ = 0.0;
  double reset_guard_until_s_ = 0.0;
  bool cs_low_ = false;

  // Registers.
  uint16_t mode_ = 0;
  uint16_t config_ = 0;
  uint8_t io_ = 0;
  uint32_t data_ = 0;
  bool data_unread_ = false;
  bool err_ = false;
  bool noxref_ = false;
  uint8_t last_channel_ = 0;
  std::array<uint32_t, ad7794::kCalPairs> offset_{};
  std::array<uint32_t, ad7794::kCalPairs> full_scale_{};

  // Serial interface.
  Phase phase_ = Phase::kComm;
  uint8_t reg_ = 0;
  uint8_t bytes_left_ = 0;
  uint32_t shift_ = 0;
  int ones_ = 0;
  bool cread_ = false;

  // Running job.
  Job job_ = Job::kNone;
  double job_done_s_ = kNever;

  std::array<uint64_t, 4> rng_{};
  bool have_spare_gauss_ = false;
  double spare_gauss_ = 0.0;
  Counters counters_;
};

}  // namespace btsm::sim

#endif
