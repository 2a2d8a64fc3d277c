#include "fake_peripheral.hpp"

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <stdexcept>

namespace btsm::test {

using namespace btsm::link::att;

FakePeripheral::~FakePeripheral() {
  stop();
  if (fd_ >= 0) ::close(fd_);
  if (stream_fd_ >= 0) ::close(stream_fd_);
}

void FakePeripheral::close_services() {
  for (size_t i = 0; i < services_.size(); ++i)
    services_[i].end = static_cast<uint16_t>(i + 1 < services_.size() ? services_[i + 1].start - 1 : next_handle_ - 1);
}

void FakePeripheral::add_service(const Uuid& uuid) {
  const uint16_t h = next_handle_++;
  attrs_.push_back({h, gatt::primary_service(), uuid.to_le()});
  services_.push_back({h, h, uuid});
  close_services();
}

uint16_t FakePeripheral::add_characteristic(const Uuid& uuid, uint8_t properties, Bytes value) {
  const uint16_t decl = next_handle_++;
  const uint16_t vh = next_handle_++;
  attrs_.push_back({decl, gatt::characteristic(), encode_char_declaration({properties, vh, uuid})});
  attrs_.push_back({vh, uuid, std::move(value)});
  if (properties & (kPropNotify | kPropIndicate)) {
    // A user description first, so the client must walk past a non-CCCD descriptor.
    attrs_.push_back({next_handle_++, Uuid::from16(0x2901), Bytes{'s', 'e', 'r', 'i', 'a', 'l'}});
    Attribute c{next_handle_++, gatt::cccd(), Bytes{0, 0}};
    c.is_cccd = true;
    c.owner_value_handle = vh;
    attrs_.push_back(c);
  }
  close_services();
  return vh;
}

void FakePeripheral::bridge(uint16_t write_handle, uint16_t notify_handle, int stream_fd) {
  bridged_handle_ = write_handle;
  notify_handle_ = notify_handle;
  stream_fd_ = stream_fd;
}

void FakePeripheral::start(int fd) {
  fd_ = fd;
  running_ = true;
  thread_ = std::thread([this] { run(); });
}

void FakePeripheral::stop() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
}

