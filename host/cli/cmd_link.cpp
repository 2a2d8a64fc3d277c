// btsm list | scan | info | monitor | record | set-speed | set-config | ack-alarm | flash-model |
// flash-firmware | keys — talking to a module (link engineer). The logic lives in host/link/;
// this file parses options, prints, and maps errors onto exit codes.
#include "cli_support.hpp"
#include "commands.hpp"
#include "common/wire_messages.hpp"
#include "host/link/ble_scan.hpp"
#include "host/link/device_keys.hpp"
#include "host/link/firmware_image.hpp"
#include "host/link/link_error.hpp"
#include "host/link/link_open.hpp"
#include "host/link/model_flash.hpp"
#include "host/link/recorder.hpp"
#include "host/link/session.hpp"
#include "host/link/usb_devices.hpp"

#include <fmt/core.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>

namespace btsm::cli {
namespace {

using namespace btsm::link;
using nlohmann::json;

// --- shared plumbing ---------------------------------------------------------------------------

std::atomic<bool> g_stop{false};
extern "C" void on_interrupt(int) { g_stop = true; }

// Ctrl-C ends monitor/record cleanly (the CSV gets its summary) instead of killing the process.
void install_interrupt_handler() {
  struct sigaction sa {};
  sa.sa_handler = on_interrupt;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

int exit_code_for(LinkErrorKind k) {
  switch (k) {
    case LinkErrorKind::kNoDevice:
    case LinkErrorKind::kPermissionDenied:
    case LinkErrorKind::kDeviceGone:
    case LinkErrorKind::kTimeout:
    case LinkErrorKind::kUnsupported:
      return kExitDevice;
    default:
      return kExitFailure;
  }
}

// Runs a command body, turning library exceptions into CommandErrors with exit codes.
template <class F>
void guarded(F&& body) {
  try {
    body();
  } catch (const CommandError&) {
    throw;
  } catch (const NackError& e) {
    throw CommandError(kExitFailure, e.what());
  } catch (const LinkError& e) {
    throw CommandError(exit_code_for(e.kind()), e.what());
  } catch (const std::invalid_argument& e) {
    throw CommandError(kExitUsage, e.what());
  } catch (const std::runtime_error& e) {
    throw CommandError(kExitFailure, e.what());
  }
}

LinkSpec spec_from(const LinkOptions& o) {
  LinkSpec s;
  s.port = o.port;
  s.ble = o.ble;
  s.rfcomm = o.rfcomm;
  s.usb = o.usb;
  s.rfcomm_channel = o.rfcomm_channel;
  s.timeout_s = o.timeout_s;
  return s;
}

struct Connection {
  TransportPtr transport;
  std::unique_ptr<Session> session;
};

Connection connect(const LinkOptions& o) {
  if (!(o.timeout_s > 0)) throw CommandError(kExitUsage, "--timeout must be positive");
  Connection c;
  c.transport = open_link(spec_from(o));
  SessionOptions so;
  so.reply_timeout = Millis(static_cast<long>(o.timeout_s * 1000));
  c.session = std::make_unique<Session>(*c.transport, so);
  return c;
}

json info_json(const ModuleIdentity& id) {
  const auto& i = id.info;
  json roles = json::object();
  for (int k = 0; k < wire::kChannels; ++k) {
    const char* n = wire::channel_role_name(id.roles.role[k]);
    roles[fmt::format("T{}", k + 1)] = n ? n : "unknown";
  }
  const char* states[] = {"none", "active", "rejected"};
  return json{{"link", id.link},
              {"device_id", device_id_text(i.device_id)},
              {"firmware_version", firmware_version(i)},
              {"protocol_version", i.protocol_version},
              {"model_state", i.model_state < 3 ? states[i.model_state] : "unknown"},
              {"model_crc", fmt::format("{:08x}", i.model_crc)},
              {"model_seq", i.model_seq},
              {"uptime_s", i.uptime_s},
              {"reset_cause", i.reset_cause},
              {"channel_roles", roles},
              {"channel_roles_from_module", id.roles.from_module},
              {"counters",
               {{"adc_timeouts", i.adc_timeouts},
                {"frame_errors", i.frame_errors},
                {"kalman_rejects", i.kalman_rejects},
                {"sensor_faults", i.sensor_faults},
                {"resets", i.resets},
                {"watchdog_resets", i.watchdog_resets}}}};
}

json sample_json(const wire::Sample& s, const SampleEvent* ev) {
  json ch = json::array();
  for (int k = 0; k < wire::kChannels; ++k) {
    const double t = mk_to_c(s.temp_mK[k]), p = mk_to_c(s.predicted_mK[k]);
    ch.push_back({{"channel", k + 1},
                  {"temp_c", std::isnan(t) ? json(nullptr) : json(t)},
                  {"predicted_c", std::isnan(p) ? json(nullptr) : json(p)},
                  {"state", wire::diag_state_name(s.channel_status[k])},
                  {"status", s.channel_status[k]}});
  }
  json j{{"sample_index", s.sample_index}, {"time_ms", s.time_ms}, {"speed_rpm", s.speed_rpm},
         {"overall", wire::diag_state_name(s.overall)},
         {"alarm_latched", (s.overall & wire::kOverallAlarmLatched) != 0},
         {"model_active", (s.overall & wire::kOverallModelActive) != 0}, {"channels", ch}};
  if (ev && ev->gap) j["lost_before"] = {ev->gap->first, ev->gap->last};
  if (ev && ev->restarted) j["module_restarted"] = true;
  return j;
}

// Key names accepted by set-config: the wire names ("sample_period_ms", "channel_role_3") or
// a number.
uint8_t parse_config_key(const std::string& text) {
  for (int k = 0; k < 256; ++k) {
    const char* n = wire::config_key_name(static_cast<uint8_t>(k));
    if (n && text == n) return static_cast<uint8_t>(k);
  }
  try {
    size_t used = 0;
    const unsigned long v = std::stoul(text, &used, 0);
    wire::ConfigRange r{};
    if (used == text.size() && v < 256 && wire::config_key_range(static_cast<uint8_t>(v), r))
      return static_cast<uint8_t>(v);
  } catch (...) {
  }
  std::string names;
  for (int k = 0; k < 256; ++k)
    if (const char* n = wire::config_key_name(static_cast<uint8_t>(k))) names += std::string(names.empty() ? "" : ", ") + n;
  throw CommandError(kExitUsage, "unknown configuration key '" + text + "' (known: " + names + ")");
}

int32_t parse_config_value(uint8_t key, const std::string& text) {
  if (key >= wire::kChannelRoleKeyFirst && key <= wire::kChannelRoleKeyLast) {
    for (uint8_t r = 0; r < wire::kChannelRoleCount; ++r)
      if (text == wire::channel_role_name(r)) return r;
  }
  try {
    size_t used = 0;
    const long long v = std::stoll(text, &used, 10);
    if (used == text.size() && v >= INT32_MIN && v <= INT32_MAX) return static_cast<int32_t>(v);
  } catch (...) {
  }
  throw CommandError(kExitUsage, fmt::format("value '{}' for {} is not an integer{}", text, wire::config_key_name(key),
                                             key >= wire::kChannelRoleKeyFirst ? " or a role name (ambient, front_bearing, "
                                                                                 "rear_bearing, housing, motor, coolant, "
                                                                                 "spare, shaft, disabled)"
                                                                               : ""));
}

std::string default_hex_path() {
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) return (exe.parent_path() / "btsm-fw-bluno.hex").string();
  return "build/bin/btsm-fw-bluno.hex";
}

uint32_t parse_device_id_or_throw(const std::string& text) {
  const auto id = parse_device_id(text);
  if (!id) throw CommandError(kExitUsage, "device id '" + text + "' is not hex (up to 8 digits, e.g. 0000de71)");
  return *id;
}

// --- commands ----------------------------------------------------------------------------------

void register_list(CLI::App& app) {
  struct A {
    bool json = false;
    std::string sysfs = "/sys";
  };
  auto a = std::make_shared<A>();
  auto* c = app.add_subcommand("list", "List serial/USB adapters a module can be behind (USB VID/PID, port path, tty)");
  c->footer(
      "Lists USB devices of known serial vendors (Arduino 2341, Arduino.org 2A03, FTDI 0403, CH340 1A86,\n"
      "CP210x 10C4, PL2303 067B) with bus-port path, product strings, kernel driver and tty, plus bound\n"
      "RFCOMM ttys. A device without tty usually means its driver is missing or another program\n"
      "(brltty) claimed it. Use the tty with --port, or the VID:PID with --usb.");
  c->add_flag("--json", a->json, "print the list as JSON");
  c->add_option("--sysfs", a->sysfs, "sysfs root (for tests)")->group("");
  c->callback([a] {
    guarded([&] {
      std::vector<UsbId> ids;
      std::string source = "libusb";
      try {
        ids = libusb_ids();
      } catch (const LinkError&) {
        ids = sysfs_usb_ids(a->sysfs);
        source = "sysfs";
      }
      const auto devs = describe_usb_serial(ids, a->sysfs);
      const auto rf = rfcomm_ttys(a->sysfs);
      if (a->json) {
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
    });
  });
}

void register_scan(CLI::App& app) {
  struct A {
    double seconds = 5.0;
    bool all = false, json = false, passive = false;
  };
  auto a = std::make_shared<A>();
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
  c->callback([a] {
    guarded([&] {
      ScanOptions so;
      so.seconds = a->seconds;
      so.active = !a->passive;
      std::cerr << fmt::format("scan: listening for {:.1f} s ...\n", a->seconds);
      const auto found = ble_scan(so);
      json j = json::array();
      size_t shown = 0;
      for (const auto& adv : found) {
        if (!a->all && !adv.looks_like_module()) continue;
        ++shown;
        std::vector<std::string> uuids;
        for (const auto& u : adv.services) uuids.push_back(u.str());
        if (a->json) {
          j.push_back({{"address", adv.address}, {"random_address", adv.random_address}, {"rssi_dbm", adv.rssi_dbm},
                       {"name", adv.name}, {"services", uuids}});
        } else {
          std::string svc;
          for (const auto& u : uuids) svc += " " + u;
          std::cout << fmt::format("{}{:<8} {:>4} dBm  {:<20}{}\n", adv.address, adv.random_address ? "/random" : "",
                                   adv.rssi_dbm, adv.name.empty() ? "(no name)" : adv.name, svc);
        }
      }
      if (a->json) print_json(j);
      else if (shown == 0)
        std::cout << fmt::format("no module-like advertisers ({} others seen; --all lists them)\n", found.size());
    });
  });
}

void register_info(CLI::App& app) {
  struct A {
    LinkOptions link;
    bool json = false;
  };
  auto a = std::make_shared<A>();
  auto* c = app.add_subcommand("info", "Show the module's identity, firmware, model state, channel roles and fault counters");
  add_link_options(*c, a->link);
  c->add_flag("--json", a->json, "print as JSON");
  c->callback([a] {
    guarded([&] {
      auto conn = connect(a->link);
      const ModuleIdentity id = identify(*conn.session);
      const json j = info_json(id);
      if (a->json) {
        print_json(j);
        return;
      }
      std::cout << fmt::format("module {}  firmware {}  protocol {}  via {}\n", j["device_id"].get<std::string>(),
                               j["firmware_version"].get<std::string>(), id.info.protocol_version, id.link);
      std::cout << fmt::format("model: {} (crc {}, seq {})  uptime {} s\n", j["model_state"].get<std::string>(),
                               j["model_crc"].get<std::string>(), id.info.model_seq, id.info.uptime_s);
      std::cout << "channels: " << id.roles.describe() << "\n";
      std::cout << "counters:";
      for (const auto& [k, v] : j["counters"].items()) std::cout << " " << k << "=" << v;
      std::cout << "\n";
    });
  });
}

void register_monitor(CLI::App& app) {
  struct A {
    LinkOptions link;
    bool json = false;
    uint64_t count = 0;
    double reconnect = 30;
  };
  auto a = std::make_shared<A>();
  auto* c = app.add_subcommand("monitor", "Live view of temperatures, predictions and diagnosis, one line per sample");
  c->footer(
      "Each line: sample index, speed, then per channel the measured temperature (degC), the model's\n"
      "prediction when a model is active, and the diagnosis when not NORMAL (WARN, ALARM, SENSOR_FAULT\n"
      "with fault bits open/short/adc/ref); last the overall state. Lost samples are reported on\n"
      "stderr, never filled in. Ctrl-C or --count ends it. --json prints one JSON object per line.");
  add_link_options(*c, a->link);
  c->add_flag("--json", a->json, "one JSON object per sample (NDJSON)");
  c->add_option("--count", a->count, "stop after N samples (0 = until Ctrl-C)")->capture_default_str();
  c->add_option("--reconnect", a->reconnect, "keep reopening a lost link for this many seconds (0 = exit)")
      ->capture_default_str();
  c->callback([a] {
    guarded([&] {
      install_interrupt_handler();
      auto conn = connect(a->link);
      const ModuleIdentity id = identify(*conn.session);
      if (!a->json)
        std::cerr << fmt::format("monitor: module {} firmware {} via {}; {}\n", device_id_text(id.info.device_id),
                                 firmware_version(id.info), id.link, id.roles.describe());
      uint64_t shown = 0, reconnects = 0;
      auto last_rx = std::chrono::steady_clock::now();
      while (!g_stop && (a->count == 0 || shown < a->count)) {
        auto ev = next_sample_with_reconnect(*conn.session, Millis(250), a->reconnect, reconnects, &g_stop);
        if (!ev) {
          if (std::chrono::steady_clock::now() - last_rx > std::chrono::seconds(60))
            throw LinkError(LinkErrorKind::kTimeout, conn.transport->describe() + ": no sample for 60 s");
          continue;
        }
        last_rx = std::chrono::steady_clock::now();
        if (a->json) {
          std::cout << sample_json(ev->sample, &*ev).dump() << std::endl;
        } else {
          if (ev->restarted) std::cerr << "monitor: module restarted (sample index went back)\n";
          if (ev->gap)
            std::cerr << fmt::format("monitor: {} sample(s) lost ({}-{})\n", ev->gap->count(), ev->gap->first,
                                     ev->gap->last);
          std::cout << format_sample_line(ev->sample, id.roles) << std::endl;
        }
        ++shown;
      }
    });
  });
}

void register_record(CLI::App& app) {
  struct A {
    LinkOptions link;
    std::string out;
    double duration = 0;
    uint64_t samples = 0;
    double reconnect = 30;
    bool json = false;
  };
  auto a = std::make_shared<A>();
  auto* c = app.add_subcommand("record", "Record samples into a recording CSV (the input of `btsm fit`)");
  c->footer(
      "CSV: '# key: value' metadata (module_id, firmware_version, link, channel_roles, ambient_channel),\n"
      "header time_s,speed_rpm,ambient_c,T<k>... (one column per channel that is neither disabled nor\n"
      "ambient, named by its hardware channel number), then one row per sample: module time since the\n"
      "first sample (s), speed (rpm), ambient channel (degC), temperatures (degC, empty = missing).\n"
      "Lost samples are never invented: each gap is a '# dropped: a-b' line (sample_index range) after\n"
      "the rows, with samples, lost_samples, module_restarts, link_reconnects and stop_reason.\n"
      "Progress goes to stderr; Ctrl-C stops cleanly.\n"
      "  btsm record --port /tmp/btsm-sim --out rec.csv --duration 3600");
  add_link_options(*c, a->link);
  c->add_option("--out", a->out, "CSV file to write")->required();
  c->add_option("--duration", a->duration, "stop after this much module time, s (0 = no limit)")->capture_default_str();
  c->add_option("--samples", a->samples, "stop after this many rows (0 = no limit)")->capture_default_str();
  c->add_option("--reconnect", a->reconnect, "keep reopening a lost link for this many seconds (0 = fail)")
      ->capture_default_str();
  c->add_flag("--json", a->json, "print the summary as JSON");
  c->callback([a] {
    guarded([&] {
      install_interrupt_handler();
      auto conn = connect(a->link);
      const ModuleIdentity id = identify(*conn.session);
      std::cerr << fmt::format("record: module {} firmware {} via {} -> {}\n", device_id_text(id.info.device_id),
                               firmware_version(id.info), id.link, a->out);
      RecordOptions ro;
      ro.out_path = a->out;
      ro.duration_s = a->duration;
      ro.max_samples = a->samples;
      ro.reconnect_s = a->reconnect;
      ro.stop = &g_stop;
      const bool tty = ::isatty(STDERR_FILENO);
      ro.progress = [&](const RecordProgress& p) {
        const std::string line = fmt::format("record: {} rows, {} lost, {} restarts, {:.0f} s", p.rows, p.lost,
                                             p.restarts, p.elapsed_s);
        if (tty) std::cerr << "\r" << line << std::flush;
        else if (p.rows % 100 == 0) std::cerr << line << "\n";
      };
      const RecordSummary s = record(*conn.session, id, ro);
      if (tty) std::cerr << "\n";
      std::cerr << fmt::format("record: {} rows written to {}, {} samples lost in {} gap(s), stopped: {}\n", s.rows,
                               a->out, s.lost, s.gaps.size(), s.stop_reason);
      if (a->json) {
        json gaps = json::array();
        for (const auto& g : s.gaps) gaps.push_back({g.first, g.last});
        print_json({{"out", a->out}, {"rows", s.rows}, {"lost", s.lost}, {"gaps", gaps}, {"restarts", s.restarts},
                    {"reconnects", s.reconnects}, {"rejected_frames", s.invalid_frames}, {"stop_reason", s.stop_reason}});
      }
    });
  });
}

void register_set_speed(CLI::App& app) {
  struct A {
    LinkOptions link;
    std::string rpm;
  };
  auto a = std::make_shared<A>();
  auto* c = app.add_subcommand("set-speed", "Tell the module the spindle speed its model uses (rpm, or 'tach' to measure it)");
  c->footer("The speed is held in the module's RAM: after a reset it measures the tach input again.\n"
            "  btsm set-speed --port /dev/ttyACM0 6000\n  btsm set-speed --ble C8:A0:30:F1:02:03 tach");
  add_link_options(*c, a->link);
  c->add_option("speed", a->rpm, "rpm 0..60000, or 'tach' for the tachometer input")->required();
  c->callback([a] {
    guarded([&] {
      uint16_t value = wire::kSpeedFromTach;
      if (a->rpm != "tach") {
        size_t used = 0;
        long v = -1;
        try {
          v = std::stol(a->rpm, &used);
        } catch (...) {
        }
        if (used != a->rpm.size() || v < 0 || v > wire::kMaxSpeedRpm)
          throw CommandError(kExitUsage, fmt::format("speed '{}': expected 0..{} rpm or 'tach'", a->rpm, wire::kMaxSpeedRpm));
        value = static_cast<uint16_t>(v);
      }
      auto conn = connect(a->link);
      conn.session->set_speed(value);
      std::cerr << "set-speed: " << (a->rpm == "tach" ? std::string("speed from tach") : a->rpm + " rpm") << " acknowledged\n";
    });
  });
}

void register_set_config(CLI::App& app) {
  struct A {
    LinkOptions link;
    std::string key, value;
  };
  auto a = std::make_shared<A>();
  auto* c = app.add_subcommand("set-config", "Set one module configuration value (checked against its range first)");
  std::string keys;
  for (int k = 0; k < 256; ++k) {
    wire::ConfigRange r{};
    const char* n = wire::config_key_name(static_cast<uint8_t>(k));
    if (n && wire::config_key_range(static_cast<uint8_t>(k), r))
      keys += fmt::format("  {:<22} [{} .. {}], default {}\n", n, r.min, r.max, r.default_value);
  }
  c->footer("Keys:\n" + keys +
            "channel_role_N takes a role name: disabled, ambient, front_bearing, rear_bearing, housing,\n"
            "motor, coolant, spare, shaft.\n  btsm set-config --port /dev/ttyACM0 sample_period_ms 2000");
  add_link_options(*c, a->link);
  c->add_option("key", a->key, "configuration key name (or number)")->required();
  c->add_option("value", a->value, "integer value (or role name)")->required();
  c->callback([a] {
    guarded([&] {
      const uint8_t key = parse_config_key(a->key);
      const int32_t value = parse_config_value(key, a->value);
      wire::ConfigRange r{};
      wire::config_key_range(key, r);
      if (value < r.min || value > r.max)
        throw CommandError(kExitUsage, fmt::format("{} = {} is outside [{}, {}]", wire::config_key_name(key), value,
                                                   r.min, r.max));
      auto conn = connect(a->link);
      conn.session->set_config(key, value);
      std::cerr << fmt::format("set-config: {} = {} acknowledged\n", wire::config_key_name(key), value);
    });
  });
}

void register_ack_alarm(CLI::App& app) {
  auto link = std::make_shared<LinkOptions>();
  auto* c = app.add_subcommand("ack-alarm", "Acknowledge a latched ALARM (it clears once the cause is gone)");
  add_link_options(*c, *link);
  c->callback([link] {
    guarded([&] {
      auto conn = connect(*link);
      conn.session->ack_alarm();
      std::cerr << "ack-alarm: acknowledged\n";
    });
  });
}

void register_flash_model(CLI::App& app) {
  struct A {
    LinkOptions link;
    std::string file, key_file;
    bool json = false;
  };
  auto a = std::make_shared<A>();
  auto* c = app.add_subcommand("flash-model", "Upload a reduced model blob to the module, authenticated, with read-back");
  c->footer(
      "FILE is the blob written by `btsm reduce --blob model.bin`, or a JSON holding it as \"blob_hex\"\n"
      "(or naming it with \"blob_file\"). The blob is validated first (size 464, CRC, version, poles,\n"
      "gains). The upload: GET_INFO (device id) -> MODEL_BEGIN -> AUTH_CHALLENGE (single-use nonce) ->\n"
      "chunks that each fit one 20-byte BLE write, each acknowledged -> MODEL_COMMIT with\n"
      "HMAC-SHA256(device key, nonce || blob) -> MODEL_READ of the whole blob and CRC compare -> INFO\n"
      "shows the new CRC and sequence. The key comes from the key store (`btsm keys path`) for the\n"
      "module's device id. The module keeps its previous model unless the commit is accepted; a\n"
      "refusal prints the module's reason (AUTH_FAILED = wrong key, BLOB_INVALID, ...).");
  add_link_options(*c, a->link);
  c->add_option("file", a->file, "model blob (.bin) or JSON with the blob")->required()->check(CLI::ExistingFile);
  c->add_option("--key-file", a->key_file, "use this key file instead of the key store (must be mode 0600)");
  c->add_flag("--json", a->json, "print the summary as JSON");
  c->callback([a] {
    guarded([&] {
      const auto blob = load_model_blob(a->file);
      const std::string why = check_model_blob(blob);
      if (!why.empty()) throw CommandError(kExitUsage, a->file + ": " + why);
      auto conn = connect(a->link);
      const auto info = conn.session->get_info();
      DeviceKey key{};
      if (!a->key_file.empty()) {
        const auto p = std::filesystem::absolute(a->key_file);
        const auto stem = p.stem().string();
        const auto id = parse_device_id(stem);
        KeyStore ks(p.parent_path().string());
        if (!id || ks.path_for(*id) != p.string())
          throw CommandError(kExitUsage, "--key-file must be named <device_id>.key (8 hex digits), got " + a->key_file);
        if (*id != info.device_id)
          throw CommandError(kExitUsage, fmt::format("--key-file is for device {}, the module is {}", stem,
                                                     device_id_text(info.device_id)));
        key = ks.load(*id);
      } else {
        key = KeyStore::from_environment().load(info.device_id);
      }
      const bool tty = ::isatty(STDERR_FILENO);
      FlashOptions fo;
      fo.progress = [&](const FlashProgress& p) {
        if (!tty) return;
        std::cerr << fmt::format("\rflash-model: {:<7} {:>4}/{} bytes", p.phase, p.bytes_sent, p.total) << std::flush;
      };
      const FlashSummary s = flash_model(*conn.session, blob, key, fo);
      if (tty) std::cerr << "\n";
      std::cerr << fmt::format("flash-model: module {} now runs model crc {:08x} (seq {} -> {}), {} chunks, read-back "
                               "verified\n",
                               device_id_text(s.device_id), s.model_crc, s.model_seq_before, s.model_seq_after, s.chunks);
      if (a->json)
        print_json({{"device_id", device_id_text(s.device_id)}, {"bytes", s.blob_size}, {"chunks", s.chunks},
                    {"max_chunk_frame_bytes", s.max_chunk_frame}, {"offset_resyncs", s.offset_resyncs},
                    {"commit_confirmed_by_info", s.commit_confirmed_by_info},
                    {"model_crc", fmt::format("{:08x}", s.model_crc)}, {"model_seq", s.model_seq_after},
                    {"verified", s.verified}});
    });
  });
}

void register_flash_firmware(CLI::App& app) {
  struct A {
    LinkOptions link;
    std::string hex, out, device_id, avrdude = "avrdude";
    bool dry_run = false, new_key = false;
  };
  auto a = std::make_shared<A>();
  auto* c = app.add_subcommand("flash-firmware", "Patch the device key into the firmware image and program it with avrdude");
  c->footer(
      "Writes the 64-byte key record (firmware/device_key.hpp: magic, device id, 32-byte key, CRC-32)\n"
      "at flash 0x7DC0 of the image, saves the patched image (mode 0600: it holds the key), then runs\n"
      "  avrdude -p atmega328p -c arduino -b 115200 -P PORT -D -U flash:w:PATCHED:i\n"
      "(the Bluno is programmed like an Arduino Uno through its USB port). The key is taken from the\n"
      "key store for --device-id; --new-key generates and stores one first. --dry-run writes the\n"
      "patched image and prints the command without running it.\n"
      "  btsm flash-firmware --device-id 0000de71 --new-key --port /dev/ttyACM0");
  add_link_options(*c, a->link);
  c->add_option("--device-id", a->device_id, "device id to give this module (hex, e.g. 0000de71)")->required();
  c->add_option("--hex", a->hex, "firmware image (default: btsm-fw-bluno.hex next to btsm)");
  c->add_option("--out", a->out, "patched image path (default: btsm-fw-<device_id>.hex in the current directory)");
  c->add_flag("--new-key", a->new_key, "generate and store a key for this device id if it has none");
  c->add_flag("--dry-run", a->dry_run, "patch and print the avrdude command, do not run it");
  c->add_option("--avrdude", a->avrdude, "avrdude executable")->capture_default_str();
  c->callback([a] {
    guarded([&] {
      const uint32_t id = parse_device_id_or_throw(a->device_id);
      KeyStore ks = KeyStore::from_environment();
      if (!ks.exists(id)) {
        if (!a->new_key)
          throw CommandError(kExitUsage, fmt::format("no key for device {} in {}: pass --new-key, or `btsm keys import {} HEX`",
                                                     device_id_text(id), ks.dir(), device_id_text(id)));
        ks.save(id, KeyStore::generate());
        std::cerr << "flash-firmware: generated key " << ks.path_for(id) << "\n";
      }
      const DeviceKey key = ks.load(id);
      const std::string in = a->hex.empty() ? default_hex_path() : a->hex;
      HexImage img = read_intel_hex(in);
      const auto r = patch_device_key(img, id, key);
      if (r.had_key)
        std::cerr << fmt::format("flash-firmware: image already held a key for device {}; replaced\n",
                                 device_id_text(r.previous_device_id));
      const std::string out = a->out.empty() ? "btsm-fw-" + device_id_text(id) + ".hex" : a->out;
      write_private_file(out, format_intel_hex(img));
      std::cerr << "flash-firmware: patched image " << out << " (device " << device_id_text(id) << ")\n";
      const bool no_link_given =
          a->link.port.empty() && a->link.usb.empty() && a->link.ble.empty() && a->link.rfcomm.empty();
      const std::string port = a->dry_run && no_link_given
                                   ? std::string("PORT")
                                   : serial_port_for(spec_from(a->link));
      const auto cmd = avrdude_command(port, out, a->avrdude);
      std::string line;
      for (const auto& s : cmd) line += (line.empty() ? "" : " ") + s;
      if (a->dry_run) {
        std::cout << line << "\n";
        return;
      }
      std::cerr << "flash-firmware: " << line << "\n";
      const int rc = run_command(cmd);
      if (rc != 0)
        throw CommandError(kExitDevice, fmt::format("avrdude failed (exit {}): check the port, that no other program "
                                                    "(monitor, serial console) has it open, and that the board is a "
                                                    "Bluno/Uno with Optiboot ('not in sync' = wrong port or baud)",
                                                    rc));
      std::cerr << "flash-firmware: done; `btsm info` should now show device " << device_id_text(id) << "\n";
    });
  });
}

void register_keys(CLI::App& app) {
  auto* k = app.add_subcommand("keys", "Manage per-device model-signing keys ($XDG_CONFIG_HOME/btsm/keys)");
  k->footer(
      "One file per module, <device_id>.key, 64 hex characters (32-byte HMAC-SHA256 key). Directory 0700,\n"
      "files 0600; a key file readable or writable by others is refused.");
  k->require_subcommand(1);
  k->add_subcommand("path", "Print the key directory")->callback([] {
    guarded([] { std::cout << KeyStore::from_environment().dir() << "\n"; });
  });
  auto json_list = std::make_shared<bool>(false);
  auto* list = k->add_subcommand("list", "List device ids that have a key");
  list->add_flag("--json", *json_list, "print as JSON");
  list->callback([json_list] {
    guarded([&] {
      const KeyStore ks = KeyStore::from_environment();
      json j = json::array();
      for (uint32_t id : ks.list()) {
        if (*json_list) j.push_back({{"device_id", device_id_text(id)}, {"path", ks.path_for(id)}});
        else std::cout << device_id_text(id) << "  " << ks.path_for(id) << "\n";
      }
      if (*json_list) print_json(j);
    });
  });
  auto show_id = std::make_shared<std::string>();
  auto* show = k->add_subcommand("show", "Print a device's key (hex) — treat the output as a secret");
  show->add_option("id", *show_id, "device id (hex)")->required();
  show->callback([show_id] {
    guarded([&] {
      std::cout << key_to_hex(KeyStore::from_environment().load(parse_device_id_or_throw(*show_id))) << "\n";
    });
  });
  struct Gen {
    std::string id;
    bool force = false;
  };
  auto gen = std::make_shared<Gen>();
  auto* g = k->add_subcommand("generate", "Create a random key for a device id (refuses to overwrite unless --force)");
  g->add_option("id", gen->id, "device id (hex)")->required();
  g->add_flag("--force", gen->force, "replace an existing key (modules flashed with the old one will refuse models)");
  g->callback([gen] {
    guarded([&] {
      const KeyStore ks = KeyStore::from_environment();
      const uint32_t id = parse_device_id_or_throw(gen->id);
      ks.save(id, KeyStore::generate(), gen->force);
      std::cout << ks.path_for(id) << "\n";
    });
  });
  struct Imp {
    std::string id, hex;
    bool force = false;
  };
  auto imp = std::make_shared<Imp>();
  auto* i = k->add_subcommand("import", "Store a key given as 64 hex characters for a device id");
  i->add_option("id", imp->id, "device id (hex)")->required();
  i->add_option("hex", imp->hex, "the key, 64 hex characters")->required();
  i->add_flag("--force", imp->force, "replace an existing key");
  i->callback([imp] {
    guarded([&] {
      const auto key = key_from_hex(imp->hex);
      if (!key) throw CommandError(kExitUsage, "key must be 64 hex characters (32 bytes)");
      const KeyStore ks = KeyStore::from_environment();
      const uint32_t id = parse_device_id_or_throw(imp->id);
      ks.save(id, *key, imp->force);
      std::cout << ks.path_for(id) << "\n";
    });
  });
}

}  // namespace

void register_link_commands(CLI::App& app) {
  register_list(app);
  register_scan(app);
  register_info(app);
  register_monitor(app);
  register_record(app);
  register_set_speed(app);
  register_set_config(app);
  register_ack_alarm(app);
  register_flash_model(app);
  register_flash_firmware(app);
  register_keys(app);
}

}  // namespace btsm::cli
