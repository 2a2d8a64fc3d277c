// Column mapping of the fit (see column_map.hpp).
#include "column_map.hpp"

#include "common/wire_messages.hpp"
#include "declared_columns.hpp"
#include "recording_metadata.hpp"

#include <map>
#include <stdexcept>

namespace btsm::thermal {

std::vector<int> measurement_columns(const Network& net, const Recording& rec) {
  std::vector<int> cols;
  if (net.measurements.empty()) throw std::invalid_argument("network '" + net.name + "' declares no measurements");
  for (const auto& m : net.measurements) {
    const int c = rec.channel_index(m.column);
    if (c < 0) {
      if (const std::string why = reserved_column_problem(m.column); !why.empty())
        throw std::invalid_argument(rec.source + ": column '" + m.column + "' (measures node '" +
                                    net.nodes[static_cast<std::size_t>(m.node)].name + "') " + why);
      std::string have;
      for (const auto& ch : rec.channels) have += " " + ch;
      throw std::invalid_argument(rec.source + ": no column '" + m.column + "' (measures node '" +
                                  net.nodes[static_cast<std::size_t>(m.node)].name + "'); columns:" + have);
    }
    cols.push_back(c);
  }
  check_measurements_not_declared(net, rec);  // a declared boundary/event column is an input, never a node
  return cols;
}

namespace {
// node name -> the column its role names ("" = no channel has it), from the recordings'
// channel_roles metadata; nodes in `explicit_specs` are left out. See map_measurements().
std::map<std::string, std::string> columns_from_roles(const Network& net, const std::vector<Recording>& recs,
                                                      const std::vector<std::string>& explicit_specs) {
  std::map<std::string, std::string> explicit_nodes;
  for (const auto& spec : explicit_specs) explicit_nodes[spec.substr(0, spec.find('='))] = spec;
  std::map<std::string, std::pair<std::string, std::string>> chosen;  // node -> (column, recording)
  for (const auto& rec : recs) {
    std::map<std::string, std::string> column_of_role;
    for (const auto& [column, role] : channel_roles(rec)) column_of_role[role] = column;  // checked: one column per role
    if (column_of_role.empty()) continue;  // absent, or defaults
    for (uint8_t r = 0; r < wire::kChannelRoleCount; ++r) {
      const std::string role = wire::channel_role_name(r);
      if (!wire::is_thermal_role(r) || net.node_index(role) < 0 || explicit_nodes.count(role)) continue;
      const auto it = column_of_role.find(role);
      const std::string column = it == column_of_role.end() ? std::string() : it->second;
      const auto prev = chosen.find(role);
      if (prev == chosen.end()) {
        chosen[role] = {column, rec.source};
      } else if (prev->second.first != column) {
        throw std::invalid_argument("channel roles: " + prev->second.second + " has node '" + role + "' on " +
                                    (prev->second.first.empty() ? "no channel" : prev->second.first) + ", " +
                                    rec.source + " on " + (column.empty() ? "no channel" : column) +
                                    "; say which with --column " + role + "=COLUMN");
      }
    }
  }
  std::map<std::string, std::string> out;
  for (const auto& [node, c] : chosen) out[node] = c.first;
  return out;
}
}  // namespace

std::string map_measurements(Network& net, const std::vector<Recording>& recs, const std::vector<std::string>& columns) {
  const auto from_roles = columns_from_roles(net, recs, columns);
  // Every chosen node loses its old column first, so swapped probes do not collide; --column last.
  std::vector<std::string> specs;
  std::string said;
  for (const auto& [node, column] : from_roles) {
    specs.push_back(node + "=");
    said += " " + node + "=" + (column.empty() ? "(none)" : column);
  }
  for (const auto& [node, column] : from_roles)
    if (!column.empty()) specs.push_back(node + "=" + column);
  specs.insert(specs.end(), columns.begin(), columns.end());
  remap_measurements(net, specs);
  // The module's ambient channel is the boundary (`btsm record` writes it as ambient_c, never as a
  // column of its own); a node measured by such a column would be fitted to the room.
  for (const auto& rec : recs) {
    const std::string ambient = ambient_channel(rec);
    for (const auto& m : net.measurements)
      if (!ambient.empty() && m.column == ambient && rec.channel_index(ambient) >= 0)
        throw std::invalid_argument(rec.source + ": column '" + ambient + "' measures node '" +
                                    net.nodes[static_cast<std::size_t>(m.node)].name +
                                    "' but the metadata names it the ambient channel; say which with --column NODE=COLUMN");
  }
  return said;
}

void check_mapping_agrees_with_roles(const Network& net, const std::vector<Recording>& recs,
                                     const std::vector<std::string>& columns, const std::string& advice) {
  for (const auto& rec : recs) {
    const std::vector<std::string> roles_of = [&] {
      std::vector<std::string> out(rec.channels.size());
      for (const auto& [column, role] : channel_roles(rec))
        if (rec.channel_index(column) >= 0) out[static_cast<std::size_t>(rec.channel_index(column))] = role;
      return out;
    }();
    for (const auto& [node, column] : columns_from_roles(net, {rec}, columns)) {
      for (const auto& m : net.measurements) {
        if (net.nodes[static_cast<std::size_t>(m.node)].name != node || m.column == column) continue;
        const int c = rec.channel_index(m.column);
        const std::string there = c >= 0 && !roles_of[static_cast<std::size_t>(c)].empty()
                                      ? m.column + " is " + roles_of[static_cast<std::size_t>(c)] + " there"
                                      : m.column + " has no role there";
        throw std::invalid_argument(rec.source + ": its channel_roles put node '" + node + "' on " +
                                    (column.empty() ? "no channel" : column) + ", but the model measures it with " +
                                    m.column + " (" + there + "): the probes are not where the model says; " + advice);
      }
    }
  }
}

}  // namespace btsm::thermal
