// The real AVR image in simavr with the AD7794 model on its SPI bus.
#include "host/sim/runner/module_board.hpp"
#include "boards/sim/simavr/simavr_harness.hpp"
#include "common/device_key.hpp"

#include <fstream>
#include <stdexcept>

namespace btsm::sim {
namespace {

class AvrModuleBoard final : public ModuleBoard {
 public:
  explicit AvrModuleBoard(const ModuleBoardOptions& o) : opts_(o), adc_(o.adc), bus_(adc_) {
    HarnessOptions h;
    h.elf_path = o.elf_path;
    h.eeprom_path = o.eeprom_path;
    if (!o.key_record.empty()) {
      if (o.key_record.size() != device_key::kRecordSize || !device_key::record_valid(o.key_record.data()))
        throw std::invalid_argument("avr board: key record must be a valid 64-byte device key record");
      h.key_record = o.key_record;
      h.key_record_addr = device_key::kFlashAddress;
    } else if (o.avr_dev_key) {
      uint8_t key[device_key::kKeySize];
      for (uint8_t i = 0; i < device_key::kKeySize; ++i) key[i] = device_key::dev_key_byte(i);
      h.key_record.assign(device_key::kRecordSize, 0xFF);
      device_key::build_record(h.key_record.data(), 0x0000DE70, key);
      h.key_record_addr = device_key::kFlashAddress;
    }
    harness_ = std::make_unique<SimavrHarness>(h, &bus_);
    harness_->on_uart_tx = [this](uint8_t b) { out_.push_back(b); };
  }
  const char* kind() const override { return "avr"; }
  double time_s() const override { return harness_->time_s(); }
  void run_until(double t_s) override {
    if (!harness_->run_until(t_s))
      throw std::runtime_error(std::string("simavr: the AVR core stopped (") + harness_->state_name() +
                               ") at t = " + std::to_string(harness_->time_s()) + " s");
  }
  AnalogFrontEnd& front_end() override { return adc_.front_end(); }
  void set_spindle_rpm(double rpm) override { harness_->set_tach_hz(rpm / 60.0 * opts_.tach_pulses_per_rev); }
  void host_send(const uint8_t* d, size_t n) override { harness_->uart_send(d, n); }
  void take_output(std::vector<uint8_t>& out) override {
    out.insert(out.end(), out_.begin(), out_.end());
    out_.clear();
  }
  void power_cycle() override { harness_->power_cycle(); }
  void save_eeprom() override { harness_->save_eeprom(); }
  std::vector<uint8_t> eeprom() override { return harness_->eeprom(); }
  BoardStats stats() const override {
    const HarnessStats h = harness_->stats();
    BoardStats s;
    s.cycles = h.cycles;
    s.active_cycles = h.active_cycles();
    s.spi_bytes = h.spi_bytes;
    s.mcu_resets = h.power_cycles;
    return s;
  }
  SimavrHarness& harness() { return *harness_; }

 private:
  ModuleBoardOptions opts_;
  Ad7794Model adc_;
  SpiModelAdapter<Ad7794Model> bus_;  // the AD7794 model on the image's SPI pins
  std::unique_ptr<SimavrHarness> harness_;
  std::vector<uint8_t> out_;
};

}  // namespace

std::unique_ptr<ModuleBoard> make_avr_board(const ModuleBoardOptions& opts) {
  if (opts.elf_path.empty()) throw std::runtime_error("avr board: no firmware image given (--elf)");
  return std::make_unique<AvrModuleBoard>(opts);
}

std::vector<uint8_t> load_eeprom_image(const std::string& path, size_t size) {
  if (path.empty()) return {};
  std::ifstream in(path, std::ios::binary);
  if (!in) return {};
  std::vector<uint8_t> img((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (img.size() != size)
    throw std::runtime_error("EEPROM image " + path + " has " + std::to_string(img.size()) +
                             " bytes, expected " + std::to_string(size));
  return img;
}

void save_eeprom_image(const std::string& path, const std::vector<uint8_t>& image) {
  if (path.empty()) return;
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(image.data()), std::streamsize(image.size()));
    if (!out) throw std::runtime_error("cannot write EEPROM image " + tmp);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    throw std::runtime_error("cannot replace EEPROM image " + path);
}

}  // namespace btsm::sim
