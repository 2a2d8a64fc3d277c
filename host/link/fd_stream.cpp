#include "host/link/fd_stream.hpp"

#include "host/link/link_error.hpp"

#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>

namespace btsm::link {

short poll_fd(int fd, short events, Millis timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    const auto left = std::chrono::duration_cast<Millis>(deadline - std::chrono::steady_clock::now());
    pollfd p{fd, events, 0};
    const int n = ::poll(&p, 1, static_cast<int>(std::max<Millis::rep>(0, left.count())));
    if (n > 0) return p.revents;
    if (n == 0) return 0;
    if (errno != EINTR) throw errno_error(errno, "poll");
  }
}

FdStreamTransport::~FdStreamTransport() { close_fd(); }

void FdStreamTransport::close_fd() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void FdStreamTransport::reopen() {
  close_fd();
  fd_ = open_fd();
}

void FdStreamTransport::write(std::span<const uint8_t> bytes) {
  if (fd_ < 0) throw LinkError(LinkErrorKind::kDeviceGone, describe() + ": not open");
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n > 0) {
      done += static_cast<size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      // Output buffer full (slow UART): wait until the driver drains it, but not forever.
      const short ev = poll_fd(fd_, POLLOUT, Millis(2000));
      if (ev & (POLLHUP | POLLERR | POLLNVAL))
        throw LinkError(LinkErrorKind::kDeviceGone, describe() + ": device hung up during write");
      if (ev == 0) throw LinkError(LinkErrorKind::kTimeout, describe() + ": write blocked for 2 s");
      continue;
    }
    throw errno_error(n < 0 ? errno : EIO, describe() + ": write");
  }
}

size_t FdStreamTransport::read(std::span<uint8_t> out, Millis timeout) {
  if (fd_ < 0) throw LinkError(LinkErrorKind::kDeviceGone, describe() + ": not open");
  const short ev = poll_fd(fd_, POLLIN, timeout);
  if (ev == 0) return 0;
  if (ev & POLLNVAL) throw LinkError(LinkErrorKind::kDeviceGone, describe() + ": descriptor closed");
  // Read even when POLLHUP is set: the peer may have written its last bytes before hanging up.
  for (;;) {
    const ssize_t n = ::read(fd_, out.data(), out.size());
    if (n > 0) return static_cast<size_t>(n);
    if (n == 0) throw LinkError(LinkErrorKind::kDeviceGone, describe() + ": device hung up");
    if (errno == EINTR) continue;
    if (errno == EAGAIN || errno == EWOULDBLOCK) {
      if (ev & (POLLHUP | POLLERR))
        throw LinkError(LinkErrorKind::kDeviceGone, describe() + ": device hung up");
      return 0;
    }
    // A pty slave whose master closed, or a USB adapter that was unplugged, reads EIO.
    throw errno_error(errno, describe() + ": read");
  }
}

}  // namespace btsm::link
