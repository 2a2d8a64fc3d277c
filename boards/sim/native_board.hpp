// Native simulated board: implements the hal/contracts.hpp Board contract on the host so the
// firmware core (firmware/app.hpp) runs unchanged against the register-level AD7794 model.
//
// Simulated time is explicit (microseconds since power-on) and only moves when the owner calls
// advance_us()/advance_to_next_event(); nothing here sleeps or reads the wall clock, so a test or
// the spindle simulation runs as fast as the CPU allows. Typical loop (see run_until_us()):
//
//   btsm::sim::NativeBoard board;
//   btsm::App<btsm::sim::NativeBoard> app(board);
//   app.init();
//   board.run_until_us(app, 60'000'000);         // one simulated minute
//   auto bytes = board.host_receive();            // frames the firmware sent
//
// Peripherals:
//  - spi      -> Ad7794Model (CS, bytes, DOUT/RDY on MISO)
//  - serial   -> two byte queues with UART timing (115200 8N1 = 86.8 us per byte) and the AVR ring
//               buffer capacities, so back-pressure and RX overruns behave like the real board
//  - clock    -> simulated time
//  - storage  -> 1 KB RAM "EEPROM" with 3.4 ms write time and a power-cut hook at any write index
//  - watchdog -> fires when not kicked for its timeout; reported via mcu_reset_pending()
//  - power    -> idle() is counted; reboot() is reported via mcu_reset_pending()
//  - tach     -> the spindle speed the plant sets, quantised like the AVR period measurement
//  - identity -> device key record (common/device_key.hpp), development key by default
#ifndef BTSM_BOARDS_SIM_NATIVE_BOARD_HPP
#define BTSM_BOARDS_SIM_NATIVE_BOARD_HPP

#include <array>
#include <cstdint>
#include <deque>
#include <optional>
#include <vector>

#include "boards/sim/ad7794_model.hpp"

namespace btsm::sim {

struct NativeBoardOptions {
  Ad7794ModelOptions adc;              // AD7794 model options (seed, noise, ...)
  uint32_t uart_baud = 115200;         // bit/s, 10 bits per byte; 0 = bytes move instantly
  uint16_t rx_buffer_bytes = 47;       // firmware receive ring capacity (AVR board: 48-slot ring)
  uint16_t tx_buffer_bytes = 71;       // firmware transmit ring capacity (AVR board: 72-slot ring)
  uint32_t eeprom_write_us = 3400;     // us per EEPROM byte write (ATmega328P datasheet: 3.3 ms)
  uint32_t watchdog_timeout_ms = 2000; // ms (AVR board uses WDTO_2S)
  uint32_t device_id = 0x0000DE70;     // reported in INFO
  std::optional<std::array<uint8_t, 32>> key;  // HMAC key; nullopt = development key 00..1F
  bool erased_key = false;             // true: the key record is all 0xFF (no key, as built)
  uint64_t entropy_seed = 0x5EED;      // seeds entropy_bits()
};

class NativeBoard {
 public:
  static constexpr uint16_t kEepromSize = 1024;

  explicit NativeBoard(const NativeBoardOptions& options = {});
  NativeBoard(const NativeBoard&) = delete;
  NativeBoard& operator=(const NativeBoard&) = delete;

  // ---- hal contract (used by the firmware) -------------------------------------------------
  struct Spi {
    NativeBoard* b;
    void select() { b->adc_.set_cs(true); }
    void deselect() { b->adc_.set_cs(false); }
    uint8_t transfer(uint8_t mosi) { return b->adc_.transfer(mosi); }
    bool miso_high() { return b->adc_.miso_high(); }
  };
  struct Serial {
    NativeBoard* b;
    bool read(uint8_t& byte);
    uint8_t* tx_claim(uint8_t& n);
    void tx_commit(uint8_t n);
  };
  struct Clock {
    NativeBoard* b;
    uint32_t millis() { return static_cast<uint32_t>(b->now_us_ / 1000); }
  };
  struct Storage {
    NativeBoard* b;
    uint16_t size() { return kEepromSize; }
    uint8_t read(uint16_t addr) { return b->eeprom_[addr % kEepromSize]; }
    bool busy() { return b->now_us_ < b->eeprom_busy_until_us_; }
    void write(uint16_t addr, uint8_t value);
  };
  struct Watchdog {
    NativeBoard* b;
    void enable();
    void kick() { b->last_kick_us_ = b->now_us_; }
    bool caused_last_reset() { return b->last_reset_by_watchdog_; }
  };
  struct Power {
    NativeBoard* b;
    void idle() { ++b->idle_calls_; }
    void reboot() { b->reset_pending_ = ResetCause::kSoftware; }
    uint8_t reset_flags() { return b->last_reset_by_watchdog_ ? 0x08 : (b->first_boot_ ? 0x01 : 0x00); }
  };
  struct Tach {
    NativeBoard* b;
    void set_pulses_per_rev(uint8_t n) { b->pulses_per_rev_ = n ? n : 1; }
    uint16_t rpm();
  };
  struct Identity {
    NativeBoard* b;
    void read_key_record(uint8_t* out, uint16_t n);
    uint16_t entropy_bits();
  };

