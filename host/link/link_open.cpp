#include "host/link/link_open.hpp"

#include "host/link/ble_transport.hpp"
#include "host/link/link_error.hpp"
#include "host/link/rfcomm_transport.hpp"
#include "host/link/serial_transport.hpp"
#include "host/link/usb_devices.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <optional>
#include <thread>

namespace btsm::link {
namespace {

std::vector<UsbSerialDevice> usb_devices(const std::string& sysfs_root) {
  std::vector<UsbId> ids;
  try {
    ids = libusb_ids();
  } catch (const LinkError&) {
    ids = sysfs_usb_ids(sysfs_root);  // no libusb access (container): sysfs has the same ids
  }
  return describe_usb_serial(ids, sysfs_root);
}

std::string only_adapter_tty(const std::string& sysfs_root) {
  std::vector<std::string> ttys;
  for (const auto& d : usb_devices(sysfs_root))
    for (const auto& t : d.ttys) ttys.push_back(t);
  if (ttys.size() == 1) return ttys.front();
  if (ttys.empty())
    throw LinkError(LinkErrorKind::kNoDevice,
                    "no link given and no USB serial adapter found: pass --port PATH, --ble ADDR, --rfcomm ADDR or "
                    "--usb VID:PID (`btsm list` and `btsm scan` find modules)");
  std::string all;
  for (const auto& t : ttys) all += " " + t;
  throw LinkError(LinkErrorKind::kNoDevice, "several serial adapters are connected (" + all.substr(1) +
                                                "): choose one with --port");
}

// Where `path` leads when it is a symbolic link whose target does not exist, else nullopt. Such a
// link is no device that may still appear: udev makes /dev/serial/by-id/... when the adapter
// appears and removes it with it, and sim-module makes its link once its pty exists; one that
// dangles names a device that is gone (an adapter unplugged without udev, a simulator killed).
std::optional<std::string> dangling_link_target(const std::string& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return std::nullopt;
  if (::stat(path.c_str(), &st) == 0 || errno != ENOENT) return std::nullopt;
  std::error_code ec;
  const auto target = std::filesystem::read_symlink(path, ec);
  return ec ? std::string("?") : target.string();
}

}  // namespace

std::string serial_port_for(const LinkSpec& spec) {
  if (!spec.ble.empty() || !spec.rfcomm.empty())
    throw LinkError(LinkErrorKind::kUnsupported,
                    "firmware is flashed through the module's USB serial port (Optiboot), not over Bluetooth: "
                    "connect it by USB and pass --port or --usb");
  if (!spec.port.empty()) {
    if (const auto target = dangling_link_target(spec.port))
      throw LinkError(LinkErrorKind::kNoDevice, "serial " + spec.port + ": a dangling symbolic link to " + *target +
                                                    ", which does not exist: the device it named is gone; `btsm list` "
                                                    "shows serial adapters");
    // A port that does not exist yet is left to the programmer (a dry run prints the command for
    // later); one that exists must be a character device: avrdude was handed a regular file.
    struct stat st {};
    if (::stat(spec.port.c_str(), &st) == 0) {
      bool tty = false;
      if (S_ISCHR(st.st_mode)) {  // /dev/null, /dev/zero are character devices too: a tty answers tcgetattr
        const int fd = ::open(spec.port.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
        if (fd >= 0) {
          tty = ::isatty(fd) != 0;
          ::close(fd);
        } else {
          tty = errno == EBUSY || errno == EACCES;  // in use or not ours: a real port, avrdude says the rest
        }
      }
      if (!tty)
        throw LinkError(LinkErrorKind::kNoDevice, "serial " + spec.port + ": " + (S_ISDIR(st.st_mode) ? "a directory, not" : "not") +
                                                      " a serial device; `btsm list` shows serial adapters");
    }
    return spec.port;
  }
  if (!spec.usb.empty()) return tty_for_usb(spec.usb, usb_devices(spec.sysfs_root));
  return only_adapter_tty(spec.sysfs_root);
}

namespace {
// Returns when `path` exists, its directory does not, or `wait_s` has passed (a README block
// pasted whole ran `set-config` before the `sim-module &` of the line before had made its link).
// A dangling symbolic link is not waited for (serial_port_for names it): it waited 5 s to fail.
void wait_for_port_to_appear(const std::string& path, double wait_s) {
  struct stat st {};
  if (path.empty() || ::lstat(path.c_str(), &st) == 0 || errno != ENOENT) return;
  const auto slash = path.find_last_of('/');
  const std::string dir = slash == std::string::npos ? "." : slash == 0 ? "/" : path.substr(0, slash);
  if (::stat(dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) return;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(wait_s);
  while (std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (::lstat(path.c_str(), &st) == 0) return;
  }
}
}  // namespace

TransportPtr open_link(const LinkSpec& spec) {
  const auto timeout = Millis(static_cast<long>(spec.timeout_s * 1000));
  if (!spec.ble.empty()) {
    GattSerialOptions o;
    o.att_timeout = std::max(timeout, Millis(2000));
    return open_ble(spec.ble, std::max(timeout, Millis(10000)), o);
  }
  if (!spec.rfcomm.empty()) {
    RfcommOptions o;
    o.channel = spec.rfcomm_channel;
    return std::make_unique<RfcommTransport>(spec.rfcomm, o);
  }
  if (!spec.port.empty()) wait_for_port_to_appear(spec.port, spec.appear_wait_s);
  return std::make_unique<SerialTransport>(serial_port_for(spec));
}

}  // namespace btsm::link
