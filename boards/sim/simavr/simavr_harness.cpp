#include "boards/sim/simavr/simavr_harness.hpp"

#include <avr_eeprom.h>
#include <avr_ioport.h>
#include <avr_spi.h>
#include <avr_uart.h>
#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_io.h>
#include <sim_irq.h>
#include <sim_cycle_timers.h>
#include <sim_time.h>

#include <cctype>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <fstream>
#include <stdexcept>
#include <string>
#include <unistd.h>

namespace btsm::sim {

namespace {

// simavr prints init chatter on stdout with printf; the btsm CLI keeps stdout for --json data.
class StdoutSilencer {
 public:
  StdoutSilencer() {
    std::fflush(stdout);
    saved_ = dup(STDOUT_FILENO);
    const int devnull = open("/dev/null", O_WRONLY);
    if (devnull >= 0) {
      dup2(devnull, STDOUT_FILENO);
      close(devnull);
    }
  }
  ~StdoutSilencer() {
    std::fflush(stdout);
    if (saved_ >= 0) {
      dup2(saved_, STDOUT_FILENO);
      close(saved_);
    }
  }

 private:
  int saved_ = -1;
};

// Only warnings and errors from the core reach stderr, and without the core's terminal colour
// codes ("\x1b[31m") when stderr is a file or a pipe (a log, a test's capture).
void quiet_logger(avr_t*, const int level, const char* format, va_list ap) {
  if (level > LOG_WARNING) return;
  char text[1024];
  std::vsnprintf(text, sizeof text, format, ap);
  std::string out = "simavr: ";
  const bool colour = ::isatty(STDERR_FILENO) != 0;
  for (const char* c = text; *c != '\0'; ++c) {
    if (!colour && c[0] == '\x1b' && c[1] == '[') {  // skip ESC [ digits/; ... final letter
      c += 2;
      while (*c != '\0' && (std::isdigit(static_cast<unsigned char>(*c)) || *c == ';')) ++c;
      if (*c == '\0') break;
      continue;
    }
    out += *c;
  }
  std::fputs(out.c_str(), stderr);
}

uint8_t* eeprom_memory(avr_t* avr) {
  // Asking with ee = NULL returns a pointer into the EEPROM array (works in every 1.x version,
  // unlike a full-size copy, which some versions reject with an off-by-one bound check).
  avr_eeprom_desc_t d{};
  d.ee = nullptr;
  d.offset = 0;
  d.size = 1;
  avr_ioctl(avr, AVR_IOCTL_EEPROM_GET, &d);  // returns -1 on success in 1.6: not an error
  return d.ee;
}

}  // namespace

// C callbacks; `param` is the harness.
struct HarnessCallbacks {
  static SimavrHarness* self(void* p) { return static_cast<SimavrHarness*>(p); }

  static void sleep_hook(avr_t* avr, avr_cycle_count_t how_long) {
    auto* h = self(avr->custom.data);
    h->sleep_cycles_ += how_long + 1;  // the core adds 1 + how_long after this call
    if (h->on_sleep) h->on_sleep(double(avr->cycle + how_long) / avr->frequency);
  }

  static void spi_output(avr_irq_t*, uint32_t value, void* p) { self(p)->on_spi_byte(uint8_t(value)); }
  static void cs_change(avr_irq_t*, uint32_t value, void* p) { self(p)->on_cs(value != 0); }
  static void uart_output(avr_irq_t*, uint32_t value, void* p) {
    auto* h = self(p);
    h->counters_.uart_tx_bytes++;
    if (h->on_uart_tx) h->on_uart_tx(uint8_t(value));
  }
  static void uart_xon(avr_irq_t*, uint32_t, void* p) {
    auto* h = self(p);
    h->xoff_ = false;
    h->feed_uart();
  }
  static void uart_xoff(avr_irq_t*, uint32_t, void* p) { self(p)->xoff_ = true; }

