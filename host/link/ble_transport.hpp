#pragma once
// BLE serial transport: a GATT client on an ATT bearer, a serial profile chosen from the
// discovered database, notifications collected into a byte stream, writes split to MTU-3.
// GattSerialTransport works on any connected SOCK_SEQPACKET ATT bearer (tests pass a
// socketpair); BleTransport connects an L2CAP LE socket on the ATT fixed channel (no D-Bus).
#include "host/link/ble_profile.hpp"

#include <deque>
#include <functional>

namespace btsm::link {

struct GattSerialOptions {
  uint16_t requested_mtu = 247;   // bytes; the peer may answer less (CC2540: 23)
  Millis att_timeout{5000};       // per ATT request
  BlunoSetup bluno;               // AT password and UART baud of a Bluno
};

class GattSerialTransport : public Transport {
 public:
  // `connect` returns a connected ATT bearer fd (ownership passes to the transport); it is
  // called again by reopen(). Connects, discovers and sets the profile up; throws LinkError.
  GattSerialTransport(std::function<int()> connect, std::string name, GattSerialOptions opts = {});
  ~GattSerialTransport() override;

  std::string describe() const override { return name_; }
  void write(std::span<const uint8_t> bytes) override;
  size_t read(std::span<uint8_t> out, Millis timeout) override;
  void reopen() override;
  size_t max_write_size() const override;

  const BleSerialProfile& profile() const { return profile_; }
  const GattDatabase& database() const { return db_; }
  uint16_t mtu() const;

 private:
  void open();
  void close();

  std::function<int()> connect_;
  std::string name_;
  GattSerialOptions opts_;
  int fd_ = -1;
  std::unique_ptr<GattClient> client_;
  GattDatabase db_;
  BleSerialProfile profile_;
  std::deque<uint8_t> rx_;
};

enum class BleAddressType { kPublic, kRandom };

// "AA:BB:CC:DD:EE:FF" or "AA:BB:CC:DD:EE:FF/random". Throws LinkError on a malformed address.
struct BleAddress {
  std::string address;
  BleAddressType type = BleAddressType::kPublic;
};
BleAddress parse_ble_address(const std::string& text);

// Connects an L2CAP LE socket to the ATT channel of `addr` (security level low: the Bluno is
// not paired). Returns the fd; throws LinkError with a hint (no adapter, out of range, ...).
int connect_le_att(const BleAddress& addr, Millis timeout);

// Opens a BLE serial link to a module.
std::unique_ptr<GattSerialTransport> open_ble(const std::string& address_text, Millis timeout,
                                              GattSerialOptions opts = {});

}  // namespace btsm::link
