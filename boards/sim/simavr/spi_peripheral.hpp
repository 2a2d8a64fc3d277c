#pragma once
// What the simavr harness needs from a device on the SPI bus (the AD7794 model in practice; tests
// use small fakes). Host code, so a virtual interface is fine here; the adapter below wraps any
// model with the contract's method names (boards/sim/ad7794_model.hpp) without changing it.
#include <cstdint>

namespace btsm::sim {

class SpiPeripheral {
 public:
  virtual ~SpiPeripheral() = default;
  virtual void set_cs(bool low) = 0;                // chip select level (true = selected)
  virtual uint8_t transfer(uint8_t mosi) = 0;       // one full-duplex byte while selected
  virtual bool dout_low() = 0;                      // DOUT/RDY (MISO) level is low while selected
  virtual void advance(double seconds) = 0;         // simulated time passes
  virtual double time_to_next_event() = 0;          // s until DOUT/RDY may change; inf = never
  virtual void power_on_reset() {}                  // supply cut: back to power-on state
};

// Wraps a model with set_cs / transfer / rdy_low / advance / time_to_next_event.
template <class Model>
class SpiModelAdapter final : public SpiPeripheral {
 public:
  explicit SpiModelAdapter(Model& m) : m_(m) {}
  void set_cs(bool low) override { m_.set_cs(low); }
  uint8_t transfer(uint8_t mosi) override { return m_.transfer(mosi); }
  bool dout_low() override { return m_.rdy_low(); }
  void advance(double s) override { m_.advance(s); }
  double time_to_next_event() override { return m_.time_to_next_event(); }
  void power_on_reset() override { m_.power_on_reset(); }

 private:
  Model& m_;
};

}  // namespace btsm::sim
