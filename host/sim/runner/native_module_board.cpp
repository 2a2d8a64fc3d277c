// The natively built firmware core (firmware::App<NativeBoard>) against the simulated board.
#include "host/sim/runner/module_board.hpp"

#include <stdexcept>

#include "boards/sim/native_board.hpp"
#include "firmware/app.hpp"
#include "common/device_key.hpp"

#include <cmath>

namespace btsm::sim {
namespace {

class NativeModuleBoard final : public ModuleBoard {
 public:
  explicit NativeModuleBoard(const ModuleBoardOptions& o) : opts_(o), board_(board_options(o)) {
    const auto img = load_eeprom_image(o.eeprom_path, NativeBoard::kEepromSize);
    if (!img.empty()) board_.eeprom() = img;
    boot();
  }
  const char* kind() const override { return "native"; }
  double time_s() const override { return double(board_.now_us()) * 1e-6; }
  void run_until(double t_s) override {
    const uint64_t end_us = uint64_t(std::llround(t_s * 1e6));
    while (board_.now_us() < end_us) {
      board_.run_until_us(*app_, end_us);
      if (board_.reset_pending()) {
        // Watchdog, REBOOT command or an injected power cut: the MCU restarts, the App is new.
        board_.mcu_reset();
        ++resets_;
        boot();
      }
    }
  }
  AnalogFrontEnd& front_end() override { return board_.front_end(); }
  void set_spindle_rpm(double rpm) override { board_.set_spindle_rpm(rpm); }
  void host_send(const uint8_t* d, size_t n) override { board_.host_send(d, n); }
  void take_output(std::vector<uint8_t>& out) override {
    const auto b = board_.host_receive();
    out.insert(out.end(), b.begin(), b.end());
  }
  void power_cycle() override {
    // Supply cut and restored now: the MCU and the ADC restart from power-on (the AD7794 shares
    // the supply); EEPROM keeps what was written. (Cuts in the middle of an EEPROM write are
    // NativeBoard::cut_power_at_write's job, used by the power-loss tests.)
    board_.mcu_reset();
    board_.adc().power_on_reset();
    ++resets_;
    boot();
  }
  void save_eeprom() override { save_eeprom_image(opts_.eeprom_path, board_.eeprom()); }
  std::vector<uint8_t> eeprom() override { return board_.eeprom(); }
  BoardStats stats() const override {
    BoardStats s;
    s.mcu_resets = resets_;
    s.idle_calls = board_.idle_calls();
    return s;
  }

 private:
  static NativeBoardOptions board_options(const ModuleBoardOptions& o) {
    NativeBoardOptions b;
    b.adc = o.adc;
    if (!o.key_record.empty()) {
      if (o.key_record.size() != device_key::kRecordSize || !device_key::record_valid(o.key_record.data()))
        throw std::invalid_argument("native board: key record must be a valid 64-byte device key record");
      b.device_id = get_le32(o.key_record.data() + device_key::kOffsetDeviceId);
      std::array<uint8_t, 32> key{};
      for (size_t i = 0; i < key.size(); ++i) key[i] = o.key_record[device_key::kOffsetKey + i];
      b.key = key;
    }
    return b;
  }
  void boot() {
    app_ = std::make_unique<App<NativeBoard>>(board_);
    board_.tach.set_pulses_per_rev(opts_.tach_pulses_per_rev);
    app_->init();
  }

  ModuleBoardOptions opts_;
  NativeBoard board_;
  std::unique_ptr<App<NativeBoard>> app_;
  uint64_t resets_ = 0;
};

}  // namespace

std::unique_ptr<ModuleBoard> make_native_board(const ModuleBoardOptions& opts) {
  return std::make_unique<NativeModuleBoard>(opts);
}

}  // namespace btsm::sim

