#include "host/link/usb_devices.hpp"

#include "host/link/link_error.hpp"

#include <libusb.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>

namespace btsm::link {
namespace fs = std::filesystem;

std::string UsbId::sysfs_name() const {
  std::string s = std::to_string(bus) + "-";
  for (size_t i = 0; i < ports.size(); ++i) s += (i ? "." : "") + std::to_string(ports[i]);
  return s;
}

const char* serial_vendor_kind(uint16_t vid) {
  switch (vid) {
    case 0x2341: return "Arduino";          // Arduino LLC (Uno-type boards, Bluno enumerates as Uno)
    case 0x2A03: return "Arduino.org";
    case 0x0403: return "FTDI";
    case 0x1A86: return "CH340";            // QinHeng
    case 0x10C4: return "CP210x";           // Silicon Labs
    case 0x067B: return "PL2303";           // Prolific
    default: return nullptr;
  }
}

namespace {

std::string read_line(const fs::path& p) {
  std::ifstream in(p);
  std::string s;
  std::getline(in, s);
  return s;
}

std::optional<uint16_t> read_hex16(const fs::path& p) {
  const std::string s = read_line(p);
  if (s.empty() || s.size() > 4) return std::nullopt;
  try {
    size_t used = 0;
    const unsigned long v = std::stoul(s, &used, 16);
    if (used != s.size()) return std::nullopt;
    return static_cast<uint16_t>(v);
  } catch (...) {
    return std::nullopt;
  }
}

bool is_tty_name(const std::string& n) {
  return n.rfind("ttyACM", 0) == 0 || n.rfind("ttyUSB", 0) == 0;
}

}  // namespace

std::vector<UsbSerialDevice> describe_usb_serial(const std::vector<UsbId>& ids, const std::string& sysfs_root,
                                                 const std::string& dev_root) {
  std::vector<UsbSerialDevice> out;
  for (const auto& id : ids) {
    const char* kind = serial_vendor_kind(id.vid);
    if (kind == nullptr || id.ports.empty()) continue;
    UsbSerialDevice d;
    d.id = id;
    d.vendor_kind = kind;
    const fs::path dir = fs::path(sysfs_root) / "bus/usb/devices" / id.sysfs_name();
    std::error_code ec;
    if (!fs::exists(dir, ec)) {
      d.note = "not in sysfs (" + dir.string() + ")";
      out.push_back(d);
      continue;
    }
    d.manufacturer = read_line(dir / "manufacturer");
    d.product = read_line(dir / "product");
    d.serial = read_line(dir / "serial");
    // Interfaces are <name>:<config>.<interface>; cdc_acm puts tty/ttyACMn below the interface,
    // usb-serial drivers (ftdi_sio, ch341, cp210x, pl2303) put ttyUSBn directly below it.
    const std::string prefix = id.sysfs_name() + ":";
    std::vector<fs::path> ifaces;
    for (const auto& e : fs::directory_iterator(dir, ec))
      if (e.path().filename().string().rfind(prefix, 0) == 0) ifaces.push_back(e.path());
    std::sort(ifaces.begin(), ifaces.end());
    for (const auto& iface : ifaces) {
      std::vector<std::string> names;
      for (const auto& e : fs::directory_iterator(iface, ec)) {
        const std::string n = e.path().filename().string();
        if (is_tty_name(n)) names.push_back(n);
        if (n == "tty")
          for (const auto& t : fs::directory_iterator(e.path(), ec))
            if (is_tty_name(t.path().filename().string())) names.push_back(t.path().filename().string());
      }
      if (!names.empty() && d.driver.empty()) {
        const fs::path drv = iface / "driver";
        if (fs::is_symlink(drv, ec)) d.driver = fs::read_symlink(drv, ec).filename().string();
      }
      std::sort(names.begin(), names.end());
      for (const auto& n : names) d.ttys.push_back((fs::path(dev_root) / n).string());
    }
    if (d.ttys.empty())
      d.note = "no tty bound: the serial driver is not loaded or another program (brltty?) claimed the device";
    out.push_back(d);
  }
  return out;
}

std::vector<UsbId> sysfs_usb_ids(const std::string& sysfs_root) {
  std::vector<UsbId> ids;
  const fs::path base = fs::path(sysfs_root) / "bus/usb/devices";
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(base, ec)) {
    const std::string name = e.path().filename().string();
    // Devices are "<bus>-<port>[.<port>...]"; interfaces contain ':' and root hubs are "usbN".
    const auto dash = name.find('-');
    if (dash == std::string::npos || name.find(':') != std::string::npos) continue;
    const auto vid = read_hex16(e.path() / "idVendor");
    const auto pid = read_hex16(e.path() / "idProduct");
    if (!vid || !pid) continue;
    UsbId id;
    id.vid = *vid;
    id.pid = *pid;
    try {
      id.bus = std::stoi(name.substr(0, dash));
      std::string rest = name.substr(dash + 1);
      size_t at = 0;
      while (at <= rest.size()) {
        const auto dot = rest.find('.', at);
        id.ports.push_back(std::stoi(rest.substr(at, dot - at)));
        if (dot == std::string::npos) break;
        at = dot + 1;
      }
    } catch (...) {
      continue;
    }
    ids.push_back(id);
  }
  std::sort(ids.begin(), ids.end(), [](const UsbId& a, const UsbId& b) { return a.sysfs_name() < b.sysfs_name(); });
  return ids;
}

