#include "host/link/serial_transport.hpp"

#include "host/link/link_error.hpp"

#include <fcntl.h>
#include <grp.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>

namespace btsm::link {
namespace {

speed_t to_speed(unsigned baud) {
  switch (baud) {
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    default: return 0;
  }
}

}  // namespace

std::string serial_permission_hint(const std::string& path) {
  struct stat st {};
  std::string group_name = "dialout";
  if (::stat(path.c_str(), &st) == 0) {
    if (const struct group* g = ::getgrgid(st.st_gid)) group_name = g->gr_name;
  }
  return "the device belongs to group '" + group_name + "': run `sudo usermod -aG " + group_name +
         " $USER` and log in again";
}

SerialTransport::SerialTransport(std::string path, SerialOptions opts)
    : path_(std::move(path)), opts_(opts) {
  open_now();
}

int SerialTransport::open_fd() {
  const speed_t speed = to_speed(opts_.baud);
  if (speed == 0)
    throw LinkError(LinkErrorKind::kIo, describe() + ": unsupported baud rate " + std::to_string(opts_.baud));
  const int fd = ::open(path_.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    if (err == ENOENT)
      throw LinkError(LinkErrorKind::kNoDevice,
                      describe() + ": no such device (is the module plugged in / the simulator running? "
                                   "`btsm list` shows serial adapters)");
    if (err == EBUSY)
      throw LinkError(LinkErrorKind::kIo, describe() + ": device busy (another program has it open?)");
    if (err == EISDIR)  // no device there, as a missing path: exit 3, not an I/O failure
      throw LinkError(LinkErrorKind::kNoDevice, describe() + ": a directory, not a serial device (`btsm list` shows serial adapters)");
    throw errno_error(err, describe() + ": open", serial_permission_hint(path_));
  }
  termios tio{};
  if (::tcgetattr(fd, &tio) != 0) {
    const int err = errno;
    ::close(fd);
    if (err == ENOTTY)  // a regular file or /dev/null: no module can answer there
      throw LinkError(LinkErrorKind::kNoDevice, describe() + ": not a serial device (tty); `btsm list` shows serial adapters");
    throw errno_error(err, describe() + ": tcgetattr");
  }
  ::cfmakeraw(&tio);
  tio.c_cflag &= ~static_cast<tcflag_t>(CSIZE | PARENB | CSTOPB | CRTSCTS);
  tio.c_cflag |= CS8 | CLOCAL | CREAD;
  if (opts_.keep_dtr_on_close) tio.c_cflag &= ~static_cast<tcflag_t>(HUPCL);
  tio.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  ::cfsetispeed(&tio, speed);
  ::cfsetospeed(&tio, speed);
  if (::tcsetattr(fd, TCSANOW, &tio) != 0) {
    const int err = errno;
    ::close(fd);
    throw errno_error(err, describe() + ": tcsetattr (115200 8N1 raw)");
  }
  return fd;
}

}  // namespace btsm::link
