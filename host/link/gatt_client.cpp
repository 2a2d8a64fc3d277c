#include "host/link/gatt_client.hpp"

#include "host/link/fd_stream.hpp"
#include "host/link/link_error.hpp"

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>

namespace btsm::link {

using namespace att;

uint16_t GattCharacteristic::cccd_handle() const {
  for (const auto& d : descriptors)
    if (d.type == gatt::cccd()) return d.handle;
  return 0;
}

bool GattDatabase::has_service(const Uuid& u) const {
  return std::any_of(services.begin(), services.end(), [&](const GattService& s) { return s.uuid == u; });
}

const GattCharacteristic* GattDatabase::find(const Uuid& uuid, const Uuid* service) const {
  for (const auto& c : characteristics)
    if (c.uuid == uuid && (service == nullptr || c.service == *service)) return &c;
  return nullptr;
}

GattClient::GattClient(int fd, std::string peer_name, Millis timeout)
    : fd_(fd), peer_(std::move(peer_name)), timeout_(timeout) {}

void GattClient::send(const Pdu& pdu) {
  if (pdu.size() > mtu_)
    throw LinkError(LinkErrorKind::kProtocol, peer_ + ": ATT PDU of " + std::to_string(pdu.size()) +
                                                  " bytes exceeds the MTU " + std::to_string(mtu_));
  for (;;) {
    const ssize_t n = ::send(fd_, pdu.data(), pdu.size(), MSG_NOSIGNAL);
    if (n == static_cast<ssize_t>(pdu.size())) return;
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      if (poll_fd(fd_, POLLOUT, timeout_) == 0)
        throw LinkError(LinkErrorKind::kTimeout, peer_ + ": ATT send blocked");
      continue;
    }
    throw errno_error(n < 0 ? errno : EIO, peer_ + ": ATT send");
  }
}

std::optional<Pdu> GattClient::receive(Millis timeout) {
  const short ev = poll_fd(fd_, POLLIN, timeout);
  if (ev == 0) return std::nullopt;
  Pdu buf(kMaxMtu + 1);
  for (;;) {
    const ssize_t n = ::recv(fd_, buf.data(), buf.size(), MSG_DONTWAIT);
    if (n > 0) {
      buf.resize(static_cast<size_t>(n));
      return buf;
    }
    if (n == 0) throw LinkError(LinkErrorKind::kDeviceGone, peer_ + ": BLE link closed by the peer");
    if (errno == EINTR) continue;
    if (errno == EAGAIN || errno == EWOULDBLOCK) {
      if (ev & (POLLHUP | POLLERR))
        throw LinkError(LinkErrorKind::kDeviceGone, peer_ + ": BLE link closed by the peer");
      return std::nullopt;
    }
    throw errno_error(errno, peer_ + ": ATT receive");
  }
}

bool GattClient::handle_unsolicited(const Pdu& pdu) {
  if (pdu.empty()) return true;  // ignore empty datagrams
  const uint8_t op = pdu[0];
  if (op == kHandleValueNotification || op == kHandleValueIndication) {
    HandleValue hv;
    if (decode_handle_value(pdu, hv) && handler_) handler_(hv.handle, hv.value);
    if (op == kHandleValueIndication) send(Pdu{kHandleValueConfirmation});
    return true;
  }
  if (is_request(op)) {
    // We are only a client; tell the peer so its bearer does not wait 30 s for us.
    send(encode_error_rsp({op, 0, kRequestNotSupported}));
    return true;
  }
  if (op & 0x40) return true;  // a command from the peer: nothing to answer
  return false;
}

void GattClient::throw_att_error(const ErrorRsp& e, const char* what) {
  char handle[8];
  std::snprintf(handle, sizeof handle, "0x%04x", e.handle);
  const auto kind = (e.code == kInsufficientAuthentication || e.code == kInsufficientEncryption)
                        ? LinkErrorKind::kPermissionDenied
                        : LinkErrorKind::kProtocol;
  throw AttError(kind, peer_ + ": " + what + " failed at handle " + handle + ": " + error_name(e.code), e.code);
}