  static avr_cycle_count_t uart_byte(avr_t* avr, avr_cycle_count_t, void* p) {
    auto* h = self(p);
    if (h->xoff_ || h->rx_queue_.empty()) {
      h->feeding_ = false;
      return 0;
    }
    const uint8_t b = h->rx_queue_.front();
    h->rx_queue_.pop_front();
    // The FIFO refuses the byte when full; XOFF is raised then (or when this byte fills it).
    avr_raise_irq(h->uart_irq_ + UART_IRQ_INPUT, b);
    h->counters_.uart_rx_bytes++;
    const avr_cycle_count_t per_byte = avr->frequency * 10ull / h->opts_.uart_baud;
    return avr->cycle + (per_byte ? per_byte : 1);
  }

  // EECR written (after the EEPROM module's own handler, which performed the write if EEPE was
  // set with EEMPE armed). Counts writes and tears the one chosen for a power cut.
  static void eecr_write(avr_t* avr, avr_io_addr_t, uint8_t v, void* p) {
    auto* h = self(p);
    if (!(v & 0x02) || (v & 0x01)) return;  // EEPE set, EERE clear
    const uint64_t index = h->counters_.eeprom_writes++;
    if (h->cut_armed_ && index >= h->cut_at_write_) {
      const uint16_t addr = uint16_t(avr->data[0x41] | (avr->data[0x42] << 8)) & avr->e2end;
      uint8_t* mem = eeprom_memory(avr);
      if (mem) mem[addr] = h->torn_value_;
      h->cut_armed_ = false;
      h->power_lost_ = true;
    }
  }

  static avr_cycle_count_t stop_marker(avr_t*, avr_cycle_count_t, void*) { return 0; }

  // Every MCU reset -- power cycle, watchdog (the REBOOT command), brown-out -- passes here, from
  // inside avr_reset(), which also drops every cycle timer: the harness's own state is restored one
  // cycle later, before the firmware's first instruction reads a pin.
  static void mcu_reset(avr_t* avr) {
    auto* h = self(avr->custom.data);
    if (h->core_reset_) h->core_reset_(avr);
    avr_cycle_timer_register(avr, 1, &HarnessCallbacks::after_reset, h);
  }
  static avr_cycle_count_t after_reset(avr_t*, avr_cycle_count_t, void* p) {
    self(p)->after_mcu_reset();
    return 0;
  }

  static avr_cycle_count_t device_event(avr_t* avr, avr_cycle_count_t, void* p) {
    auto* h = self(p);
    h->sync_device();
    h->update_miso();
    const double t = h->spi_ ? h->spi_->time_to_next_event() : INFINITY;
    if (!std::isfinite(t)) return 0;
    const double c = std::ceil(t * avr->frequency);
    return avr->cycle + (c < 1.0 ? 1 : avr_cycle_count_t(c));
  }

  static avr_cycle_count_t tach_toggle(avr_t* avr, avr_cycle_count_t, void* p) {
    auto* h = self(p);
    if (!(h->tach_hz_ > 0.0)) {
      h->tach_level_ = false;
      avr_raise_irq(h->tach_irq_, 0);
      h->tach_running_ = false;
      return 0;
    }
    h->tach_level_ = !h->tach_level_;
    avr_raise_irq(h->tach_irq_, h->tach_level_ ? 1 : 0);
    if (h->tach_level_) h->counters_.tach_pulses++;
    const double half = avr->frequency / (2.0 * h->tach_hz_);
    return avr->cycle + (half < 1.0 ? 1 : avr_cycle_count_t(half));
  }

