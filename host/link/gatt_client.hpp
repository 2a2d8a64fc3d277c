#pragma once
// GATT client over an ATT bearer given as a connected SOCK_SEQPACKET descriptor (one PDU per
// datagram): an L2CAP LE socket on the ATT fixed channel in production, one end of a
// socketpair(AF_UNIX, SOCK_SEQPACKET) with the fake peripheral in tests. Synchronous and
// single-threaded: a request waits for its response; notifications that arrive meanwhile are
// routed to the handler in arrival order, and unexpected peer requests get "request not
// supported" so the peer is never left waiting.
#include "host/link/att_pdu.hpp"
#include "host/link/transport.hpp"

#include "host/link/link_error.hpp"

#include <functional>

namespace btsm::link {

struct GattService {
  uint16_t start = 0, end = 0;
  att::Uuid uuid;
};
struct GattDescriptor {
  uint16_t handle = 0;
  att::Uuid type;
};
struct GattCharacteristic {
  uint16_t decl_handle = 0, value_handle = 0, end_handle = 0;
  uint8_t properties = 0;
  att::Uuid uuid;
  att::Uuid service;
  std::vector<GattDescriptor> descriptors;
  bool can(uint8_t prop) const { return (properties & prop) != 0; }
  uint16_t cccd_handle() const;  // 0 if the characteristic has no CCCD
};
struct GattDatabase {
  std::vector<GattService> services;
  std::vector<GattCharacteristic> characteristics;
  bool has_service(const att::Uuid& u) const;
  // First characteristic with that UUID (inside `service` when given), or nullptr.
  const GattCharacteristic* find(const att::Uuid& uuid, const att::Uuid* service = nullptr) const;
};

// An ATT Error Response to one of our requests; code() is the ATT error code.
class AttError : public LinkError {
 public:
  AttError(LinkErrorKind kind, const std::string& what, uint8_t code) : LinkError(kind, what), code_(code) {}
  uint8_t code() const { return code_; }

 private:
  uint8_t code_;
};

class GattClient {
 public:
  using NotificationHandler = std::function<void(uint16_t handle, std::span<const uint8_t> value)>;

  // Does not own fd. `timeout` bounds every request/response transaction.
  GattClient(int fd, std::string peer_name, Millis timeout = Millis(5000));

  void on_notification(NotificationHandler h) { handler_ = std::move(h); }
  uint16_t mtu() const { return mtu_; }

  // Exchange MTU; the effective MTU is min(ours, theirs). Peers that refuse keep 23.
  uint16_t exchange_mtu(uint16_t client_rx_mtu = 247);
  std::vector<GattService> discover_primary_services();
  std::vector<GattCharacteristic> discover_characteristics(const GattService& s);
  std::vector<GattDescriptor> discover_descriptors(uint16_t start, uint16_t end);
  // Services, their characteristics, and every characteristic's descriptors.
  GattDatabase discover_all();

  // Read (with Read Blob continuation for values longer than MTU-1).
  att::Bytes read(uint16_t handle);
  // Write one value of at most MTU-3 bytes (Write Request waits for the response).
  void write(uint16_t handle, std::span<const uint8_t> value, bool with_response);
  // Split `data` into MTU-3 pieces and write them in order.
  void write_chunked(uint16_t handle, std::span<const uint8_t> data, bool with_response);
  void enable_notifications(uint16_t cccd_handle, bool indications = false);

  // Processes incoming PDUs for up to `timeout` (returns after the first batch); true if any
  // PDU arrived. Throws LinkError(kDeviceGone) when the bearer is closed.
  bool poll(Millis timeout);

 private:
  att::Pdu transact(const att::Pdu& req, uint8_t rsp_opcode, const char* what);
  void send(const att::Pdu& pdu);
  // Receives one PDU; nullopt on timeout.
  std::optional<att::Pdu> receive(Millis timeout);
  // Notification/indication/peer request handling; returns false if the PDU is not unsolicited.
  bool handle_unsolicited(const att::Pdu& pdu);
  [[noreturn]] void throw_att_error(const att::ErrorRsp& e, const char* what);

  int fd_;
  std::string peer_;
  Millis timeout_;
  uint16_t mtu_ = att::kDefaultLeMtu;
  NotificationHandler handler_;
};

}  // namespace btsm::link