Pdu GattClient::transact(const Pdu& req, uint8_t rsp_opcode, const char* what) {
  send(req);
  const auto deadline = std::chrono::steady_clock::now() + timeout_;
  for (;;) {
    const auto left = std::chrono::duration_cast<Millis>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0)
      throw LinkError(LinkErrorKind::kTimeout, peer_ + ": no answer to " + what + " (" +
                                                   opcode_name(req[0]) + ")");
    auto pdu = receive(left);
    if (!pdu) continue;
    if (pdu->empty()) continue;
    if ((*pdu)[0] == rsp_opcode) return *pdu;
    if ((*pdu)[0] == kErrorRsp) {
      ErrorRsp e;
      if (decode_error_rsp(*pdu, e) && e.request_opcode == req[0]) {
        // Attribute-not-found ends discovery loops; the caller decides.
        throw_att_error(e, what);
      }
      continue;  // an error for some other request: stale, ignore
    }
    if (handle_unsolicited(*pdu)) continue;
    throw LinkError(LinkErrorKind::kProtocol, peer_ + ": unexpected " + opcode_name((*pdu)[0]) +
                                                  " while waiting for the answer to " + what);
  }
}

uint16_t GattClient::exchange_mtu(uint16_t client_rx_mtu) {
  try {
    const Pdu rsp = transact(encode_mtu(kMtuReq, client_rx_mtu), kMtuRsp, "MTU exchange");
    uint16_t server_mtu = 0;
    if (!decode_mtu(rsp, kMtuRsp, server_mtu))
      throw LinkError(LinkErrorKind::kProtocol, peer_ + ": malformed Exchange MTU Response");
    mtu_ = std::min(client_rx_mtu, server_mtu);
  } catch (const AttError&) {
    mtu_ = kDefaultLeMtu;  // the peer refused: the default applies
  }
  return mtu_;
}

namespace {
// True when the error ends a discovery loop normally (no more attributes in the range).
bool is_not_found(const AttError& e) { return e.code() == kAttributeNotFound; }
}  // namespace

std::vector<GattService> GattClient::discover_primary_services() {
  std::vector<GattService> out;
  uint32_t start = 1;
  while (start <= 0xFFFF) {
    Pdu rsp;
    try {
      rsp = transact(encode_typed_range(kReadByGroupTypeReq, {{static_cast<uint16_t>(start), 0xFFFF},
                                                              gatt::primary_service()}),
                     kReadByGroupTypeRsp, "primary service discovery");
    } catch (const AttError& e) {
      if (is_not_found(e)) break;
      throw;
    }
    std::vector<GroupRecord> recs;
    if (!decode_read_by_group_rsp(rsp, recs))
      throw LinkError(LinkErrorKind::kProtocol, peer_ + ": malformed Read By Group Type Response");
    for (const auto& r : recs) {
      if (r.start < start)
        throw LinkError(LinkErrorKind::kProtocol, peer_ + ": service discovery went backwards");
      out.push_back({r.start, r.end, r.uuid});
    }
    start = static_cast<uint32_t>(recs.back().end) + 1;
  }
  return out;
}

std::vector<GattCharacteristic> GattClient::discover_characteristics(const GattService& s) {
  std::vector<GattCharacteristic> out;
  uint32_t start = s.start;
  while (start <= s.end) {
    Pdu rsp;
    try {
      rsp = transact(encode_typed_range(kReadByTypeReq, {{static_cast<uint16_t>(start), s.end},
                                                         gatt::characteristic()}),
                     kReadByTypeRsp, "characteristic discovery");
    } catch (const AttError& e) {
      if (is_not_found(e)) break;
      throw;
    }
    std::vector<TypeRecord> recs;
    if (!decode_read_by_type_rsp(rsp, recs))
      throw LinkError(LinkErrorKind::kProtocol, peer_ + ": malformed Read By Type Response");
    for (const auto& r : recs) {
      CharDeclaration d;
      if (r.handle < start || !decode_char_declaration(r.value, d) || d.value_handle <= r.handle)
        throw LinkError(LinkErrorKind::kProtocol, peer_ + ": malformed characteristic declaration");
      GattCharacteristic c;
      c.decl_handle = r.handle;
      c.value_handle = d.value_handle;
      c.properties = d.properties;
      c.uuid = d.uuid;
      c.service = s.uuid;
      c.end_handle = s.end;
      if (!out.empty()) out.back().end_handle = static_cast<uint16_t>(r.handle - 1);
      out.push_back(c);
    }
    start = static_cast<uint32_t>(recs.back().handle) + 1;
  }
  return out;
}

