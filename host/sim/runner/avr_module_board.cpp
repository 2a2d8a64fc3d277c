// The real AVR image in simavr with the AD7794 model on its SPI bus.
#include "host/sim/runner/module_board.hpp"
#include "boards/sim/simavr/simavr_harness.hpp"
#include "common/device_key.hpp"
#include "host/io/input_error.hpp"
#include "host/io/input_file.hpp"
#include "host/io/output_file.hpp"

#include <filesystem>
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
  std::error_code ec;
  if (path.empty() || !std::filesystem::exists(path, ec)) return {};  // a new module: blank EEPROM, saved at the end
  // Capped, and refusing directories and devices: /dev/zero was read for ever (1 GB in 8 s).
  const std::string bytes = io::read_input_file(path, size, "module EEPROM image (--eeprom)", io::FileKind::Binary);
  if (bytes.size() != size)
    throw io::InputError("--eeprom " + path + ": " + std::to_string(bytes.size()) + " bytes, an EEPROM image has " +
                         std::to_string(size) + " (give a file this simulator saved, or a new name)");
  return std::vector<uint8_t>(bytes.begin(), bytes.end());
}

std::string avr_elf_problem(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return "no such firmware image (build it, or pass --elf)";
  if (!std::filesystem::is_regular_file(path, ec)) return "not a regular file";
  std::string bytes;
  try {
    bytes = io::read_input_file(path, 8u << 20, "firmware image", io::FileKind::Binary);
  } catch (const std::exception& e) {
    return e.what();
  }
  const auto u8 = [&](std::size_t at) { return static_cast<uint32_t>(static_cast<unsigned char>(bytes[at])); };
  const auto u16 = [&](std::size_t at) { return u8(at) | (u8(at + 1) << 8); };
  const auto u32 = [&](std::size_t at) { return u16(at) | (u16(at + 2) << 16); };
  // ELF32 little-endian header: magic, class 1, data 1; e_machine at 18 (EM_AVR = 83), e_phoff at
  // 28, e_phentsize at 42, e_phnum at 44. Program header: p_offset at 4, p_filesz at 16.
  if (bytes.size() < 4 || bytes.compare(0, 4, "\x7f" "ELF") != 0) return "not an ELF file (give the firmware's .elf, not its .hex)";
  if (bytes.size() < 52) return "an ELF file cut short (" + std::to_string(bytes.size()) + " bytes, no complete header)";
  if (u8(4) != 1 || u8(5) != 1 || u16(18) != 83)
    return "an ELF file for another machine (e_machine " + std::to_string(u16(18)) + "), not an AVR image";
  const std::uint64_t phoff = u32(28), phentsize = u16(42), phnum = u16(44);
  if (phnum == 0 || phentsize < 32 || phoff + phnum * phentsize > bytes.size())
    return "an ELF file cut short or without program segments (nothing simavr could load)";
  for (std::uint64_t i = 0; i < phnum; ++i) {
    const std::size_t ph = static_cast<std::size_t>(phoff + i * phentsize);
    if (static_cast<std::uint64_t>(u32(ph + 4)) + u32(ph + 16) > bytes.size())
      return "an ELF file cut short (segment " + std::to_string(i) + " ends past the end of the file)";
  }
  // simavr finds the flash image through the section headers (e_shoff at 32, e_shentsize at 46,
  // e_shnum at 48; a section's sh_type at 4, sh_offset at 16, sh_size at 20; NOBITS = 8 has none).
  const std::uint64_t shoff = u32(32), shentsize = u16(46), shnum = u16(48);
  if (shnum == 0 || shentsize < 40 || shoff + shnum * shentsize > bytes.size())
    return "an ELF file with its section headers missing or past the end of the file";
  for (std::uint64_t i = 0; i < shnum; ++i) {
    const std::size_t sh = static_cast<std::size_t>(shoff + i * shentsize);
    if (u32(sh + 4) != 8 && static_cast<std::uint64_t>(u32(sh + 16)) + u32(sh + 20) > bytes.size())
      return "an ELF file cut short (section " + std::to_string(i) + " ends past the end of the file)";
  }
  return {};
}

void save_eeprom_image(const std::string& path, const std::vector<uint8_t>& image) {
  if (path.empty()) return;
  io::write_output_file(path, std::string_view(reinterpret_cast<const char*>(image.data()), image.size()), "module EEPROM image");
}

}  // namespace btsm::sim
