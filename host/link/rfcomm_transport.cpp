#include "host/link/rfcomm_transport.hpp"

#include "host/link/link_error.hpp"

#include <bluetooth/bluetooth.h>
#include <bluetooth/rfcomm.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstring>

namespace btsm::link {

void parse_bdaddr_or_throw(const std::string& text, uint8_t out_le[6]) {
  // Six hex pairs separated by ':'; bdaddr_t stores them little-endian (last pair first).
  bool ok = text.size() == 17;
  for (size_t i = 0; ok && i < 17; ++i) {
    if (i % 3 == 2) ok = text[i] == ':';
    else ok = std::isxdigit(static_cast<unsigned char>(text[i])) != 0;
  }
  if (!ok)
    throw LinkError(LinkErrorKind::kNoDevice,
                    "bad Bluetooth address '" + text + "': expected AA:BB:CC:DD:EE:FF");
  for (int i = 0; i < 6; ++i)
    out_le[5 - i] = static_cast<uint8_t>(std::stoi(text.substr(static_cast<size_t>(i) * 3, 2), nullptr, 16));
}

RfcommTransport::RfcommTransport(std::string address, RfcommOptions opts)
    : address_(std::move(address)), opts_(opts) {
  open_now();
}

std::string RfcommTransport::describe() const {
  return "rfcomm " + address_ + " channel " + std::to_string(opts_.channel);
}

int RfcommTransport::open_fd() {
  sockaddr_rc addr{};
  addr.rc_family = AF_BLUETOOTH;
  addr.rc_channel = static_cast<uint8_t>(opts_.channel);
  parse_bdaddr_or_throw(address_, addr.rc_bdaddr.b);
  const int fd = ::socket(AF_BLUETOOTH, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, BTPROTO_RFCOMM);
  if (fd < 0) {
    const int err = errno;
    if (err == EAFNOSUPPORT || err == EPROTONOSUPPORT)
      throw LinkError(LinkErrorKind::kNoDevice,
                      describe() + ": this kernel has no Bluetooth RFCOMM support (no adapter?)");
    throw errno_error(err, describe() + ": socket");
  }
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 && errno != EINPROGRESS) {
    const int err = errno;
    ::close(fd);
    throw errno_error(err, describe() + ": connect", "pair the device first: bluetoothctl pair " + address_);
  }
  const short ev = poll_fd(fd, POLLOUT, opts_.connect_timeout);
  int soerr = 0;
  socklen_t len = sizeof soerr;
  ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &soerr, &len);
  if (ev == 0 || soerr != 0) {
    ::close(fd);
    if (ev == 0) throw LinkError(LinkErrorKind::kTimeout, describe() + ": connect timed out (device off or out of range?)");
    throw errno_error(soerr, describe() + ": connect", "pair the device first: bluetoothctl pair " + address_);
  }
  return fd;
}

}  // namespace btsm::link
