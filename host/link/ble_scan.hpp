#pragma once
// BLE discovery without D-Bus: HCI LE scan on the first adapter, advertising reports parsed
// into address, address type, RSSI, name and advertised service UUIDs. Needs CAP_NET_ADMIN and
// CAP_NET_RAW (root or setcap), which the error message says.
#include "host/link/att_pdu.hpp"
#include "host/link/transport.hpp"

#include <functional>
#include <map>
#include <string>

namespace btsm::link {

struct BleAdvertiser {
  std::string address;       // AA:BB:CC:DD:EE:FF
  bool random_address = false;
  int rssi_dbm = 0;          // last report
  std::string name;          // complete or shortened local name, if advertised
  std::vector<att::Uuid> services;  // advertised service UUIDs (16- and 128-bit)
  bool looks_like_module() const;   // advertises or is named like a Bluno / NUS / HM-10
};

// Parses the AD structures of one advertising/scan-response payload into `adv` (name, UUIDs).
// Malformed trailing structures are ignored, never read past `data`.
void parse_advertising_data(std::span<const uint8_t> data, BleAdvertiser& adv);

// Parses an HCI LE Meta event (subevent 0x02 advertising report) starting at the subevent
// byte; merges every report into `found` keyed by address. Returns false if malformed.
bool parse_le_advertising_event(std::span<const uint8_t> meta, std::map<std::string, BleAdvertiser>& found);

struct ScanOptions {
  double seconds = 5.0;     // scan duration, s
  bool active = true;       // active scan asks for scan responses (which carry the name)
  // Called once the adapter scans ("hci0"), before the listening time starts: what a caller says
  // "listening" with, so nothing claims to listen when the adapter is missing or refused.
  std::function<void(const std::string& adapter)> on_listening;
};

// Scans and returns the advertisers sorted by RSSI (strongest first). Throws LinkError.
std::vector<BleAdvertiser> ble_scan(const ScanOptions& opts);

}  // namespace btsm::link
