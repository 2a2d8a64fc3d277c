#pragma once
// simavr harness: runs the real ATmega328P image (btsm-fw-bluno.elf) in libsimavr 1.6 with the
// simulated board around it.
//
// Wiring (pins default to boards/bluno_beetle's: CS PB2, DOUT/RDY = MISO PB4, tach INT0 PD2):
//  * SPI: the device's reply to each MOSI byte is raised on SPI_IRQ_INPUT from inside the
//    SPI_IRQ_OUTPUT callback (AVR_IOCTL_SPI_GETIRQ(0): the number 0; the 328P's SPI has no name).
//    simavr 1.6 completes every SPI byte after a fixed 100 us (1600 cycles at 16 MHz); with
//    `spi_real_timing` the harness reschedules that completion to 8 x `spi_sck_divider` cycles,
//    as on the real chip, so busy-waiting firmware is not charged 100x too many cycles.
//  * Chip select and DOUT/RDY: the CS port pin IRQ is watched; DOUT/RDY drives the MISO pin IRQ
//    (low = conversion ready) while CS is low, high otherwise. The device's time_to_next_event()
//    is scheduled as a cycle timer, so RDY falls at the simulated conversion end.
//  * Tach: the INT0 pin is toggled by a cycle timer at the requested pulse rate.
//  * UART0: the STDIO flag is cleared (binary data); transmitted bytes go to on_uart_tx; bytes for
//    the firmware are fed at the 115200-baud byte rate while XON, paused on XOFF.
//  * EEPROM: kept across power cycles, and across runs in `eeprom_path` (raw 1024-byte image).
//    The 1.6 EEPROM ioctls return -1 even on success, so their return is ignored.
//  * Sleep: avr->sleep is replaced: no usleep (fast-forward), sleeping cycles are counted (active
//    cycles = total - sleeping), and an optional pacing hook keeps a wall-clock ratio.
#include "boards/sim/simavr/spi_peripheral.hpp"

#include <cstdint>
#include <deque>
#include <functional>
#include <string>
#include <vector>

struct avr_t;
struct avr_irq_t;

namespace btsm::sim {

struct PinRef {
  char port = 'B';  // 'B', 'C', 'D'
  int bit = 0;      // 0..7
};

struct HarnessOptions {
  std::string elf_path;                 // AVR ELF image
  std::string mcu = "atmega328p";       // used when the ELF carries no .mmcu section
  uint32_t f_cpu_hz = 16000000;         // Hz, used when the ELF carries no frequency
  PinRef adc_cs{'B', 2};                // AD7794 chip select (active low)
  PinRef adc_dout_rdy{'B', 4};          // MISO = AD7794 DOUT/RDY
  PinRef tach{'D', 2};                  // INT0
  std::string eeprom_path;              // raw EEPROM image loaded at start, saved on save_eeprom()
  bool spi_real_timing = true;          // SPI byte = 8 x spi_sck_divider cycles (see above)
  int spi_sck_divider = 4;              // fosc/4 (SPR = 0, SPI2X = 0)
  uint32_t uart_baud = 115200;          // byte pacing of the host -> firmware direction
  // Written into flash after loading (e.g. the device key record that production flashes at
  // common/device_key.hpp kFlashAddress); empty = the image as built.
  std::vector<uint8_t> key_record;
  uint32_t key_record_addr = 0x7DC0;    // byte address in flash
};

struct HarnessStats {
  uint64_t cycles = 0;          // total simulated cycles
  uint64_t sleep_cycles = 0;    // cycles spent in SLEEP
  uint64_t spi_bytes = 0;       // bytes clocked on the SPI bus
  uint64_t uart_tx_bytes = 0;   // bytes the firmware sent
  uint64_t uart_rx_bytes = 0;   // bytes delivered to the firmware
  uint64_t uart_rx_dropped = 0; // bytes the firmware's FIFO refused
  uint64_t tach_pulses = 0;     // rising edges on the tach pin
  uint64_t power_cycles = 0;
  uint64_t eeprom_writes = 0;   // EEPROM byte writes started by the firmware (EEPE)
  uint64_t active_cycles() const { return cycles - sleep_cycles; }
};

class SimavrHarness {
 public:
  // Loads the ELF; throws std::runtime_error naming the file on failure. `spi` may be null (no
  // device on the bus: reads return 0xFF... as an absent chip with a pulled-up MISO would).
  SimavrHarness(const HarnessOptions& opts, SpiPeripheral* spi);
  ~SimavrHarness();
  SimavrHarness(const SimavrHarness&) = delete;
  SimavrHarness& operator=(const SimavrHarness&) = delete;

