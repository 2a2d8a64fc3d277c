#pragma once
// Serial tty transport: /dev/ttyACM*, /dev/ttyUSB*, /dev/rfcommN or a pty of the simulated
// module. Raw 8N1 at 115200 baud (the Bluno's ATmega <-> CC2540 UART rate), no flow control.
#include "host/link/fd_stream.hpp"

namespace btsm::link {

struct SerialOptions {
  unsigned baud = 115200;       // bits/s; one of the standard termios rates
  bool keep_dtr_on_close = true;  // clear HUPCL so closing the port does not reset the board
};

class SerialTransport : public FdStreamTransport {
 public:
  // Opens immediately; throws LinkError (kNoDevice, kPermissionDenied with a dialout hint, kIo).
  explicit SerialTransport(std::string path, SerialOptions opts = {});
  std::string describe() const override { return "serial " + path_; }
  const std::string& path() const { return path_; }

 protected:
  int open_fd() override;

 private:
  std::string path_;
  SerialOptions opts_;
};

// The hint printed with EACCES on a tty: which group owns it and how to join it.
std::string serial_permission_hint(const std::string& path);

}  // namespace btsm::link