std::vector<GattDescriptor> GattClient::discover_descriptors(uint16_t first, uint16_t last) {
  std::vector<GattDescriptor> out;
  uint32_t start = first;
  while (start <= last && start != 0) {
    Pdu rsp;
    try {
      rsp = transact(encode_find_info_req({static_cast<uint16_t>(start), last}), kFindInfoRsp,
                     "descriptor discovery");
    } catch (const AttError& e) {
      if (is_not_found(e)) break;
      throw;
    }
    std::vector<InfoRecord> recs;
    if (!decode_find_info_rsp(rsp, recs))
      throw LinkError(LinkErrorKind::kProtocol, peer_ + ": malformed Find Information Response");
    for (const auto& r : recs) {
      if (r.handle < start)
        throw LinkError(LinkErrorKind::kProtocol, peer_ + ": descriptor discovery went backwards");
      out.push_back({r.handle, r.type});
    }
    start = static_cast<uint32_t>(recs.back().handle) + 1;
  }
  return out;
}

GattDatabase GattClient::discover_all() {
  GattDatabase db;
  db.services = discover_primary_services();
  for (const auto& s : db.services) {
    auto chars = discover_characteristics(s);
    for (auto& c : chars) {
      if (c.value_handle < c.end_handle)
        c.descriptors = discover_descriptors(static_cast<uint16_t>(c.value_handle + 1), c.end_handle);
      db.characteristics.push_back(std::move(c));
    }
  }
  return db;
}

Bytes GattClient::read(uint16_t handle) {
  const Pdu rsp = transact(encode_read_req(handle), kReadRsp, "read");
  Bytes value(rsp.begin() + 1, rsp.end());
  // A full response may mean a longer value: continue with Read Blob until a short piece.
  size_t piece = value.size();
  while (piece == static_cast<size_t>(mtu_ - 1) && value.size() < 512) {
    Pdu blob;
    try {
      blob = transact(encode_read_blob_req({handle, static_cast<uint16_t>(value.size())}), kReadBlobRsp,
                      "read blob");
    } catch (const AttError& e) {
      if (e.code() == kAttributeNotLong || e.code() == kInvalidOffset) break;
      throw;
    }
    piece = blob.size() - 1;
    value.insert(value.end(), blob.begin() + 1, blob.end());
  }
  return value;
}

void GattClient::write(uint16_t handle, std::span<const uint8_t> value, bool with_response) {
  if (value.size() > static_cast<size_t>(mtu_ - 3))
    throw LinkError(LinkErrorKind::kProtocol, peer_ + ": write of " + std::to_string(value.size()) +
                                                  " bytes exceeds MTU-3");
  WriteReq w{handle, Bytes(value.begin(), value.end())};
  if (with_response) {
    transact(encode_write(kWriteReq, w), kWriteRsp, "write");
  } else {
    send(encode_write(kWriteCmd, w));
  }
}

void GattClient::write_chunked(uint16_t handle, std::span<const uint8_t> data, bool with_response) {
  const size_t chunk = static_cast<size_t>(mtu_ - 3);
  for (size_t at = 0; at < data.size(); at += chunk)
    write(handle, data.subspan(at, std::min(chunk, data.size() - at)), with_response);
}

void GattClient::enable_notifications(uint16_t cccd_handle, bool indications) {
  const uint8_t v[2] = {static_cast<uint8_t>(indications ? 0x02 : 0x01), 0x00};
  write(cccd_handle, v, true);
}

bool GattClient::poll(Millis timeout) {
  auto pdu = receive(timeout);
  if (!pdu) return false;
  bool any = false;
  while (pdu) {
    any = true;
    if (!handle_unsolicited(*pdu)) {
      // A response nobody waits for (late answer after a timeout): drop it.
    }
    pdu = receive(Millis(0));
  }
  return any;
}

}  // namespace btsm::link
