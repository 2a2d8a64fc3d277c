// Declared boundary and event columns of a recording (see declared_columns.hpp).
#include "host/thermal/declared_columns.hpp"

#include "host/io/input_error.hpp"

#include <cmath>
#include <stdexcept>

namespace btsm::thermal {
namespace {

std::vector<std::string> split_list(const std::string& s) {
  std::vector<std::string> out;
  std::string cur;
  auto push = [&] {
    std::size_t a = 0, b = cur.size();
    while (a < b && (cur[a] == ' ' || cur[a] == '\t')) ++a;
    while (b > a && (cur[b - 1] == ' ' || cur[b - 1] == '\t')) --b;
    const std::string t = cur.substr(a, b - a);
    bool seen = false;
    for (const auto& o : out) seen = seen || o == t;
    if (!t.empty() && !seen) out.push_back(t);
    cur.clear();
  };
  for (char c : s) {
    if (c == ',') push();
    else cur += c;
  }
  push();
  return out;
}

std::vector<std::string> declared(const Recording& rec, const char* key) {
  std::vector<std::string> out;
  for (const auto& kv : rec.meta)
    if (kv.first == key)
      for (const auto& c : split_list(kv.second)) {
        bool seen = false;
        for (const auto& o : out) seen = seen || o == c;
        if (!seen) out.push_back(c);
      }
  return out;
}

void set_declared(Recording& rec, const char* key, const std::vector<std::string>& cols) {
  std::erase_if(rec.meta, [&](const auto& kv) { return kv.first == key; });
  if (cols.empty()) return;
  std::string v;
  for (const auto& c : cols) v += (v.empty() ? "" : ",") + c;
  rec.meta.emplace_back(key, v);
}

std::string row_where(const Recording& rec, Eigen::Index k) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "time_s %.10g (data row %ld)", rec.time_s[static_cast<std::size_t>(k)], static_cast<long>(k + 1));
  return buf;
}

}  // namespace

std::vector<std::string> boundary_columns(const Recording& rec) { return declared(rec, kBoundaryColumnsKey); }
std::vector<std::string> event_columns(const Recording& rec) { return declared(rec, kEventColumnsKey); }

bool is_declared_column(const Recording& rec, const std::string& column) {
  for (const auto& c : boundary_columns(rec))
    if (c == column) return true;
  for (const auto& c : event_columns(rec))
    if (c == column) return true;
  return false;
}

void check_declared_columns(const Recording& rec) {
  const std::vector<std::string> b = boundary_columns(rec), e = event_columns(rec);
  for (const auto& c : b) {
    for (const auto& x : e)
      if (x == c) throw io::InputError(rec.source + ": column '" + c + "' is declared both as a boundary and as an event");
    const int j = rec.channel_index(c);
    if (const std::string why = reserved_column_problem(c); !why.empty())
      throw io::InputError(rec.source + ": declared boundary column '" + c + "' " + why);
    if (j < 0) throw io::InputError(rec.source + ": declared boundary column '" + c + "' is not in the header");
    for (Eigen::Index k = 0; k < rec.temp_c.rows(); ++k)
      if (!std::isfinite(rec.temp_c(k, j)))
        throw io::InputError(rec.source + ": boundary column '" + c + "' is empty at " + row_where(rec, k) +
                                    " (a boundary temperature is needed on every row)");
  }
  for (const auto& c : e) {
    const int j = rec.channel_index(c);
    if (const std::string why = reserved_column_problem(c); !why.empty())
      throw io::InputError(rec.source + ": declared event column '" + c + "' " + why);
    if (j < 0) throw io::InputError(rec.source + ": declared event column '" + c + "' is not in the header");
    for (Eigen::Index k = 0; k < rec.temp_c.rows(); ++k) {
      const double v = rec.temp_c(k, j);
      if (v != 0.0 && v != 1.0)
        throw io::InputError(rec.source + ": event column '" + c + "' must be 0 or 1, found " +
                                    (std::isfinite(v) ? std::to_string(v) : std::string("an empty cell")) + " at " + row_where(rec, k));
    }
  }
}

void declare_columns(Recording& rec, const std::vector<std::string>& boundaries, const std::vector<std::string>& events) {
  std::vector<std::string> b = boundary_columns(rec), e = event_columns(rec);
  auto add = [](std::vector<std::string>& v, const std::string& c) {
    for (const auto& o : v)
      if (o == c) return;
    v.push_back(c);
  };
  for (const auto& c : boundaries)
    for (const auto& x : split_list(c)) add(b, x);
  for (const auto& c : events)
    for (const auto& x : split_list(c)) add(e, x);
  Recording declared = rec;  // checked before it replaces anything
  set_declared(declared, kBoundaryColumnsKey, b);
  set_declared(declared, kEventColumnsKey, e);
  check_declared_columns(declared);
  rec.meta = std::move(declared.meta);
}

void check_measurements_not_declared(const Network& net, const Recording& rec) {
  for (const auto& m : net.measurements)
    if (is_declared_column(rec, m.column))
      throw std::invalid_argument(rec.source + ": column '" + m.column + "' is declared as a boundary or event column, so it cannot measure node '" +
                                  net.nodes[static_cast<std::size_t>(m.node)].name + "'");
}

}  // namespace btsm::thermal
