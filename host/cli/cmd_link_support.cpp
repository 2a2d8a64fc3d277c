#include "cmd_link_support.hpp"

#include "common/wire_messages.hpp"
#include "host/link/ble_transport.hpp"
#include "host/link/device_keys.hpp"
#include "host/link/rfcomm_transport.hpp"
#include "host/link/usb_devices.hpp"

#include <fmt/core.h>

#include <cmath>
#include <csignal>

namespace btsm::cli {

using namespace btsm::link;
using nlohmann::json;

std::atomic<bool> g_link_stop{false};

namespace {
extern "C" void on_interrupt(int) { g_link_stop = true; }
}  // namespace

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

// The link options' syntax is checked before anything is opened: a malformed address is a bad
// argument (exit 2), not a missing device (exit 3).
void check_link_syntax(const LinkOptions& o) {
  try {
    if (!o.ble.empty()) (void)parse_ble_address(o.ble);
    if (!o.rfcomm.empty()) {
      uint8_t tmp[6];
      parse_bdaddr_or_throw(o.rfcomm, tmp);
    }
  } catch (const LinkError& e) {
    throw CommandError(kExitUsage, std::string(o.ble.empty() ? "--rfcomm: " : "--ble: ") + e.what());
  }
  if (!o.usb.empty() && !parse_vid_pid(o.usb))
    throw CommandError(kExitUsage, "bad --usb '" + o.usb + "': expected VID:PID in hex, e.g. 2341:0043");
}

Connection connect(const LinkOptions& o) {
  if (!(o.timeout_s > 0)) throw CommandError(kExitUsage, "--timeout must be positive");
  check_link_syntax(o);
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

uint32_t parse_device_id_or_throw(const std::string& text) {
  const auto id = parse_device_id(text);
  if (!id) throw CommandError(kExitUsage, "device id '" + text + "' is not hex (up to 8 digits, e.g. 0000de71)");
  return *id;
}

}  // namespace btsm::cli
