#pragma once
// One byte-stream interface for every way of reaching a module: a serial tty (USB-serial,
// /dev/rfcommN, a pty of the simulated module), a BLE GATT serial profile, an RFCOMM socket.
// The session above sees only bytes; framing and reassembly of 20-byte BLE notifications into
// frames is the frame decoder's job, not the transport's.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

namespace btsm::link {

using Millis = std::chrono::milliseconds;

class Transport {
 public:
  virtual ~Transport() = default;
  Transport() = default;
  Transport(const Transport&) = delete;
  Transport& operator=(const Transport&) = delete;

  // Human-readable name used in every error message ("serial /dev/ttyACM0").
  virtual std::string describe() const = 0;

  // Sends all bytes (split into transport-sized pieces as needed). Throws LinkError.
  virtual void write(std::span<const uint8_t> bytes) = 0;

  // Waits up to `timeout` for data and returns how many bytes were stored (0 = timeout).
  // Throws LinkError(kDeviceGone) when the peer hung up.
  virtual size_t read(std::span<uint8_t> out, Millis timeout) = 0;

  // Closes and opens the same device again (after a reset or a dropped link). Throws LinkError.
  virtual void reopen() = 0;

  // Largest write the peer takes in one piece (20 for a BLE link at the default ATT MTU). The
  // session sizes model chunks so an encoded frame fits one such piece.
  virtual size_t max_write_size() const { return SIZE_MAX; }
};

using TransportPtr = std::unique_ptr<Transport>;

}  // namespace btsm::link
