#include "host/link/ble_scan.hpp"

#include "host/link/fd_stream.hpp"
#include "host/link/link_error.hpp"

#include <bluetooth/bluetooth.h>
#include <bluetooth/hci.h>
#include <bluetooth/hci_lib.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>

namespace btsm::link {

bool BleAdvertiser::looks_like_module() const {
  static const att::Uuid known[] = {att::Uuid::from16(0xDFB0), att::Uuid::from16(0xFFE0),
                                    *att::Uuid::parse("6e400001-b5a3-f393-e0a9-e50e24dcca9e")};
  for (const auto& s : services)
    if (std::find(std::begin(known), std::end(known), s) != std::end(known)) return true;
  return name.find("Bluno") != std::string::npos || name.find("BTSM") != std::string::npos;
}

void parse_advertising_data(std::span<const uint8_t> data, BleAdvertiser& adv) {
  size_t at = 0;
  while (at < data.size()) {
    const size_t len = data[at];
    if (len == 0) break;  // early termination (padding)
    if (at + 1 + len > data.size()) break;  // truncated structure
    const uint8_t type = data[at + 1];
    const auto body = data.subspan(at + 2, len - 1);
    switch (type) {
      case 0x08:  // shortened local name
        if (!adv.name.empty()) break;
        [[fallthrough]];
      case 0x09:  // complete local name
        adv.name.assign(body.begin(), body.end());
        break;
      case 0x02: case 0x03:  // 16-bit service UUIDs (incomplete / complete)
        for (size_t i = 0; i + 1 < body.size(); i += 2) {
          auto u = *att::Uuid::from_le(body.subspan(i, 2));
          if (std::find(adv.services.begin(), adv.services.end(), u) == adv.services.end()) adv.services.push_back(u);
        }
        break;
      case 0x06: case 0x07:  // 128-bit service UUIDs
        for (size_t i = 0; i + 15 < body.size(); i += 16) {
          auto u = *att::Uuid::from_le(body.subspan(i, 16));
          if (std::find(adv.services.begin(), adv.services.end(), u) == adv.services.end()) adv.services.push_back(u);
        }
        break;
      default:
        break;
    }
    at += 1 + len;
  }
}

bool parse_le_advertising_event(std::span<const uint8_t> meta, std::map<std::string, BleAdvertiser>& found) {
  // subevent(1) num_reports(1) then per report: evt_type(1) addr_type(1) addr(6) len(1) data(len) rssi(1)
  if (meta.size() < 2 || meta[0] != EVT_LE_ADVERTISING_REPORT) return false;
  const size_t n = meta[1];
  size_t at = 2;
  for (size_t r = 0; r < n; ++r) {
    if (at + 9 > meta.size()) return false;
    const uint8_t addr_type = meta[at + 1];
    char addr[18];
    std::snprintf(addr, sizeof addr, "%02X:%02X:%02X:%02X:%02X:%02X", meta[at + 7], meta[at + 6],
                  meta[at + 5], meta[at + 4], meta[at + 3], meta[at + 2]);
    const size_t len = meta[at + 8];
    if (at + 9 + len + 1 > meta.size()) return false;
    BleAdvertiser& adv = found[addr];
    adv.address = addr;
    adv.random_address = addr_type == 0x01;
    parse_advertising_data(meta.subspan(at + 9, len), adv);
    adv.rssi_dbm = static_cast<int8_t>(meta[at + 9 + len]);
    at += 9 + len + 1;
  }
  return true;
}

std::vector<BleAdvertiser> ble_scan(const ScanOptions& opts) {
  const int dev_id = hci_get_route(nullptr);
  if (dev_id < 0)
    throw LinkError(LinkErrorKind::kNoDevice,
                    "BLE scan: no Bluetooth adapter found (is it plugged in and up? `hciconfig`, `rfkill list`)");
  const int dd = hci_open_dev(dev_id);
  if (dd < 0) throw errno_error(errno, "BLE scan: open hci" + std::to_string(dev_id));
  struct Closer {
    int dd;
    bool scanning = false;
    ~Closer() {
      if (scanning) hci_le_set_scan_enable(dd, 0x00, 0x00, 1000);
      hci_close_dev(dd);
    }
  } closer{dd};
  const char* perm_hint = "LE scanning needs CAP_NET_ADMIN: run as root or `sudo setcap cap_net_raw,cap_net_admin+eip $(which btsm)`";
  // Interval and window 0x0010 (10 ms): scan continuously.
  if (hci_le_set_scan_parameters(dd, opts.active ? 0x01 : 0x00, htobs(0x0010), htobs(0x0010), 0x00, 0x00, 1000) < 0)
    throw errno_error(errno, "BLE scan: set scan parameters on hci" + std::to_string(dev_id), perm_hint);
  if (hci_le_set_scan_enable(dd, 0x01, 0x00, 1000) < 0)
    throw errno_error(errno, "BLE scan: enable scan on hci" + std::to_string(dev_id), perm_hint);
  closer.scanning = true;

  hci_filter old{};
  socklen_t olen = sizeof old;
  ::getsockopt(dd, SOL_HCI, HCI_FILTER, &old, &olen);
  hci_filter nf{};
  hci_filter_clear(&nf);
  hci_filter_set_ptype(HCI_EVENT_PKT, &nf);
  hci_filter_set_event(EVT_LE_META_EVENT, &nf);
  if (::setsockopt(dd, SOL_HCI, HCI_FILTER, &nf, sizeof nf) < 0)
    throw errno_error(errno, "BLE scan: set HCI filter", perm_hint);
  if (opts.on_listening) opts.on_listening("hci" + std::to_string(dev_id));

  std::map<std::string, BleAdvertiser> found;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(opts.seconds);
  uint8_t buf[HCI_MAX_EVENT_SIZE];
  while (std::chrono::steady_clock::now() < deadline) {
    const auto left = std::chrono::duration_cast<Millis>(deadline - std::chrono::steady_clock::now());
    if (poll_fd(dd, POLLIN, left) == 0) continue;
    const ssize_t n = ::read(dd, buf, sizeof buf);
    if (n < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      throw errno_error(errno, "BLE scan: read HCI events");
    }
    // packet type(1) + event header(2: evt, plen) + meta event
    if (n < 1 + HCI_EVENT_HDR_SIZE || buf[0] != HCI_EVENT_PKT || buf[1] != EVT_LE_META_EVENT) continue;
    parse_le_advertising_event(std::span<const uint8_t>(buf + 1 + HCI_EVENT_HDR_SIZE,
                                                        static_cast<size_t>(n) - 1 - HCI_EVENT_HDR_SIZE),
                               found);
  }
  ::setsockopt(dd, SOL_HCI, HCI_FILTER, &old, sizeof old);
  std::vector<BleAdvertiser> out;
  for (auto& [k, v] : found) out.push_back(std::move(v));
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.rssi_dbm > b.rssi_dbm; });
  return out;
}

}  // namespace btsm::link
