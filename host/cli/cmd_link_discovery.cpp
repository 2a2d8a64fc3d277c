// btsm list | scan | info: finding a module and asking who it is.
#include "cmd_link_support.hpp"
#include "common/model_blob.hpp"
#include "host/link/ble_scan.hpp"
#include "host/link/device_keys.hpp"
#include "host/link/model_blob_file.hpp"
#include "host/link/model_flash.hpp"
#include "host/link/usb_devices.hpp"

#include <fmt/core.h>

#include <iostream>
#include <memory>

namespace btsm::cli {
namespace {

using namespace btsm::link;
using nlohmann::json;

// --- list ----------------------------------------------------------------------------------------

struct ListArgs {
  bool json = false;
  std::string sysfs = "/sys";
};

void run_list(const ListArgs& a) {
  std::vector<UsbId> ids;
  std::string source = "libusb";
  try {
    ids = libusb_ids();
  } catch (const LinkError&) {
    ids = sysfs_usb_ids(a.sysfs);
    source = "sysfs";
  }
  const auto devs = describe_usb_serial(ids, a.sysfs);
  const auto rf = rfcomm_ttys(a.sysfs);
  if (a.json) {
    json j = json::array();
    for (const auto& d : devs)
      j.push_back({{"vid", fmt::format("{:04x}", d.id.vid)}, {"pid", fmt::format("{:04x}", d.id.pid)},
                   {"usb_path", d.id.sysfs_name()}, {"kind", d.vendor_kind}, {"manufacturer", d.manufacturer},
                   {"product", d.product}, {"serial", d.serial}, {"driver", d.driver}, {"ttys", d.ttys},
                   {"note", d.note}});
    for (const auto& r : rf) j.push_back({{"kind", "rfcomm"}, {"ttys", {r}}});
    print_json(j);
    return;
  }
  if (devs.empty() && rf.empty()) {
    std::cout << "no USB serial adapters or RFCOMM ttys found (enumerated with " << source << ")\n";
    return;
  }
  for (const auto& d : devs) {
    std::cout << fmt::format("{:04x}:{:04x}  usb {:<8} {:<8} {}{}{}", d.id.vid, d.id.pid, d.id.sysfs_name(),
                             d.vendor_kind, d.product, d.serial.empty() ? "" : " (serial " + d.serial + ")",
                             d.driver.empty() ? "" : " [" + d.driver + "]");
    for (const auto& t : d.ttys) std::cout << "  " << t;
    if (d.ttys.empty()) std::cout << "  -- " << d.note;
    std::cout << "\n";
  }
  for (const auto& r : rf) std::cout << "rfcomm     " << r << "\n";
}

void register_list(CLI::App& app) {
  auto a = std::make_shared<ListArgs>();
  auto* c = app.add_subcommand("list", "List serial/USB adapters a module can be behind (USB VID/PID, port path, tty)");
  c->footer(
      "Lists USB devices of known serial vendors (Arduino 2341, Arduino.org 2A03, FTDI 0403, CH340 1A86,\n"
      "CP210x 10C4, PL2303 067B) with bus-port path, product strings, kernel driver and tty, plus bound\n"
      "RFCOMM ttys. A device without tty usually means its driver is missing or another program\n"
      "(brltty) claimed it. Use the tty with --port, or the VID:PID with --usb.");
  c->add_flag("--json", a->json, "print the list as JSON");
  c->add_option("--sysfs", a->sysfs, "sysfs root (for tests)")->group("");
  c->callback([a] { guarded([&] { run_list(*a); }); });
}

// --- scan ----------------------------------------------------------------------------------------

struct ScanArgs {
  double seconds = 5.0;
  bool all = false, json = false, passive = false;
};

void print_advertisers(const ScanArgs& a, const std::vector<BleAdvertiser>& found) {
  json j = json::array();
  size_t shown = 0;
  for (const auto& adv : found) {
    if (!a.all && !adv.looks_like_module()) continue;
    ++shown;
    std::vector<std::string> uuids;
    for (const auto& u : adv.services) uuids.push_back(u.str());
    if (a.json) {
      j.push_back({{"address", adv.address}, {"random_address", adv.random_address}, {"rssi_dbm", adv.rssi_dbm},
                   {"name", adv.name}, {"services", uuids}});
    } else {
      std::string svc;
      for (const auto& u : uuids) svc += " " + u;
      std::cout << fmt::format("{}{:<8} {:>4} dBm  {:<20}{}\n", adv.address, adv.random_address ? "/random" : "",
                               adv.rssi_dbm, adv.name.empty() ? "(no name)" : adv.name, svc);
    }
  }
  if (a.json) print_json(j);
  else if (shown == 0)
    std::cout << fmt::format("no module-like advertisers ({} others seen; --all lists them)\n", found.size());
}

void run_scan(const ScanArgs& a) {
  ScanOptions so;
  so.seconds = a.seconds;
  so.active = !a.passive;
  so.on_listening = [&](const std::string& adapter) {
    std::cerr << fmt::format("scan: listening for {:.1f} s on {} ...\n", a.seconds, adapter);
  };
  print_advertisers(a, ble_scan(so));
}

void register_scan(CLI::App& app) {
  auto a = std::make_shared<ScanArgs>();
  auto* c = app.add_subcommand("scan", "Scan for BLE modules (HCI LE scan, no D-Bus; needs root or CAP_NET_ADMIN)");
  c->footer(
      "Shows advertisers that look like a module (Bluno 0xDFB0, Nordic UART, HM-10 0xFFE0, or a name\n"
      "containing Bluno/BTSM); --all shows every advertiser. Connect with `--ble ADDR` (append /random\n"
      "for a random address). Grant the capability once with:\n"
      "  sudo setcap cap_net_raw,cap_net_admin+eip $(which btsm)");
  c->add_option("--seconds", a->seconds, "scan duration, s")->capture_default_str()->check(CLI::Range(0.5, 120.0));
  c->add_flag("--all", a->all, "list every advertiser, not only module-like ones");
  c->add_flag("--passive", a->passive, "passive scan (no scan requests; names may be missing)");
  c->add_flag("--json", a->json, "print the advertisers as JSON");
  c->callback([a] { guarded([&] { run_scan(*a); }); });
}

// --- info ----------------------------------------------------------------------------------------

struct InfoArgs {
  LinkOptions link;
  bool json = false;
};

// The active model's channel map against the module's roles (the blob's role bytes, read back).
std::vector<std::string> model_channel_map(Session& session, const ModuleIdentity& id, json& j) {
  std::vector<std::string> lines;
  if (id.info.model_state != static_cast<uint8_t>(wire::ModelState::Active)) return lines;
  const ActiveModelMap am = read_active_model_map(session);
  j["model_format_version"] = am.version;
  if (am.version != kReducedModelVersion) {
    lines.push_back(fmt::format("the active model has format version {}, not {}: no channel map", am.version,
                                kReducedModelVersion));
    return lines;
  }
  const ChannelMapCheck mc = check_channel_map(am.roles, id.roles.role);
  json cm = json::array();
  for (const auto& ch : mc.channels) {
    const char* model = ch.model_role == kModelRoleUnchecked ? "unchecked" : wire::channel_role_name(ch.model_role);
    const char* module = wire::channel_role_name(ch.module_role);
    cm.push_back({{"model", model ? model : "?"}, {"module", module ? module : "?"}, {"verdict", ch.verdict}});
    lines.push_back(ch.text);
  }
  j["model_channel_map"] = cm;
  if (am.n_breakpoints >= 2) {
    json sp = json::array();
    for (uint8_t i = 1; i < am.n_breakpoints; ++i) sp.push_back(am.speed_rpm[i]);
    j["model_speeds_rpm"] = sp;
    lines.insert(lines.begin(), "speeds: " + describe_model_speeds(am.speed_rpm, am.n_breakpoints));
  }
  for (const auto& w : mc.conflicts) lines.push_back("CONFLICT: " + w);
  for (const auto& w : mc.warnings) lines.push_back("warning: " + w);
  return lines;
}

void run_info(const InfoArgs& a) {
  auto conn = connect(a.link);
  const ModuleIdentity id = identify(*conn.session);
  json j = info_json(id);
  const std::vector<std::string> map_lines = model_channel_map(*conn.session, id, j);
  if (a.json) {
    print_json(j);
    return;
  }
  std::cout << fmt::format("module {}  firmware {}  protocol {}  via {}\n", j["device_id"].get<std::string>(),
                           j["firmware_version"].get<std::string>(), id.info.protocol_version, id.link);
  std::cout << fmt::format("model: {} (crc {}, seq {})  uptime {} s\n", j["model_state"].get<std::string>(),
                           j["model_crc"].get<std::string>(), id.info.model_seq, id.info.uptime_s);
  std::cout << "channels: " << id.roles.describe() << "\n";
  if (!map_lines.empty()) std::cout << "model channel map:\n";
  for (const auto& l : map_lines) std::cout << "  " << l << "\n";
  std::cout << "counters:";
  for (const auto& [k, v] : j["counters"].items()) std::cout << " " << k << "=" << v;
  std::cout << "\n";
}

void register_info(CLI::App& app) {
  auto a = std::make_shared<InfoArgs>();
  auto* c = app.add_subcommand("info", "Show the module's identity, firmware, model state, channel roles and fault counters");
  add_link_options(*c, a->link);
  c->add_flag("--json", a->json, "print as JSON");
  c->callback([a] { guarded([&] { run_info(*a); }); });
}

}  // namespace

void register_link_discovery_commands(CLI::App& app) {
  register_list(app);
  register_scan(app);
  register_info(app);
}

}  // namespace btsm::cli
