#pragma once
// In-process fake BLE peripheral: a real GATT database (handles, declarations, CCCDs) served
// over one end of socketpair(AF_UNIX, SOCK_SEQPACKET) with the same ATT codecs the client uses.
// Discovery ends with "attribute not found" error responses as on a real device. Optionally
// bridges its serial characteristic to a byte stream fd (e.g. a fake module): writes go to the
// fd, bytes from the fd come back as notifications of at most MTU-3 bytes.
#include "host/link/att_pdu.hpp"

#include <atomic>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace btsm::test {

namespace att = btsm::link::att;

class FakePeripheral {
 public:
  struct Attribute {
    uint16_t handle = 0;
    att::Uuid type;
    att::Bytes value;
    bool is_cccd = false;
    uint16_t owner_value_handle = 0;  // for CCCDs: the characteristic they configure
  };
  struct Write {
    uint8_t opcode;
    uint16_t handle;
    att::Bytes value;
  };

  FakePeripheral() = default;
  ~FakePeripheral();

  // Database building (before start()).
  void add_service(const att::Uuid& uuid);
  uint16_t add_characteristic(const att::Uuid& uuid, uint8_t properties, att::Bytes value = {});
  void set_server_mtu(uint16_t mtu) { server_mtu_ = mtu; }
  // Bytes written to `write_handle` go to stream_fd; bytes read from stream_fd are notified
  // from `notify_handle`. Takes ownership of stream_fd.
  void bridge(uint16_t write_handle, uint16_t notify_handle, int stream_fd);

  // Serves on fd (takes ownership) in a thread.
  void start(int fd);
  void stop();
  // Drops the link: stops serving and closes the bearer.
  void disconnect();

  // Sends a notification now if the client enabled it (thread-safe). Returns false otherwise.
  bool notify(uint16_t value_handle, const att::Bytes& value);
  bool notifications_enabled(uint16_t value_handle) const;
  std::vector<Write> writes() const;
  uint16_t mtu() const { return mtu_; }
  size_t requests_served() const { return requests_; }

  // Typical databases. Each returns the serial value handle through `serial` and, for Bluno,
  // the command handle through `command`.
  static void make_bluno(FakePeripheral& p, uint16_t& serial, uint16_t& command, const std::string& model = "DF Bluno");
  static void make_nus(FakePeripheral& p, uint16_t& rx_write, uint16_t& tx_notify);
  static void make_hm10(FakePeripheral& p, uint16_t& serial);

 private:
  void run();
  att::Pdu handle(const att::Pdu& req);
  void send(const att::Pdu& pdu);
  void close_services();

  struct Service {
    uint16_t start, end;
    att::Uuid uuid;
  };
  std::vector<Attribute> attrs_;
  std::vector<Service> services_;
  uint16_t next_handle_ = 1;
  uint16_t server_mtu_ = 23;
  std::atomic<uint16_t> mtu_{23};
  int fd_ = -1;
  int stream_fd_ = -1;
  uint16_t bridged_handle_ = 0;
  uint16_t notify_handle_ = 0;
  std::thread thread_;
  std::atomic<bool> running_{false};
  mutable std::mutex mu_;
  std::vector<Write> writes_;
  std::atomic<size_t> requests_{0};
};

}  // namespace btsm::test
