#pragma once
// A Transport over a stream file descriptor (tty or RFCOMM socket): poll-based reads with a
// deadline, complete writes, hang-up detection. Subclasses only say how to open the fd.
#include "host/link/transport.hpp"

namespace btsm::link {

class FdStreamTransport : public Transport {
 public:
  ~FdStreamTransport() override;
  void write(std::span<const uint8_t> bytes) override;
  size_t read(std::span<uint8_t> out, Millis timeout) override;
  void reopen() override;
  int fd() const { return fd_; }

 protected:
  // Opens the device and returns a non-blocking fd; throws LinkError.
  virtual int open_fd() = 0;
  void open_now() { fd_ = open_fd(); }
  void close_fd();

 private:
  int fd_ = -1;
};

// Polls fd for `events` up to timeout; returns revents (0 on timeout). Retries on EINTR.
short poll_fd(int fd, short events, Millis timeout);

}  // namespace btsm::link
