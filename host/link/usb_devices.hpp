#pragma once
// Finding modules on USB: libusb enumerates devices (VID/PID, bus, port path); sysfs maps each
// one to the tty its kernel driver created (/dev/ttyACM*, /dev/ttyUSB*) and gives its strings.
// The sysfs root is a parameter so the mapping is tested on a fake tree.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace btsm::link {

// One USB device as the enumerator sees it.
struct UsbId {
  uint16_t vid = 0, pid = 0;
  int bus = 0;
  std::vector<int> ports;  // port numbers from the root hub down
  std::string sysfs_name() const;  // "1-2.3" (the kernel's name of the device)
};

struct UsbSerialDevice {
  UsbId id;
  std::string vendor_kind;       // "Arduino", "FTDI", "CH340", "CP210x", "PL2303"
  std::string manufacturer, product, serial;  // USB strings from sysfs (may be empty)
  std::string driver;            // kernel driver of the data interface (cdc_acm, ftdi_sio, ch341...)
  std::vector<std::string> ttys; // "/dev/ttyACM0"
  std::string note;              // why there is no tty, if none
};

// Vendor IDs of boards and USB-serial bridges a module can sit behind, with names.
// nullptr when the vendor is not a known serial adapter.
const char* serial_vendor_kind(uint16_t vid);

// Looks each id up in <sysfs_root>/bus/usb/devices/<name>; keeps only known serial vendors.
// Device nodes are reported as <dev_root>/<ttyname>.
std::vector<UsbSerialDevice> describe_usb_serial(const std::vector<UsbId>& ids, const std::string& sysfs_root,
                                                 const std::string& dev_root = "/dev");

// Enumeration sources: libusb (production), or the sysfs tree itself (fallback and tests).
// libusb_ids throws LinkError(kIo) if libusb cannot initialise.
std::vector<UsbId> libusb_ids();
std::vector<UsbId> sysfs_usb_ids(const std::string& sysfs_root);

// Other serial ports worth listing: bound RFCOMM ttys (/dev/rfcommN) from <sysfs_root>/class/tty.
std::vector<std::string> rfcomm_ttys(const std::string& sysfs_root, const std::string& dev_root = "/dev");

// "2341:0043" -> {vid, pid}; nullopt when malformed.
std::optional<std::pair<uint16_t, uint16_t>> parse_vid_pid(const std::string& text);

// The tty of the single adapter matching VID:PID. Throws LinkError(kNoDevice) naming what was
// found when there is none, several, or the device has no tty (driver missing / brltty).
std::string tty_for_usb(const std::string& vid_pid, const std::vector<UsbSerialDevice>& devices);

}  // namespace btsm::link
