// Column mapping of the fit (see column_map.hpp).
#include "column_map.hpp"

#include "common/wire_messages.hpp"
#include "declared_columns.hpp"
#include "recording_metadata.hpp"

#include <algorithm>
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
// The recording has `column` and not one value in it.
bool never_sampled(const Recording& rec, const std::string& column) {
  const int c = rec.channel_index(column);
  return c >= 0 && !rec.temp_c.col(c).array().isFinite().any();
}
}  // namespace

std::vector<Measurement> unsampled_measurements(const Network& net, const Recording& rec) {
  std::vector<Measurement> out;
  for (const auto& m : net.measurements)
    if (never_sampled(rec, m.column)) out.push_back(m);
  return out;
}

std::vector<std::string> unsampled_measurement_warnings(const Network& net, const Recording& rec, const std::string& consequence) {
  std::vector<std::string> out;
  for (const auto& m : unsampled_measurements(net, rec))
    out.push_back(rec.source + ": column '" + m.column + "' (node '" + net.nodes[static_cast<std::size_t>(m.node)].name +
                  "') has no value in any row: " + consequence);
  return out;
}

void refuse_unsampled_measurements(const Network& net, const std::vector<Recording>& recs) {
  for (const auto& m : net.measurements) {
    if (recs.empty() || !std::all_of(recs.begin(), recs.end(), [&](const Recording& r) { return never_sampled(r, m.column); }))
      continue;
    std::string files;
    for (const auto& rec : recs) files += (files.empty() ? "" : ", ") + rec.source;
    const std::string node = net.nodes[static_cast<std::size_t>(m.node)].name;
    throw std::invalid_argument("column '" + m.column + "' (measures node '" + node + "') has no value in any row of " + files +
                                ": the probe read nothing (open or not connected?); give recordings where it reads, or leave "
                                "the node unmeasured with '--column " + node + "='");
  }
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

namespace {

// column -> its role in `rec`'s channel_roles (absent: no role there).
std::map<std::string, std::string> roles_by_column(const Recording& rec) {
  std::map<std::string, std::string> out;
  for (const auto& [column, role] : channel_roles(rec)) out[column] = role;
  return out;
}

// True when the fit measured `node` with `model_column` against its recordings' roles on purpose
// (--column shaft=T5 with T5 spare), and `rec_roles` lay the probes out as those recordings did for
// it: they put the node on the same channel (`roles_column`, "" = none) and give `model_column` the
// role it had then. A probe that moved changes one of the two; a model fitted on recordings without
// roles, or with a hand-made map that does not say so, excuses nothing.
bool fit_mapped_it_so(const std::vector<FittedChannel>& fitted, const std::string& node, const std::string& model_column,
                      const std::string& roles_column, const std::map<std::string, std::string>& rec_roles) {
  std::string fit_roles_column, role_then;
  bool measured_so = false;
  for (const auto& f : fitted) {
    if (f.module_role == node) fit_roles_column = f.column;
    if (f.column == model_column && f.node == node) measured_so = true, role_then = f.module_role;
  }
  const auto now = rec_roles.find(model_column);
  return measured_so && !role_then.empty() && fit_roles_column == roles_column && now != rec_roles.end() &&
         now->second == role_then;
}

}  // namespace

void check_mapping_agrees_with_roles(const Network& net, const std::vector<FittedChannel>& fitted,
                                     const std::vector<Recording>& recs, const std::vector<std::string>& columns,
                                     const std::string& advice) {
  for (const auto& rec : recs) {
    const auto rec_roles = roles_by_column(rec);
    for (const auto& [node, column] : columns_from_roles(net, {rec}, columns)) {
      for (const auto& m : net.measurements) {
        if (net.nodes[static_cast<std::size_t>(m.node)].name != node || m.column == column) continue;
        if (fit_mapped_it_so(fitted, node, m.column, column, rec_roles)) continue;
        const auto role = rec_roles.find(m.column);
        const std::string there = rec.channel_index(m.column) >= 0 && role != rec_roles.end()
                                      ? m.column + " is " + role->second + " there"
                                      : m.column + " has no role there";
        throw std::invalid_argument(rec.source + ": its channel_roles put node '" + node + "' on " +
                                    (column.empty() ? "no channel" : column) + ", but the model measures it with " +
                                    m.column + " (" + there + "): the probes are not where the model says; " + advice);
      }
    }
  }
}

}  // namespace btsm::thermal