void FakePeripheral::disconnect() {
  stop();
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void FakePeripheral::send(const Pdu& pdu) {
  if (fd_ >= 0) ::send(fd_, pdu.data(), pdu.size(), MSG_NOSIGNAL);
}

bool FakePeripheral::notifications_enabled(uint16_t vh) const {
  std::lock_guard<std::mutex> l(mu_);
  for (const auto& a : attrs_)
    if (a.is_cccd && a.owner_value_handle == vh) return a.value.size() == 2 && (a.value[0] & 0x01);
  return false;
}

bool FakePeripheral::notify(uint16_t vh, const Bytes& value) {
  if (!notifications_enabled(vh)) return false;
  std::lock_guard<std::mutex> l(mu_);
  send(encode_handle_value(kHandleValueNotification, {vh, value}));
  return true;
}

std::vector<FakePeripheral::Write> FakePeripheral::writes() const {
  std::lock_guard<std::mutex> l(mu_);
  return writes_;
}

Pdu FakePeripheral::handle(const Pdu& req) {
  ++requests_;
  const uint8_t op = req.empty() ? 0 : req[0];
  auto error = [&](uint16_t h, uint8_t code) { return encode_error_rsp({op, h, code}); };
  const uint16_t mtu = mtu_;
  switch (op) {
    case kMtuReq: {
      uint16_t client = 0;
      if (!decode_mtu(req, kMtuReq, client)) return error(0, kInvalidPdu);
      mtu_ = std::min(client, server_mtu_);
      return encode_mtu(kMtuRsp, server_mtu_);
    }
    case kReadByGroupTypeReq: {
      TypedRangeReq r;
      if (!decode_typed_range(req, op, r)) return error(0, kInvalidPdu);
      if (r.range.start == 0 || r.range.start > r.range.end) return error(r.range.start, kInvalidHandle);
      if (!(r.type == gatt::primary_service())) return error(r.range.start, kUnsupportedGroupType);
      std::vector<GroupRecord> recs;
      for (const auto& s : services_)
        if (s.start >= r.range.start && s.start <= r.range.end) recs.push_back({s.start, s.end, s.uuid});
      if (recs.empty()) return error(r.range.start, kAttributeNotFound);
      size_t taken = 0;
      return encode_read_by_group_rsp(recs, mtu, taken);
    }
    case kReadByTypeReq: {
      TypedRangeReq r;
      if (!decode_typed_range(req, op, r)) return error(0, kInvalidPdu);
      if (r.range.start == 0 || r.range.start > r.range.end) return error(r.range.start, kInvalidHandle);
      std::vector<TypeRecord> recs;
      for (const auto& a : attrs_)
        if (a.handle >= r.range.start && a.handle <= r.range.end && a.type == r.type) recs.push_back({a.handle, a.value});
      if (recs.empty()) return error(r.range.start, kAttributeNotFound);
      size_t taken = 0;
      return encode_read_by_type_rsp(recs, mtu, taken);
    }
    case kFindInfoReq: {
      HandleRange r;
      if (!decode_find_info_req(req, r)) return error(0, kInvalidPdu);
      if (r.start == 0 || r.start > r.end) return error(r.start, kInvalidHandle);
      std::vector<InfoRecord> recs;
      for (const auto& a : attrs_)
        if (a.handle >= r.start && a.handle <= r.end) recs.push_back({a.handle, a.type});
      if (recs.empty()) return error(r.start, kAttributeNotFound);
      size_t taken = 0;
      return encode_find_info_rsp(recs, mtu, taken);
    }
    case kReadReq:
    case kReadBlobReq: {
      uint16_t h = 0, offset = 0;
      if (op == kReadReq) {
        if (!decode_read_req(req, h)) return error(0, kInvalidPdu);
      } else {
        ReadBlobReq rb;
        if (!decode_read_blob_req(req, rb)) return error(0, kInvalidPdu);
        h = rb.handle;
        offset = rb.offset;
      }
      std::lock_guard<std::mutex> l(mu_);
      for (const auto& a : attrs_) {
        if (a.handle != h) continue;
        if (offset > a.value.size()) return error(h, kInvalidOffset);
        const size_t n = std::min<size_t>(a.value.size() - offset, mtu - 1);
        return encode_value_rsp(op == kReadReq ? kReadRsp : kReadBlobRsp,
                                std::span<const uint8_t>(a.value).subspan(offset, n));
      }
      return error(h, kInvalidHandle);
    }
    case kWriteReq:
    case kWriteCmd: {
      WriteReq w;
      if (!decode_write(req, op, w)) return op == kWriteReq ? error(0, kInvalidPdu) : Pdu{};
      bool found = false;
      {
        std::lock_guard<std::mutex> l(mu_);
        writes_.push_back({op, w.handle, w.value});
        for (auto& a : attrs_) {
          if (a.handle != w.handle) continue;
          found = true;
          if (a.is_cccd && w.value.size() != 2) return op == kWriteReq ? error(w.handle, kInvalidAttributeValueLength) : Pdu{};
          a.value = w.value;
        }
      }
      if (!found) return op == kWriteReq ? error(w.handle, kInvalidHandle) : Pdu{};
      if (w.handle == bridged_handle_ && stream_fd_ >= 0) {
        size_t done = 0;
        while (done < w.value.size()) {
          const ssize_t n = ::write(stream_fd_, w.value.data() + done, w.value.size() - done);
          if (n <= 0) break;
          done += static_cast<size_t>(n);
        }
      }
      return op == kWriteReq ? Pdu{kWriteRsp} : Pdu{};
    }
    case kHandleValueConfirmation: return {};
    default:
      if (is_request(op)) return error(0, kRequestNotSupported);
      return {};
  }
}

void FakePeripheral::run() {
  Pdu buf(600);
  uint8_t sbuf[256];
  while (running_) {
    pollfd p[2] = {{fd_, POLLIN, 0}, {stream_fd_, POLLIN, 0}};
    const nfds_t n = stream_fd_ >= 0 ? 2 : 1;
    if (::poll(p, n, 10) <= 0) continue;
    if (p[0].revents & POLLIN) {
      const ssize_t r = ::recv(fd_, buf.data(), buf.size(), 0);
      if (r <= 0) break;  // client closed the bearer
      const Pdu rsp = handle(Pdu(buf.begin(), buf.begin() + r));
      if (!rsp.empty()) {
        std::lock_guard<std::mutex> l(mu_);
        send(rsp);
      }
    }
    if (p[0].revents & (POLLHUP | POLLERR)) break;
    if (n == 2 && (p[1].revents & POLLIN)) {
      const ssize_t r = ::read(stream_fd_, sbuf, sizeof sbuf);
      if (r > 0) {
        // Like the CC2540: the UART stream goes out in notifications of at most MTU-3 bytes.
        const size_t chunk = static_cast<size_t>(mtu_ - 3);
        for (ssize_t at = 0; at < r; at += static_cast<ssize_t>(chunk)) {
          const size_t len = std::min(chunk, static_cast<size_t>(r - at));
          notify(notify_handle_, Bytes(sbuf + at, sbuf + at + len));
        }
      }
    }
  }
}

void FakePeripheral::make_bluno(FakePeripheral& p, uint16_t& serial, uint16_t& command, const std::string& model) {
  p.add_service(Uuid::from16(0x1800));  // GAP
  p.add_characteristic(Uuid::from16(0x2A00), kPropRead, Bytes{'B', 'l', 'u', 'n', 'o'});
  p.add_service(Uuid::from16(0x180A));  // Device Information
  p.add_characteristic(Uuid::from16(0x2A24), kPropRead, Bytes(model.begin(), model.end()));
  p.add_service(Uuid::from16(0xDFB0));
  serial = p.add_characteristic(Uuid::from16(0xDFB1),
                                kPropRead | kPropWriteWithoutResponse | kPropWrite | kPropNotify);
  command = p.add_characteristic(Uuid::from16(0xDFB2), kPropRead | kPropWriteWithoutResponse | kPropWrite | kPropNotify);
}

void FakePeripheral::make_nus(FakePeripheral& p, uint16_t& rx_write, uint16_t& tx_notify) {
  p.add_service(Uuid::from16(0x1800));
  p.add_characteristic(Uuid::from16(0x2A00), kPropRead, Bytes{'N', 'U', 'S'});
  p.add_service(*Uuid::parse("6e400001-b5a3-f393-e0a9-e50e24dcca9e"));
  // Notify characteristic declared first on purpose: the client must pick by properties.
  tx_notify = p.add_characteristic(*Uuid::parse("6e400003-b5a3-f393-e0a9-e50e24dcca9e"), kPropNotify);
  rx_write = p.add_characteristic(*Uuid::parse("6e400002-b5a3-f393-e0a9-e50e24dcca9e"),
                                  kPropWrite | kPropWriteWithoutResponse);
}

void FakePeripheral::make_hm10(FakePeripheral& p, uint16_t& serial) {
  p.add_service(Uuid::from16(0x1800));
  p.add_characteristic(Uuid::from16(0x2A00), kPropRead, Bytes{'H', 'M', 'S', 'o', 'f', 't'});
  p.add_service(Uuid::from16(0xFFE0));
  serial = p.add_characteristic(Uuid::from16(0xFFE1), kPropRead | kPropWrite | kPropNotify);  // no write-cmd
}

}  // namespace btsm::test
