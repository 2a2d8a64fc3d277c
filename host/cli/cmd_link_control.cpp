// btsm set-speed | set-config | get-config | ack-alarm: single requests to the module.
#include "cmd_link_support.hpp"
#include "common/model_blob.hpp"
#include "common/wire_messages.hpp"
#include "host/io/utf8_text.hpp"
#include "host/link/model_flash.hpp"
#include "host/link/recorder.hpp"

#include <fmt/core.h>

#include <climits>
#include <iostream>
#include <memory>
#include <vector>

namespace btsm::cli {
namespace {

using namespace btsm::link;

// --- set-speed -----------------------------------------------------------------------------------

struct SetSpeedArgs {
  LinkOptions link;
  std::string rpm;
};

// "tach" -> kSpeedFromTach, "0".."60000" -> rpm, anything else a usage error.
uint16_t parse_speed(const std::string& text) {
  if (text == "tach") return wire::kSpeedFromTach;
  size_t used = 0;
  long v = -1;
  try {
    v = std::stol(text, &used);
  } catch (...) {
  }
  if (used != text.size() || v < 0 || v > wire::kMaxSpeedRpm)
    throw CommandError(kExitUsage, fmt::format("speed '{}': expected 0..{} rpm or 'tach'", text, wire::kMaxSpeedRpm));
  return static_cast<uint16_t>(v);
}

void run_set_speed(const SetSpeedArgs& a) {
  const uint16_t value = parse_speed(a.rpm);
  auto conn = connect(a.link);
  conn.session->set_speed(value);
  std::cerr << "set-speed: " << (a.rpm == "tach" ? std::string("speed from tach") : a.rpm + " rpm") << " acknowledged\n";
}

void register_set_speed(CLI::App& app) {
  auto a = std::make_shared<SetSpeedArgs>();
  auto* c = app.add_subcommand("set-speed", "Tell the module the spindle speed its model uses (rpm, or 'tach' to measure it)");
  c->footer("The speed is held in the module's RAM: after a reset it measures the tach input again.\n"
            "  btsm set-speed --port /dev/ttyACM0 6000\n  btsm set-speed --ble C8:A0:30:F1:02:03 tach");
  add_link_options(*c, a->link);
  c->add_option("speed", a->rpm, "rpm 0..60000, or 'tach' for the tachometer input")->required();
  c->callback([a] { guarded([&] { run_set_speed(*a); }); });
}

// --- set-config ----------------------------------------------------------------------------------

struct SetConfigArgs {
  LinkOptions link;
  std::string key, value;
};

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
  if (key >= wire::kChannelRoleKeyFirst && key <= wire::kChannelRoleKeyLast)
    if (const int r = wire::channel_role_from_name(text.c_str()); r >= 0) return r;
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

// What a value means: a role name for the channel role keys, else the number.
std::string config_value_text(uint8_t key, int32_t value) {
  if (key >= wire::kChannelRoleKeyFirst && key <= wire::kChannelRoleKeyLast && value >= 0 && value < 256)
    if (const char* n = wire::channel_role_name(static_cast<uint8_t>(value))) return n;
  return std::to_string(value);
}

// A role change can leave the active model's channel map behind (probe 5: the ambient role moved
// away, and the module showed NORMAL without predicting anything): said as `info` says it.
void warn_about_active_model(Session& session) {
  try {
    const ActiveModelMap am = read_active_model_map(session);
    if (am.version != kReducedModelVersion) return;
    const ChannelMapCheck mc = check_channel_map(am.roles, read_channel_roles(session).role);
    for (const auto& w : mc.conflicts)
      std::cerr << "set-config: WARNING: the active model no longer fits the roles: " << w << "\n";
    for (const auto& w : mc.warnings) std::cerr << "set-config: warning: " << w << "\n";
  } catch (const std::exception& e) {
    // firmware without MODEL_READ/GET_CONFIG, or the link failing after the acknowledged change:
    // the change stands; `info` says what it can
    std::cerr << "set-config: could not check the active model's channel map (" << io::printable(e.what())
              << "); `btsm info` shows it\n";
  }
}

void run_set_config(const SetConfigArgs& a) {
  const uint8_t key = parse_config_key(a.key);
  const int32_t value = parse_config_value(key, a.value);
  wire::ConfigRange r{};
  wire::config_key_range(key, r);
  if (value < r.min || value > r.max)
    throw CommandError(kExitUsage,
                       fmt::format("{} = {} is outside [{}, {}]", wire::config_key_name(key), value, r.min, r.max));
  auto conn = connect(a.link);
  // A measured role (a bearing, the housing ...) or the ambient belongs to one channel: a second
  // ambient was acknowledged silently, and every recording after it was refused by the readers.
  // Not refused here: swapping two probes' roles passes through a moment where both have one.
  std::string shared_with;
  if (key >= wire::kChannelRoleKeyFirst && key <= wire::kChannelRoleKeyLast &&
      (wire::is_thermal_role(static_cast<uint8_t>(value)) || value == static_cast<int32_t>(wire::ChannelRole::Ambient))) {
    const uint8_t self = static_cast<uint8_t>(key - wire::kChannelRoleKeyFirst);
    try {
      for (uint8_t ch = 0; ch < kChannels; ++ch)
        if (ch != self && conn.session->get_config(wire::channel_role_key(ch)).value == value)
          shared_with += (shared_with.empty() ? "" : ", ") + std::to_string(ch + 1);
    } catch (const link::NackError&) {
      // firmware without GET_CONFIG cannot be asked; `record` checks the roles it reports
    }
  }
  const bool role_key = key >= wire::kChannelRoleKeyFirst && key <= wire::kChannelRoleKeyLast;
  // Every channel disabled: the module sends no sample at all, and `monitor` can only blame the link.
  if (role_key && value == static_cast<int32_t>(wire::ChannelRole::Disabled)) {
    const uint8_t self = static_cast<uint8_t>(key - wire::kChannelRoleKeyFirst);
    bool another = false;
    try {
      for (uint8_t ch = 0; ch < kChannels && !another; ++ch)
        another = ch != self && conn.session->get_config(wire::channel_role_key(ch)).value !=
                                    static_cast<int32_t>(wire::ChannelRole::Disabled);
    } catch (const link::NackError&) {
      another = true;  // cannot be asked: let the module decide
    }
    if (!another)
      throw CommandError(kExitUsage, fmt::format("{} disabled would disable the last channel in use: the module would send "
                                                 "no sample at all (give another channel a role first)",
                                                 wire::config_key_name(key)));
  }
  conn.session->set_config(key, value);
  std::cerr << fmt::format("set-config: {} = {} acknowledged\n", wire::config_key_name(key), config_value_text(key, value));
  if (role_key) warn_about_active_model(*conn.session);
  if (!shared_with.empty())
    std::cerr << fmt::format("set-config: WARNING: channel {} has the role {} too; a role belongs to one channel, and "
                             "`record` refuses to start until each has its own (give channel {} another role)\n",
                             shared_with, config_value_text(key, value), shared_with);
}

// One line per key with its range and default, for the help footer.
std::string config_keys_help() {
  std::string keys;
  for (int k = 0; k < 256; ++k) {
    wire::ConfigRange r{};
    const char* n = wire::config_key_name(static_cast<uint8_t>(k));
    if (n && wire::config_key_range(static_cast<uint8_t>(k), r))
      keys += fmt::format("  {:<22} [{} .. {}], default {}\n", n, r.min, r.max, r.default_value);
  }
  return keys;
}

void register_set_config(CLI::App& app) {
  auto a = std::make_shared<SetConfigArgs>();
  auto* c = app.add_subcommand("set-config", "Set one module configuration value (checked against its range first)");
  c->footer("Keys:\n" + config_keys_help() +
            "channel_role_N takes a role name: disabled, ambient, front_bearing, rear_bearing, housing,\n"
            "motor, coolant, spare, shaft.\n  btsm set-config --port /dev/ttyACM0 sample_period_ms 2000");
  add_link_options(*c, a->link);
  c->add_option("key", a->key, "configuration key name (or number)")->required();
  c->add_option("value", a->value, "integer value (or role name)")->required();
  c->callback([a] { guarded([&] { run_set_config(*a); }); });
}

// --- get-config ----------------------------------------------------------------------------------

struct GetConfigArgs {
  LinkOptions link;
  std::vector<std::string> keys;
  bool json = false;
};

void run_get_config(const GetConfigArgs& a) {
  std::vector<uint8_t> keys;
  for (const auto& k : a.keys) keys.push_back(parse_config_key(k));
  if (keys.empty())
    for (int k = 0; k < 256; ++k) {
      wire::ConfigRange r{};
      if (wire::config_key_name(static_cast<uint8_t>(k)) && wire::config_key_range(static_cast<uint8_t>(k), r))
        keys.push_back(static_cast<uint8_t>(k));
    }
  auto conn = connect(a.link);
  nlohmann::json j = nlohmann::json::object();
  for (uint8_t key : keys) {
    const wire::ConfigValue v = conn.session->get_config(key);
    if (v.key != key)
      throw CommandError(kExitFailure, fmt::format("asked for {} and the module answered key {}",
                                                   wire::config_key_name(key), v.key));
    const std::string text = config_value_text(key, v.value);
    if (a.json) {
      j[wire::config_key_name(key)] = text == std::to_string(v.value) ? nlohmann::json(v.value) : nlohmann::json(text);
    } else {
      std::cout << fmt::format("{:<22} {}\n", wire::config_key_name(key), text);
    }
  }
  if (a.json) print_json(j);
}

void register_get_config(CLI::App& app) {
  auto a = std::make_shared<GetConfigArgs>();
  auto* c = app.add_subcommand("get-config", "Read module configuration values (GET_CONFIG), all keys or the ones named");
  c->footer("One line per key: name and value (channel roles by name). Keys and ranges: `btsm set-config --help`.\n"
            "  btsm get-config --port /dev/ttyACM0\n  btsm get-config --port /dev/ttyACM0 sample_period_ms channel_role_5");
  add_link_options(*c, a->link);
  c->add_option("key", a->keys, "configuration key names (or numbers); none = every key");
  c->add_flag("--json", a->json, "print {key: value} as JSON");
  c->callback([a] { guarded([&] { run_get_config(*a); }); });
}

// --- ack-alarm -----------------------------------------------------------------------------------

void run_ack_alarm(const LinkOptions& link) {
  auto conn = connect(link);
  conn.session->ack_alarm();
  std::cerr << "ack-alarm: acknowledged\n";
}

void register_ack_alarm(CLI::App& app) {
  auto link = std::make_shared<LinkOptions>();
  auto* c = app.add_subcommand("ack-alarm", "Acknowledge a latched ALARM (it clears once the cause is gone)");
  add_link_options(*c, *link);
  c->callback([link] { guarded([&] { run_ack_alarm(*link); }); });
}

}  // namespace

void register_link_control_commands(CLI::App& app) {
  register_set_speed(app);
  register_set_config(app);
  register_get_config(app);
  register_ack_alarm(app);
}

}  // namespace btsm::cli