  Spi spi{this};
  Serial serial{this};
  Clock clock{this};
  Storage storage{this};
  Watchdog watchdog{this};
  Power power{this};
  Tach tach{this};
  Identity identity{this};

  // ---- simulation side (plant, harness, tests) ---------------------------------------------
  Ad7794Model& adc() { return adc_; }
  AnalogFrontEnd& front_end() { return adc_.front_end(); }

  uint64_t now_us() const { return now_us_; }
  // Moves simulated time forward, delivering UART bytes, EEPROM completion, ADC events and the
  // watchdog on the way.
  void advance_us(uint64_t dt_us);
  // Microseconds until the next internal event (ADC conversion end, UART byte, EEPROM write end,
  // watchdog expiry); UINT64_MAX when nothing is scheduled.
  uint64_t us_to_next_event() const;
  // Advances to the next internal event, but at most max_us (and at least 1 us).
  void advance_to_next_event(uint64_t max_us);

  // Runs `app.poll()` and sleeps between polls until t_end_us or until an MCU reset is pending
  // (watchdog, reboot command, power cut). Uses app.idle_budget_ms() as the longest sleep, so
  // ADC RDY, received bytes and timers wake the firmware exactly when they would on hardware.
  // A harness that owns the App recreates it after mcu_reset().
  template <class AppT>
  void run_until_us(AppT& app, uint64_t t_end_us) {
    while (now_us_ < t_end_us && !reset_pending()) {
      app.poll();
      const uint64_t budget_us = static_cast<uint64_t>(app.idle_budget_ms()) * 1000;
      if (budget_us == 0 && ++busy_polls_ < kMaxBusyPolls) continue;
      busy_polls_ = 0;
      power.idle();
      uint64_t limit = t_end_us - now_us_;
      if (budget_us > 0 && budget_us < limit) limit = budget_us;
      advance_to_next_event(limit);
    }
  }

  // Host side of the UART: bytes towards the firmware (delivered at the baud rate) and bytes the
  // firmware has sent (everything that finished transmission so far).
  void host_send(const uint8_t* data, size_t n);
  void host_send(const std::vector<uint8_t>& data) { host_send(data.data(), data.size()); }
  std::vector<uint8_t> host_receive();
  uint64_t rx_overruns() const { return rx_overruns_; }

  // Spindle: speed seen by the tachometer input.
  void set_spindle_rpm(double rpm) { spindle_rpm_ = rpm; }

  // EEPROM access for tests, and the power-cut hook: the write with zero-based index
  // `write_index` (counted from now) is torn (the cell gets `torn_value`) and every later write is
  // lost; reset_pending() then reports kPowerLoss.
  std::vector<uint8_t>& eeprom() { return eeprom_; }
  void cut_power_at_write(uint64_t write_index, uint8_t torn_value = 0xFF);
  uint64_t eeprom_writes() const { return eeprom_writes_; }

  enum class ResetCause : uint8_t { kNone, kWatchdog, kSoftware, kPowerLoss };
  bool reset_pending() const { return reset_pending_ != ResetCause::kNone; }
  ResetCause pending_reset_cause() const { return reset_pending_; }
  // Performs the MCU reset: UART rings cleared, watchdog off, power restored (EEPROM content
  // kept, the AD7794 keeps its state unless power was lost). Create a new App afterwards.
  void mcu_reset();
  uint64_t watchdog_resets() const { return watchdog_resets_; }
  uint64_t idle_calls() const { return idle_calls_; }

 private:
  static constexpr int kMaxBusyPolls = 100000;
  uint64_t byte_time_us() const;
  void sync_adc();

  NativeBoardOptions opt_;
  Ad7794Model adc_;
  uint64_t now_us_ = 0;

  std::deque<uint8_t> rx_wire_;   // host -> firmware, not yet received
  std::deque<uint8_t> rx_ring_;   // received, waiting for serial.read()
  std::deque<uint8_t> tx_ring_;   // firmware -> host, waiting for the transmitter
  std::vector<uint8_t> tx_claimed_;  // Serial::tx_claim() space, moved to tx_ring_ by tx_commit()
  std::vector<uint8_t> tx_done_;  // transmitted, waiting for host_receive()
  uint64_t next_rx_us_ = 0;
  uint64_t next_tx_us_ = 0;
  uint64_t rx_overruns_ = 0;

  std::vector<uint8_t> eeprom_;
  uint64_t eeprom_busy_until_us_ = 0;
  uint64_t eeprom_writes_ = 0;
  std::optional<uint64_t> cut_at_write_;
  uint8_t torn_value_ = 0xFF;
  bool powered_ = true;

  bool watchdog_enabled_ = false;
  uint64_t last_kick_us_ = 0;
  bool last_reset_by_watchdog_ = false;
  bool first_boot_ = true;
  uint64_t watchdog_resets_ = 0;
  ResetCause reset_pending_ = ResetCause::kNone;

  double spindle_rpm_ = 0.0;
  uint8_t pulses_per_rev_ = 1;
  std::array<uint8_t, 64> key_record_{};
  uint64_t entropy_state_ = 0;
  uint64_t idle_calls_ = 0;
  int busy_polls_ = 0;
};

}  // namespace btsm::sim

#endif