  // Runs instructions until simulated time reaches t_s or the core stops (crash, or sleep with
  // interrupts off). Returns false if the core stopped.
  bool run_until(double t_s);
  // Runs until `cycle`; same return value.
  bool run_until_cycle(uint64_t cycle);
  double time_s() const;
  uint64_t cycle() const;
  uint32_t frequency_hz() const;
  HarnessStats stats() const;
  const char* state_name() const;

  // Power: cut and restore the supply at the current instant (CPU and I/O reset, SRAM contents
  // lost to the reset, EEPROM kept, the SPI device power-on reset too).
  void power_cycle();
  // Power-loss injection: the supply fails during EEPROM byte write number `write_index`
  // (counted from now, 0 = the next one). That cell is torn (gets `torn_value`), the run stops
  // at once (run_until* return true with power_lost() set), and the next run_until* call first
  // restores the power (power_cycle()).
  void cut_power_at_eeprom_write(uint64_t write_index, uint8_t torn_value = 0xFF);
  bool power_lost() const { return power_lost_; }

  // UART.
  std::function<void(uint8_t)> on_uart_tx;
  void uart_send(const uint8_t* data, size_t n);  // queue bytes towards the firmware
  size_t uart_rx_pending() const { return rx_queue_.size(); }

  // Tach: pulses per second on the tach pin (0 = stopped).
  void set_tach_hz(double hz);

  // Called from the sleep hook with the simulated time the core is about to skip to (pacing).
  std::function<void(double sim_time_s)> on_sleep;

  // EEPROM image access (1 KB on the 328P).
  std::vector<uint8_t> eeprom() const;
  void set_eeprom(const std::vector<uint8_t>& image);
  void save_eeprom() const;  // to eeprom_path (no-op if empty); throws on I/O error

  // Cycle profile: while set (and sized flashend/2 + 1), the active cycles of every instruction
  // are added to the entry of its word address (with the cost of an interrupt entry it triggers;
  // sleeping cycles are not counted). Null: no per-instruction bookkeeping.
  void set_profile(std::vector<uint64_t>* cycles_by_word) { profile_ = cycles_by_word; }

  // Debug access for wiring tests.
  uint8_t read_data(uint16_t addr) const;
  avr_t* core() { return avr_; }  // for tests that need the raw simavr core

 private:
  friend struct HarnessCallbacks;
  void attach();
  void sync_device();
  void update_miso();
  void schedule_device_event();
  void on_spi_byte(uint8_t mosi);
  void on_cs(bool high);
  void feed_uart();
  void after_mcu_reset();

  HarnessOptions opts_;
  SpiPeripheral* spi_;
  avr_t* avr_ = nullptr;
  avr_irq_t* spi_irq_ = nullptr;
  avr_irq_t* uart_irq_ = nullptr;
  avr_irq_t* miso_irq_ = nullptr;
  avr_irq_t* tach_irq_ = nullptr;
  avr_irq_t* cs_irq_ = nullptr;
  bool cs_low_ = false;
  uint64_t device_cycle_ = 0;   // cycle up to which the device has been advanced
  bool xoff_ = false;
  bool feeding_ = false;
  std::deque<uint8_t> rx_queue_;
  double tach_hz_ = 0.0;
  bool tach_level_ = false;
  bool tach_running_ = false;
  uint64_t sleep_cycles_ = 0;
  std::vector<uint64_t>* profile_ = nullptr;
  HarnessStats counters_;
  uint64_t spi_raise_when_ = 0;
  std::vector<uint8_t> eeprom_init_;
  bool cut_armed_ = false;
  uint64_t cut_at_write_ = 0;
  uint8_t torn_value_ = 0xFF;
  bool power_lost_ = false;
  void (*core_reset_)(avr_t*) = nullptr;  // the core's own reset hook, chained
};

}  // namespace btsm::sim
