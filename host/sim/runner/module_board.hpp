#pragma once
// The MCU side of a simulated module, either the natively built firmware core on NativeBoard or
// the real AVR image in simavr. Both drive the same register-level AD7794 model, whose analog
// front end the plant writes. Internal to the runner (SimModule is the public API).
#include "boards/sim/ad7794_model.hpp"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace btsm::sim {

struct BoardStats {
  uint64_t cycles = 0;         // avr: simulated CPU cycles; native: 0
  uint64_t active_cycles = 0;  // avr: cycles not spent in SLEEP
  uint64_t spi_bytes = 0;      // avr only
  uint64_t mcu_resets = 0;     // power cycles + watchdog/software resets seen by the runner
  uint64_t idle_calls = 0;     // native: board.power.idle() calls
};

struct ModuleBoardOptions {
  Ad7794ModelOptions adc;            // seed, noise scale, ...
  std::string elf_path;              // avr only
  std::string eeprom_path;           // raw 1 KB EEPROM image, loaded at start, saved on save
  uint8_t tach_pulses_per_rev = 1;   // pulses per revolution on the tach input
  // avr: provision the public development key (common/device_key.hpp) into the image's key
  // record, as the native board does by default; false = the image as built (often erased).
  bool avr_dev_key = true;
  // Device key record (common/device_key.hpp layout, kRecordSize bytes) to provision instead:
  // avr -> written to flash at kFlashAddress; native -> its device id and key. Empty = none.
  std::vector<uint8_t> key_record;
};

class ModuleBoard {
 public:
  virtual ~ModuleBoard() = default;
  virtual const char* kind() const = 0;          // "native" or "avr"
  virtual double time_s() const = 0;             // simulated time since the run started
  virtual void run_until(double t_s) = 0;        // MCU and ADC advance to t
  virtual AnalogFrontEnd& front_end() = 0;
  virtual void set_spindle_rpm(double rpm) = 0;
  virtual void host_send(const uint8_t* data, size_t n) = 0;
  virtual void take_output(std::vector<uint8_t>& out) = 0;  // appends what the firmware sent
  virtual void power_cycle() = 0;                // supply cut and restored now
  virtual void save_eeprom() = 0;                // to eeprom_path, if any
  virtual std::vector<uint8_t> eeprom() = 0;
  virtual BoardStats stats() const = 0;
};

// Throws std::runtime_error when the board cannot be built (no ELF).
std::unique_ptr<ModuleBoard> make_native_board(const ModuleBoardOptions& opts);
std::unique_ptr<ModuleBoard> make_avr_board(const ModuleBoardOptions& opts);

// Raw EEPROM image helpers shared by both boards.
std::vector<uint8_t> load_eeprom_image(const std::string& path, size_t size);  // empty if no file

// Why `path` is no AVR firmware image simavr can run ("" when it is one): missing, a directory, not
// an ELF file (a .hex), an ELF for another machine, or cut short (program headers or segments
// past the end of the file). simavr loads whatever it is given and the core then "crashes" at its
// first instruction, which names nothing.
std::string avr_elf_problem(const std::string& path);
void save_eeprom_image(const std::string& path, const std::vector<uint8_t>& image);

}  // namespace btsm::sim
