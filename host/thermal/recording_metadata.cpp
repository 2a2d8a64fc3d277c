// Checks of a recording's channel_roles / ambient_channel metadata (see recording_metadata.hpp).
#include "recording_metadata.hpp"

#include "common/wire_messages.hpp"
#include "declared_columns.hpp"
#include "host/io/input_error.hpp"

#include <sstream>
#include <stdexcept>

namespace btsm::thermal {
namespace {

std::string trimmed(const std::string& s) {
  const auto a = s.find_first_not_of(" \t");
  if (a == std::string::npos) return {};
  return s.substr(a, s.find_last_not_of(" \t") - a + 1);
}

[[noreturn]] void bad(const Recording& rec, const std::string& key, const std::string& what) {
  throw io::InputError(rec.source + ": metadata '# " + key + "': " + what);
}

// The value of a line that must say one thing: given twice with different values, the first would
// win silently (the reader keeps every line; an edited file can hold the old one and a new one).
std::string single_value(const Recording& rec, const char* key) {
  std::string value;
  bool seen = false;
  for (const auto& [k, v] : rec.meta) {
    if (k != key) continue;
    if (seen && trimmed(v) != trimmed(value)) bad(rec, key, "given twice with different values ('" + value + "', '" + v + "')");
    value = v;
    seen = true;
  }
  return value;
}

}  // namespace

std::vector<std::pair<std::string, std::string>> channel_roles(const Recording& rec) {
  static const char* kKey = "channel_roles";
  std::vector<std::pair<std::string, std::string>> out;
  const std::string line = single_value(rec, kKey);
  if (line.empty() || line.find('(') != std::string::npos) return out;  // absent, or firmware defaults
  std::stringstream ss(line);
  std::string item;
  while (std::getline(ss, item, ',')) {
    item = trimmed(item);
    const auto eq = item.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == item.size())
      bad(rec, kKey, "entry '" + item + "' is not COLUMN=ROLE (e.g. T1=rear_bearing)");
    const std::string column = trimmed(item.substr(0, eq)), role = trimmed(item.substr(eq + 1));
    const int r = wire::channel_role_from_name(role.c_str());  // -1 also for the "unknown" `btsm record` writes
    if (r < 0 && role != "unknown") {
      std::string known;
      for (uint8_t k = 0; k < wire::kChannelRoleCount; ++k) known += std::string(k ? ", " : "") + wire::channel_role_name(k);
      bad(rec, kKey, "unknown role '" + role + "' for " + column + " (known: " + known + ")");
    }
    for (const auto& [c, other] : out) {
      if (c == column) bad(rec, kKey, "channel " + column + " is listed twice (" + other + ", " + role + ")");
      // One probe per measured point: two channels with one role leave the fit to pick one of
      // them silently and leave another point unmeasured.
      const bool unique = r >= 0 && (wire::is_thermal_role(static_cast<uint8_t>(r)) || r == static_cast<int>(wire::ChannelRole::Ambient));
      if (unique && other == role) bad(rec, kKey, "role '" + role + "' is on two channels, " + c + " and " + column);
    }
    out.emplace_back(column, role);
  }
  return out;
}

std::string ambient_channel(const Recording& rec) {
  static const char* kKey = "ambient_channel";
  const std::string ch = trimmed(single_value(rec, kKey));
  if (ch.empty()) {
    // "# ambient_channel:" with nothing after it dropped the ambient from the model's channel map
    for (const auto& [k, v] : rec.meta)
      if (k == kKey) bad(rec, kKey, "is empty: name the ambient channel (T1..T5), or delete the line if the module has none");
    return ch;
  }
  if (!(ch.size() == 2 && ch[0] == 'T' && ch[1] >= '1' && ch[1] <= '5'))
    bad(rec, kKey, "'" + ch + "' is not a module channel (T1..T5)");
  for (const auto& [column, role] : channel_roles(rec)) {
    if (column == ch && role != "ambient") bad(rec, kKey, ch + " has the role '" + role + "' in channel_roles, not ambient");
    if (column != ch && role == "ambient") bad(rec, kKey, ch + " contradicts channel_roles, where " + column + " is the ambient");
  }
  return ch;
}

void check_recording_metadata(const Recording& rec) {
  // A key the tool acts on, written in another case, would be read as an unknown key and ignored:
  // the error would come later, as a missing column or an unmeasured node, far from its cause.
  for (const auto& [k, v] : rec.meta) {
    std::string lower = k;
    for (char& c : lower) c = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
    for (const char* known : {"channel_roles", "ambient_channel", "boundary_columns", "event_columns"})
      if (lower == known && k != known) bad(rec, k, std::string("keys are lower case: write '# ") + known + ":'");
  }
  check_declared_columns(rec);
  (void)channel_roles(rec);
  (void)ambient_channel(rec);
}

}  // namespace btsm::thermal
