// Checks of a recording's channel_roles / ambient_channel metadata (see recording_metadata.hpp).
#include "recording_metadata.hpp"

#include "common/wire_messages.hpp"
#include "declared_columns.hpp"
#include "host/io/input_error.hpp"

#include <fmt/core.h>

#include <algorithm>
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

// The module's channels, as record writes them: the only columns channel_roles and ambient_channel
// can name.
bool is_module_channel(const std::string& column) {
  return column.size() == 2 && column[0] == 'T' && column[1] >= '1' && column[1] <= '5';
}

constexpr const char* kActedOnKeys[] = {"channel_roles", "ambient_channel", "boundary_columns", "event_columns"};

// The key a metadata line's start looks like: blanks and further '#' dropped, the words before
// anything but a letter, digit, '_', '-' or blank, lower case, '-' and blanks as '_'.
// "## channel_roles" -> "channel_roles", "channel-roles" -> "channel_roles", and "channel_roles =
// T1=..." (no colon: all of it is the key) -> "channel_roles".
std::string key_it_looks_like(const std::string& key) {
  std::string k = trimmed(key.substr(std::min(key.find_first_not_of("# \t"), key.size())));
  const auto end = k.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_- \t");
  k = trimmed(k.substr(0, end));
  for (char& c : k) c = c == '-' || c == ' ' || c == '\t' ? '_' : static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
  return k;
}

// A metadata line as the file held it (near enough: the reader trimmed it), cut for a message.
std::string shown_line(const std::string& key, const std::string& value) {
  std::string line = key.rfind('#', 0) == 0 ? "#" : "# ";
  line += key;
  if (!value.empty()) line.append(": ").append(value);
  return line.size() > 80 ? line.substr(0, 77) + "..." : line;
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
    // as ambient_channel: a role on a channel the module does not have was ignored
    if (!is_module_channel(column)) bad(rec, kKey, "entry '" + item + "': '" + column + "' is not a module channel (T1..T5)");
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
  if (!is_module_channel(ch))
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
    for (const char* known : kActedOnKeys)
      if (lower == known && k != known) bad(rec, k, std::string("keys are lower case: write '# ") + known + ":'");
  }
  check_declared_columns(rec);
  (void)channel_roles(rec);
  (void)ambient_channel(rec);
}

std::vector<std::string> metadata_warnings(const Recording& rec) {
  std::vector<std::string> out;
  for (const auto& [k, v] : rec.meta) {
    const std::string looks = key_it_looks_like(k);
    std::string lower = k;
    for (char& c : lower) c = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
    for (const char* known : kActedOnKeys)
      if (looks == known && k != known && lower != known) {  // another case only is refused (check_recording_metadata)
        out.push_back(fmt::format("{}: the line '{}' is not read as '# {}:' (write '# {}: ...': one '#', the key, a colon): "
                                  "what it says is ignored",
                                  rec.source, shown_line(k, v), known, known));
      }
  }
  return out;
}

std::vector<std::string> reading_warnings(const Recording& rec) {
  std::vector<std::string> out;
  if (std::string gap = long_gap_warning(rec); !gap.empty()) out.push_back(std::move(gap));
  for (auto& w : metadata_warnings(rec)) out.push_back(std::move(w));
  out.insert(out.end(), rec.warnings.begin(), rec.warnings.end());
  return out;
}

}  // namespace btsm::thermal
