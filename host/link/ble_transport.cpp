#include "host/link/ble_transport.hpp"

#include "host/link/fd_stream.hpp"
#include "host/link/link_error.hpp"
#include "host/link/rfcomm_transport.hpp"

#include <bluetooth/bluetooth.h>
#include <bluetooth/hci.h>
#include <bluetooth/hci_lib.h>
#include <bluetooth/l2cap.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>

namespace btsm::link {

GattSerialTransport::GattSerialTransport(std::function<int()> connect, std::string name,
                                         GattSerialOptions opts)
    : connect_(std::move(connect)), name_(std::move(name)), opts_(opts) {
  open();
}

GattSerialTransport::~GattSerialTransport() { close(); }

void GattSerialTransport::close() {
  client_.reset();
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void GattSerialTransport::open() {
  fd_ = connect_();
  try {
    client_ = std::make_unique<GattClient>(fd_, name_, opts_.att_timeout);
    // Notifications may start as soon as the CCCD is written, so install the collector first.
    client_->on_notification([this](uint16_t handle, std::span<const uint8_t> value) {
      if (handle == profile_.rx_handle && handle != 0) rx_.insert(rx_.end(), value.begin(), value.end());
    });
    client_->exchange_mtu(opts_.requested_mtu);
    db_ = client_->discover_all();
    profile_ = choose_profile(db_, name_);
    setup_profile(*client_, profile_, name_, opts_.bluno);
  } catch (...) {
    close();
    throw;
  }
}

void GattSerialTransport::reopen() {
  close();
  rx_.clear();
  open();
}

uint16_t GattSerialTransport::mtu() const { return client_ ? client_->mtu() : att::kDefaultLeMtu; }

size_t GattSerialTransport::max_write_size() const { return static_cast<size_t>(mtu() - 3); }

void GattSerialTransport::write(std::span<const uint8_t> bytes) {
  if (!client_) throw LinkError(LinkErrorKind::kDeviceGone, name_ + ": not connected");
  client_->write_chunked(profile_.tx_handle, bytes, profile_.tx_with_response);
}

size_t GattSerialTransport::read(std::span<uint8_t> out, Millis timeout) {
  if (!client_) throw LinkError(LinkErrorKind::kDeviceGone, name_ + ": not connected");
  if (rx_.empty()) client_->poll(timeout);
  const size_t n = std::min(out.size(), rx_.size());
  std::copy_n(rx_.begin(), n, out.begin());
  rx_.erase(rx_.begin(), rx_.begin() + static_cast<long>(n));
  return n;
}

BleAddress parse_ble_address(const std::string& text) {
  BleAddress a;
  a.address = text;
  const auto slash = text.find('/');
  if (slash != std::string::npos) {
    a.address = text.substr(0, slash);
    const std::string t = text.substr(slash + 1);
    if (t == "random") a.type = BleAddressType::kRandom;
    else if (t == "public") a.type = BleAddressType::kPublic;
    else
      throw LinkError(LinkErrorKind::kNoDevice,
                      "bad BLE address type '" + t + "' in '" + text + "': use /public or /random");
  }
  uint8_t tmp[6];
  parse_bdaddr_or_throw(a.address, tmp);
  return a;
}

int connect_le_att(const BleAddress& addr, Millis timeout) {
  const std::string name = "BLE " + addr.address;
  // The first adapter; without one, LE connects fail in confusing ways, so say it plainly.
  if (hci_get_route(nullptr) < 0)
    throw LinkError(LinkErrorKind::kNoDevice,
                    name + ": no Bluetooth adapter found (is it plugged in and up? `hciconfig` / `rfkill list`)");
  const int fd = ::socket(AF_BLUETOOTH, SOCK_SEQPACKET | SOCK_CLOEXEC, BTPROTO_L2CAP);
  if (fd < 0) throw errno_error(errno, name + ": L2CAP socket");
  auto fail = [&](int err, const std::string& what) {
    ::close(fd);
    return errno_error(err, name + ": " + what,
                       "LE connections may need CAP_NET_RAW: `sudo setcap cap_net_raw,cap_net_admin+eip $(which btsm)`");
  };
  sockaddr_l2 src{};
  src.l2_family = AF_BLUETOOTH;
  src.l2_cid = htobs(att::kAttCid);
  src.l2_bdaddr_type = BDADDR_LE_PUBLIC;
  // l2_bdaddr stays all-zero = BDADDR_ANY (the macro is a C compound literal).
  if (::bind(fd, reinterpret_cast<sockaddr*>(&src), sizeof src) != 0) throw fail(errno, "bind ATT channel");
  bt_security sec{};
  sec.level = BT_SECURITY_LOW;
  if (::setsockopt(fd, SOL_BLUETOOTH, BT_SECURITY, &sec, sizeof sec) != 0) throw fail(errno, "set security");

  sockaddr_l2 dst{};
  dst.l2_family = AF_BLUETOOTH;
  dst.l2_cid = htobs(att::kAttCid);
  dst.l2_psm = 0;
  dst.l2_bdaddr_type = addr.type == BleAddressType::kRandom ? BDADDR_LE_RANDOM : BDADDR_LE_PUBLIC;
  parse_bdaddr_or_throw(addr.address, dst.l2_bdaddr.b);
  // Connect non-blocking so the deadline is ours, not the kernel's 40 s.
  const int flags = ::fcntl(fd, F_GETFL);
  ::fcntl(fd, F_SETFL, flags | O_NONBLOCK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&dst), sizeof dst) != 0 && errno != EINPROGRESS)
    throw fail(errno, "connect");
  const short ev = poll_fd(fd, POLLOUT, timeout);
  int soerr = 0;
  socklen_t len = sizeof soerr;
  ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &soerr, &len);
  if (ev == 0) {
    ::close(fd);
    throw LinkError(LinkErrorKind::kTimeout,
                    name + ": connect timed out (module off, out of range, connected elsewhere, or a "
                           "random address: try " + addr.address + "/random)");
  }
  if (soerr != 0) throw fail(soerr, "connect");
  return fd;
}

std::unique_ptr<GattSerialTransport> open_ble(const std::string& address_text, Millis timeout,
                                              GattSerialOptions opts) {
  const BleAddress addr = parse_ble_address(address_text);
  return std::make_unique<GattSerialTransport>([addr, timeout] { return connect_le_att(addr, timeout); },
                                               "BLE " + addr.address, opts);
}

}  // namespace btsm::link