  // Called after the SPI module's own SPDR write handler (handlers on one address run in order
  // of registration). The 1.6 module has just queued its completion timer 100 us ahead; move
  // it to the real byte time.
  static void spdr_write(avr_t* avr, avr_io_addr_t, uint8_t, void* p) {
    auto* h = self(p);
    if (!h->opts_.spi_real_timing) return;
    const avr_cycle_count_t expect = avr->cycle + avr_usec_to_cycles(avr, 100);
    for (avr_cycle_timer_slot_p s = avr->cycle_timers.timer; s; s = s->next) {
      if (s->when != expect || s->param == p) continue;
      const avr_cycle_timer_t fn = s->timer;
      void* const prm = s->param;
      avr_cycle_timer_cancel(avr, fn, prm);
      avr_cycle_timer_register(avr, avr_cycle_count_t(8 * h->opts_.spi_sck_divider), fn, prm);
      return;
    }
  }
};

SimavrHarness::SimavrHarness(const HarnessOptions& opts, SpiPeripheral* spi) : opts_(opts), spi_(spi) {
  if (access(opts_.elf_path.c_str(), R_OK) != 0)
    throw std::runtime_error("simavr: cannot read firmware image " + opts_.elf_path);
  avr_global_logger_set(quiet_logger);
  elf_firmware_t fw;
  std::memset(&fw, 0, sizeof fw);
  {
    StdoutSilencer quiet;
    if (elf_read_firmware(opts_.elf_path.c_str(), &fw) != 0)
      throw std::runtime_error("simavr: " + opts_.elf_path + " is not a loadable AVR ELF image");
    const char* mcu = fw.mmcu[0] ? fw.mmcu : opts_.mcu.c_str();
    avr_ = avr_make_mcu_by_name(mcu);
    if (!avr_) throw std::runtime_error(std::string("simavr: unknown MCU '") + mcu + "'");
    avr_init(avr_);
    avr_load_firmware(avr_, &fw);
  }
  // Without an .mmcu section the ELF names no clock; the core would keep its 1 MHz default.
  avr_->frequency = fw.frequency ? fw.frequency : opts_.f_cpu_hz;
  std::free(fw.flash);
  std::free(fw.eeprom);
  avr_->log = LOG_WARNING;
  if (!opts_.key_record.empty()) {
    if (opts_.key_record_addr + opts_.key_record.size() > avr_->flashend + 1u)
      throw std::runtime_error("simavr: key record does not fit in flash");
    std::memcpy(avr_->flash + opts_.key_record_addr, opts_.key_record.data(), opts_.key_record.size());
  }
  avr_->custom.data = this;
  avr_->sleep = &HarnessCallbacks::sleep_hook;
  attach();
  if (!opts_.eeprom_path.empty()) {
    std::ifstream in(opts_.eeprom_path, std::ios::binary);
    if (in) {
      std::vector<uint8_t> img((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      if (img.size() != size_t(avr_->e2end) + 1)
        throw std::runtime_error("simavr: EEPROM image " + opts_.eeprom_path + " has " +
                                 std::to_string(img.size()) + " bytes, expected " +
                                 std::to_string(avr_->e2end + 1));
      set_eeprom(img);
    }
  }
}

SimavrHarness::~SimavrHarness() {
  if (avr_) {
    avr_terminate(avr_);
    // avr_t and its I/O modules are freed by avr_terminate's deallocation in newer versions;
    // 1.6 leaves the core allocated, which is harmless for the few instances a process makes.
  }
}

void SimavrHarness::attach() {
  spi_irq_ = avr_io_getirq(avr_, AVR_IOCTL_SPI_GETIRQ(0), 0);
  uart_irq_ = avr_io_getirq(avr_, AVR_IOCTL_UART_GETIRQ('0'), 0);
  cs_irq_ = avr_io_getirq(avr_, AVR_IOCTL_IOPORT_GETIRQ(opts_.adc_cs.port), opts_.adc_cs.bit);
  miso_irq_ = avr_io_getirq(avr_, AVR_IOCTL_IOPORT_GETIRQ(opts_.adc_dout_rdy.port), opts_.adc_dout_rdy.bit);
  tach_irq_ = avr_io_getirq(avr_, AVR_IOCTL_IOPORT_GETIRQ(opts_.tach.port), opts_.tach.bit);
  if (!spi_irq_ || !uart_irq_ || !cs_irq_ || !miso_irq_ || !tach_irq_)
    throw std::runtime_error("simavr: the MCU lacks SPI, UART0 or the configured port pins");
  core_reset_ = avr_->reset;
  avr_->reset = &HarnessCallbacks::mcu_reset;
  avr_irq_register_notify(spi_irq_ + SPI_IRQ_OUTPUT, &HarnessCallbacks::spi_output, this);
  avr_irq_register_notify(cs_irq_, &HarnessCallbacks::cs_change, this);
  avr_irq_register_notify(uart_irq_ + UART_IRQ_OUTPUT, &HarnessCallbacks::uart_output, this);
  avr_irq_register_notify(uart_irq_ + UART_IRQ_OUT_XON, &HarnessCallbacks::uart_xon, this);
  avr_irq_register_notify(uart_irq_ + UART_IRQ_OUT_XOFF, &HarnessCallbacks::uart_xoff, this);
  // SPDR is data address 0x4E, EECR 0x3F on the ATmega48/88/168/328 family.
  avr_register_io_write(avr_, 0x4E, &HarnessCallbacks::spdr_write, this);
  avr_register_io_write(avr_, 0x3F, &HarnessCallbacks::eecr_write, this);
  uint32_t flags = 0;
  avr_ioctl(avr_, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
  flags &= ~uint32_t(AVR_UART_FLAG_STDIO);
  avr_ioctl(avr_, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
  // Idle bus: MISO pulled high, tach low.
  avr_raise_irq(miso_irq_, 1);
  // (tach pin left at its reset level 0: raising it here would count as an INT0 event)
  device_cycle_ = avr_->cycle;
}

double SimavrHarness::time_s() const { return double(avr_->cycle) / avr_->frequency; }
uint64_t SimavrHarness::cycle() const { return avr_->cycle; }
uint32_t SimavrHarness::frequency_hz() const { return avr_->frequency; }

HarnessStats SimavrHarness::stats() const {
  HarnessStats s = counters_;
  s.cycles = avr_->cycle;
  s.sleep_cycles = sleep_cycles_;
  return s;
}

const char* SimavrHarness::state_name() const {
  switch (avr_->state) {
    case cpu_Limbo: return "limbo";
    case cpu_Stopped: return "stopped";
    case cpu_Running: return "running";
    case cpu_Sleeping: return "sleeping";
    case cpu_Step: return "step";
    case cpu_StepDone: return "step-done";
    case cpu_Done: return "done (sleep with interrupts off)";
    case cpu_Crashed: return "crashed";
    default: return "unknown";
  }
}

void SimavrHarness::cut_power_at_eeprom_write(uint64_t write_index, uint8_t torn_value) {
  cut_armed_ = true;
  cut_at_write_ = counters_.eeprom_writes + write_index;
  torn_value_ = torn_value;
}

bool SimavrHarness::run_until_cycle(uint64_t target) {
  if (power_lost_) {
    power_lost_ = false;
    power_cycle();
  }
  if (avr_->cycle >= target) return true;
  // A timer at the target bounds the sleep fast-forward, so a sleeping core stops there instead
  // of jumping to its next wake-up source.
  avr_cycle_timer_register(avr_, target - avr_->cycle, &HarnessCallbacks::stop_marker, this);
  bool ok = true;
  while (avr_->cycle < target) {
    const uint32_t pc = avr_->pc;
    const uint64_t cycle0 = avr_->cycle, sleep0 = sleep_cycles_;
    const int st = avr_run(avr_);
    if (profile_) (*profile_)[pc >> 1] += (avr_->cycle - cycle0) - (sleep_cycles_ - sleep0);
    if (st == cpu_Done || st == cpu_Crashed) {
      ok = false;
      break;
    }
    if (power_lost_) break;  // the supply failed: nothing runs until the next call
  }
  avr_cycle_timer_cancel(avr_, &HarnessCallbacks::stop_marker, this);
  return ok;
}

bool SimavrHarness::run_until(double t_s) {
  return run_until_cycle(uint64_t(std::llround(t_s * avr_->frequency)));
}

void SimavrHarness::sync_device() {
  if (!spi_) return;
  if (avr_->cycle > device_cycle_) spi_->advance(double(avr_->cycle - device_cycle_) / avr_->frequency);
  device_cycle_ = avr_->cycle;
}

void SimavrHarness::update_miso() {
  const bool low = cs_low_ && spi_ && spi_->dout_low();
  avr_raise_irq(miso_irq_, low ? 0 : 1);
}

void SimavrHarness::schedule_device_event() {
  if (!spi_) return;
  avr_cycle_timer_cancel(avr_, &HarnessCallbacks::device_event, this);
  const double t = spi_->time_to_next_event();
  if (!std::isfinite(t)) return;
  const double c = std::ceil(t * avr_->frequency);
  avr_cycle_timer_register(avr_, c < 1.0 ? 1 : avr_cycle_count_t(c), &HarnessCallbacks::device_event, this);
}

void SimavrHarness::on_spi_byte(uint8_t mosi) {
  counters_.spi_bytes++;
  uint8_t miso = 0xFF;  // nobody selected: MISO idles high
  if (spi_ && cs_low_) {
    sync_device();
    miso = spi_->transfer(mosi);
  }
  avr_raise_irq(spi_irq_ + SPI_IRQ_INPUT, miso);
  update_miso();
  schedule_device_event();
}

void SimavrHarness::on_cs(bool high) {
  const bool low = !high;
  if (low == cs_low_) return;
  sync_device();
  cs_low_ = low;
  if (spi_) spi_->set_cs(low);
  update_miso();
  schedule_device_event();
}

void SimavrHarness::uart_send(const uint8_t* data, size_t n) {
  rx_queue_.insert(rx_queue_.end(), data, data + n);
  feed_uart();
}

void SimavrHarness::feed_uart() {
  if (feeding_ || xoff_ || rx_queue_.empty()) return;
  feeding_ = true;
  avr_cycle_timer_register(avr_, 1, &HarnessCallbacks::uart_byte, this);
}

void SimavrHarness::set_tach_hz(double hz) {
  tach_hz_ = hz > 0.0 && std::isfinite(hz) ? hz : 0.0;
  if (tach_hz_ > 0.0 && !tach_running_) {
    tach_running_ = true;
    avr_cycle_timer_register(avr_, 1, &HarnessCallbacks::tach_toggle, this);
  }
}

// The supply fails and returns: the MCU resets (after_mcu_reset restores the wiring), SRAM is lost,
// the EEPROM keeps its contents, the AD7794 goes through its own power-on reset, and host bytes in
// flight are lost.
void SimavrHarness::power_cycle() {
  const std::vector<uint8_t> ee = eeprom();
  avr_reset(avr_);
  set_eeprom(ee);
  cs_low_ = false;
  if (spi_) {
    sync_device();
    spi_->power_on_reset();
  }
  device_cycle_ = avr_->cycle;
  rx_queue_.clear();
  counters_.power_cycles++;
}

// After any MCU reset: avr_reset cleared the I/O registers and dropped every cycle timer.
void SimavrHarness::after_mcu_reset() {
  uint32_t flags = 0;
  avr_ioctl(avr_, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
  flags &= ~uint32_t(AVR_UART_FLAG_STDIO);
  avr_ioctl(avr_, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
  xoff_ = false;
  feeding_ = false;
  feed_uart();
  tach_running_ = false;
  tach_level_ = false;
  set_tach_hz(tach_hz_);
  // PINB is 0 again, but the pin IRQ keeps its last value and simavr filters a raise to the same
  // value: re-raising a high DOUT/RDY would leave PINB4 reading 0 -- "conversion ready" -- for
  // ever (every calibration "finished" at once and the firmware re-initialised the chip in a
  // loop). A 0 first makes the real level a change that reaches the port.
  avr_raise_irq(miso_irq_, 0);
  update_miso();
  schedule_device_event();
}

std::vector<uint8_t> SimavrHarness::eeprom() const {
  const uint8_t* mem = eeprom_memory(avr_);
  if (!mem) throw std::runtime_error("simavr: the MCU has no EEPROM");
  return std::vector<uint8_t>(mem, mem + avr_->e2end + 1);
}

void SimavrHarness::set_eeprom(const std::vector<uint8_t>& image) {
  uint8_t* mem = eeprom_memory(avr_);
  if (!mem) throw std::runtime_error("simavr: the MCU has no EEPROM");
  if (image.size() != size_t(avr_->e2end) + 1)
    throw std::invalid_argument("simavr: EEPROM image must have " + std::to_string(avr_->e2end + 1) + " bytes");
  std::memcpy(mem, image.data(), image.size());
}

void SimavrHarness::save_eeprom() const {
  if (opts_.eeprom_path.empty()) return;
  const auto img = eeprom();
  const std::string tmp = opts_.eeprom_path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(img.data()), std::streamsize(img.size()));
    if (!out) throw std::runtime_error("simavr: cannot write EEPROM image " + tmp);
  }
  if (std::rename(tmp.c_str(), opts_.eeprom_path.c_str()) != 0)
    throw std::runtime_error("simavr: cannot replace EEPROM image " + opts_.eeprom_path);
}

uint8_t SimavrHarness::read_data(uint16_t addr) const { return avr_->data[addr]; }

}  // namespace btsm::sim