std::vector<UsbId> libusb_ids() {
  libusb_context* ctx = nullptr;
  const int rc = libusb_init(&ctx);
  if (rc != 0) throw LinkError(LinkErrorKind::kIo, std::string("libusb_init: ") + libusb_error_name(rc));
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx, &list);
  std::vector<UsbId> ids;
  for (ssize_t i = 0; i < n; ++i) {
    libusb_device_descriptor desc{};
    if (libusb_get_device_descriptor(list[i], &desc) != 0) continue;
    UsbId id;
    id.vid = desc.idVendor;
    id.pid = desc.idProduct;
    id.bus = libusb_get_bus_number(list[i]);
    uint8_t ports[8];
    const int np = libusb_get_port_numbers(list[i], ports, sizeof ports);
    for (int k = 0; k < np; ++k) id.ports.push_back(ports[k]);
    ids.push_back(id);
  }
  if (list) libusb_free_device_list(list, 1);
  libusb_exit(ctx);
  if (n < 0) throw LinkError(LinkErrorKind::kIo, std::string("libusb_get_device_list: ") +
                                                     libusb_error_name(static_cast<int>(n)));
  std::sort(ids.begin(), ids.end(), [](const UsbId& a, const UsbId& b) { return a.sysfs_name() < b.sysfs_name(); });
  return ids;
}

std::vector<std::string> rfcomm_ttys(const std::string& sysfs_root, const std::string& dev_root) {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(fs::path(sysfs_root) / "class/tty", ec)) {
    const std::string n = e.path().filename().string();
    if (n.rfind("rfcomm", 0) == 0) out.push_back((fs::path(dev_root) / n).string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::optional<std::pair<uint16_t, uint16_t>> parse_vid_pid(const std::string& text) {
  const auto colon = text.find(':');
  if (colon == std::string::npos || colon == 0 || colon > 4 || text.size() - colon - 1 == 0 ||
      text.size() - colon - 1 > 4)
    return std::nullopt;
  auto hex = [](const std::string& s) -> std::optional<uint16_t> {
    for (char c : s)
      if (!std::isxdigit(static_cast<unsigned char>(c))) return std::nullopt;
    return static_cast<uint16_t>(std::stoul(s, nullptr, 16));
  };
  auto v = hex(text.substr(0, colon));
  auto p = hex(text.substr(colon + 1));
  if (!v || !p) return std::nullopt;
  return std::make_pair(*v, *p);
}

std::string tty_for_usb(const std::string& vid_pid, const std::vector<UsbSerialDevice>& devices) {
  const auto vp = parse_vid_pid(vid_pid);
  if (!vp) throw LinkError(LinkErrorKind::kNoDevice, "bad --usb '" + vid_pid + "': expected VID:PID in hex, e.g. 2341:0043");
  std::vector<const UsbSerialDevice*> match;
  for (const auto& d : devices)
    if (d.id.vid == vp->first && d.id.pid == vp->second) match.push_back(&d);
  if (match.empty())
    throw LinkError(LinkErrorKind::kNoDevice, "no USB serial adapter " + vid_pid +
                                                  " found (`btsm list` shows what is connected)");
  if (match.size() > 1) {
    std::string which;
    for (const auto* d : match) which += " " + d->id.sysfs_name() + (d->ttys.empty() ? "" : "=" + d->ttys.front());
    throw LinkError(LinkErrorKind::kNoDevice, "several adapters " + vid_pid + " are connected (" + which.substr(1) +
                                                  "): choose one with --port");
  }
  if (match.front()->ttys.empty())
    throw LinkError(LinkErrorKind::kNoDevice, "USB adapter " + vid_pid + " at " + match.front()->id.sysfs_name() +
                                                  ": " + match.front()->note);
  return match.front()->ttys.front();
}

}  // namespace btsm::link
