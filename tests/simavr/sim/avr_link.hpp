#pragma once
// Test helper: the real BTSM image in simavr with the AD7794 model as a host link
// (send / step / capture, see tests/hil/sim/model_upload.hpp).
#include "boards/sim/ad7794_model.hpp"
#include "boards/sim/simavr/simavr_harness.hpp"
#include "common/device_key.hpp"
#include "tests/hil/sim/wire_capture.hpp"

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>

namespace btsm::test {

// The firmware image: $BTSM_FW_ELF, else the host build's bin/ (ExternalProject output).
inline std::string firmware_elf() {
  if (const char* e = std::getenv("BTSM_FW_ELF")) return e;
  return std::string(BTSM_BIN_DIR) + "/btsm-fw-bluno.elf";
}

inline std::vector<uint8_t> dev_key_record() {
  uint8_t key[device_key::kKeySize];
  for (uint8_t i = 0; i < device_key::kKeySize; ++i) key[i] = device_key::dev_key_byte(i);
  std::vector<uint8_t> rec(device_key::kRecordSize, 0xFF);
  device_key::build_record(rec.data(), 0x0000DE70, key);
  return rec;
}

struct AvrLink {
  AvrLink() : bus(adc) {
    sim::HarnessOptions o;
    o.elf_path = firmware_elf();
    o.key_record = dev_key_record();
    o.key_record_addr = device_key::kFlashAddress;
    h = std::make_unique<sim::SimavrHarness>(o, &bus);
    h->on_uart_tx = [this](uint8_t b) { rx.push_back(b); };
  }
  void send(const std::vector<uint8_t>& b) { h->uart_send(b.data(), b.size()); }
  void step(double s) {
    if (h->power_lost()) return;  // dark until reboot()
    h->run_until(h->time_s() + s);
    cap.feed(rx);
    rx.clear();
  }
  Capture& capture() { return cap; }
  void reboot() {  // power restored (after a cut) or cycled
    if (!h->power_lost()) h->power_cycle();
    h->run_until(h->time_s());  // restores the power after a cut
    rx.clear();
    cap = Capture();
  }

  sim::Ad7794Model adc;
  sim::SpiModelAdapter<sim::Ad7794Model> bus;
  std::unique_ptr<sim::SimavrHarness> h;
  std::vector<uint8_t> rx;
  Capture cap;
};

}  // namespace btsm::test
