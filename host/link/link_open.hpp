#pragma once
// Opening the link a device command asked for: --port, --ble, --rfcomm, --usb, or (none given)
// the only USB serial adapter present.
#include "host/link/transport.hpp"

#include <string>

namespace btsm::link {

struct LinkSpec {
  std::string port, ble, rfcomm, usb;
  int rfcomm_channel = 1;
  double timeout_s = 2.0;  // connect / reply timeout, s
  std::string sysfs_root = "/sys";
  // A --port that does not exist yet is waited for this long (s) when its directory exists: a
  // simulated module started with `&` on the line before makes its pty link a moment later, a
  // board re-enumerates after a reset.
  double appear_wait_s = 5.0;
};

// Throws LinkError (kNoDevice with what to do when nothing is selected or found).
TransportPtr open_link(const LinkSpec& spec);

// The serial port a spec designates (for avrdude): --port, or the tty of --usb / the only
// adapter. BLE and RFCOMM are refused: the bootloader listens on the USB serial port only.
std::string serial_port_for(const LinkSpec& spec);

}  // namespace btsm::link
