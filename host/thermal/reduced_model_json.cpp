#include "reduced_model_json.hpp"

#include "common/byte_order.hpp"
#include "common/model_blob.hpp"
#include "common/wire_messages.hpp"
#include "host/io/json_input.hpp"
#include "host/io/utf8_text.hpp"

#include <fmt/format.h>

#include <cmath>
#include <functional>
#include <stdexcept>
#include <vector>

namespace btsm::thermal {
namespace {

using nlohmann::json;

// ---- reading the table back -------------------------------------------------------------------

[[noreturn]] void bad_field(const std::string& path, const std::string& what) { throw std::invalid_argument(path + " " + what); }

std::string sub(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }
std::string at(const std::string& path, std::size_t i) { return fmt::format("{}[{}]", path, i); }

const json& member(const json& obj, const std::string& path, const char* key) {
  if (!obj.is_object()) bad_field(path.empty() ? "the table" : path, "is " + io::json_excerpt(obj) + ", not an object");
  if (!obj.contains(key)) bad_field(sub(path, key), "is missing");
  return obj[key];
}

double number(const json& v, const std::string& path) {
  if (!v.is_number()) bad_field(path, "is " + io::json_excerpt(v) + ", not a number");
  return v.get<double>();
}

// A whole number lo..hi: the blob keeps it in a field of that width, so no other value can be it.
unsigned whole(const json& v, const std::string& path, unsigned lo, unsigned hi) {
  const double d = number(v, path);
  if (!(d >= lo && d <= hi && d == std::floor(d)))
    bad_field(path, fmt::format("is {}, not a whole number {}..{}", io::json_excerpt(v), lo, hi));
  return static_cast<unsigned>(d);
}

const json& array(const json& v, const std::string& path, std::size_t n) {
  if (!v.is_array() || v.size() != n) bad_field(path, fmt::format("is {}, not an array of {}", io::json_excerpt(v), n));
  return v;
}

void per_channel(const json& v, const std::string& path, double (&out)[kModelChannels]) {
  array(v, path, kModelChannels);
  for (std::size_t j = 0; j < kModelChannels; ++j) out[j] = number(v[j], at(path, j));
}

// The role as role_json wrote it: a role name, "unchecked", or the code itself.
uint8_t role_code(const json& v, const std::string& path) {
  if (v.is_string()) {
    const std::string& s = v.get_ref<const std::string&>();
    if (s == "unchecked") return kModelRoleUnchecked;
    if (const int r = wire::channel_role_from_name(s.c_str()); r >= 0) return static_cast<uint8_t>(r);
    bad_field(path, "is " + io::json_excerpt(v) + ", not a channel role name");
  }
  return static_cast<uint8_t>(whole(v, path, 0, 255));
}

void read_breakpoints(const json& sm, ReducedModelF64& m) {
  const json& bps = member(sm, "", "breakpoints");
  if (!bps.is_array() || bps.empty() || bps.size() > kModelMaxBreakpoints)
    bad_field("breakpoints", fmt::format("is {}, not an array of 1..{} breakpoints", io::json_excerpt(bps), kModelMaxBreakpoints));
  m.n_breakpoints = static_cast<uint8_t>(bps.size());
  for (std::size_t i = 0; i < bps.size(); ++i) {
    const std::string p = at("breakpoints", i);
    m.speed_rpm[i] = static_cast<uint16_t>(whole(member(bps[i], p, "speed_rpm"), sub(p, "speed_rpm"), 0, 65535));
    per_channel(member(bps[i], p, "a"), sub(p, "a"), m.a[i]);
    per_channel(member(bps[i], p, "b_K"), sub(p, "b_K"), m.b_K[i]);
  }
}

// stop_phase_end_s holds both ends; stop_phases one entry per phase in use, with its end again.
void read_stop_phases(const json& sm, ReducedModelF64& m) {
  const json& ends = array(member(sm, "", "stop_phase_end_s"), "stop_phase_end_s", kModelEarlyStopPhases);
  for (std::size_t k = 0; k < kModelEarlyStopPhases; ++k)
    m.stop_end_s[k] = static_cast<uint16_t>(whole(ends[k], at("stop_phase_end_s", k), 0, 65535));
  const json& phases = member(sm, "", "stop_phases");
  std::size_t used = 0;
  for (std::size_t k = 0; k < kModelEarlyStopPhases; ++k) used += m.stop_end_s[k] != 0;
  if (!phases.is_array() || phases.size() != used)
    bad_field("stop_phases", fmt::format("is {}, not an array of {} (the phases stop_phase_end_s sets)", io::json_excerpt(phases), used));
  std::size_t i = 0;
  for (std::size_t k = 0; k < kModelEarlyStopPhases; ++k) {
    if (m.stop_end_s[k] == 0) continue;
    const std::string p = at("stop_phases", i);
    const json& e = member(phases[i], p, "end_s");
    if (whole(e, sub(p, "end_s"), 0, 65535) != m.stop_end_s[k])
      bad_field(sub(p, "end_s"), fmt::format("is {}, but stop_phase_end_s[{}] is {}", io::json_excerpt(e), k, m.stop_end_s[k]));
    per_channel(member(phases[i], p, "a"), sub(p, "a"), m.stop_a[k]);
    ++i;
  }
}

void read_detector(const json& d, const std::string& p, ChannelDetector& out) {
  out.drift_K = number(member(d, p, "drift_K"), sub(p, "drift_K"));
  out.low_drift_K = number(member(d, p, "low_drift_K"), sub(p, "low_drift_K"));
  out.warn_evidence_K_min = number(member(d, p, "warn_evidence_K_min"), sub(p, "warn_evidence_K_min"));
  out.alarm_evidence_K_min = number(member(d, p, "alarm_evidence_K_min"), sub(p, "alarm_evidence_K_min"));
  out.low_warn_evidence_K_min = number(member(d, p, "low_warn_evidence_K_min"), sub(p, "low_warn_evidence_K_min"));
  out.abs_limit_c = number(member(d, p, "abs_limit_c"), sub(p, "abs_limit_c"));
  out.max_rise_K_per_min = number(member(d, p, "max_rise_K_per_min"), sub(p, "max_rise_K_per_min"));
}

// The fields that say which channels have a model: the rest of the table is read by them.
void read_header(const json& sm, ReducedModelF64& m) {
  m.dt_ms = static_cast<uint16_t>(whole(member(sm, "", "dt_ms"), "dt_ms", 0, 65535));
  m.enabled_mask = static_cast<uint8_t>(whole(member(sm, "", "enabled_mask"), "enabled_mask", 0, 255));
  const json& amb = member(sm, "", "ambient_channel");  // 1-based, null = none
  m.ambient_channel = amb.is_null() ? kModelAmbientNone : static_cast<uint8_t>(whole(amb, "ambient_channel", 1, kModelChannels) - 1);
}

// What the blob holds of a channel depends on its kind: a model (detector, carrier), the ambient
// (its limit only) or nothing. Fields reduce does not write for that kind are left at zero.
void read_channel(const json& c, std::size_t j, ReducedModelF64& m) {
  const std::string p = at("channels", j);
  if (whole(member(c, p, "channel"), sub(p, "channel"), 0, 255) != j + 1)
    bad_field(sub(p, "channel"), fmt::format("is {}, not {} (the channels are in order)", io::json_excerpt(c["channel"]), j + 1));
  m.role[j] = role_code(member(c, p, "role"), sub(p, "role"));
  m.detector[j] = ChannelDetector{0, 0, 0, 0, 0, 0, 0};
  const auto ch = static_cast<uint8_t>(j);
  if (model_predicts(m.enabled_mask, m.ambient_channel, ch)) {
    read_detector(member(c, p, "detector"), sub(p, "detector"), m.detector[j]);
    if (c.contains("carrier_channel")) {
      m.carrier[j] = static_cast<uint8_t>(whole(c["carrier_channel"], sub(p, "carrier_channel"), 1, kModelChannels));
      m.couple[j] = number(member(c, p, "coupling_per_step"), sub(p, "coupling_per_step"));
    }
  } else if (j == m.ambient_channel) {
    m.detector[j].abs_limit_c = number(member(c, p, "abs_limit_c"), sub(p, "abs_limit_c"));
  }
}

// ---- the blob's fields, by the path of the table's field that makes each ----------------------

struct BlobField {
  std::size_t off = 0, size = 0;  // bytes in the blob
  bool is_signed = false;
  std::string path;               // in "scheduled_model"
  std::string label;              // what it is, for a user
  std::function<std::string(int64_t)> show;  // the raw value in the table's units
};

int64_t raw_value(const uint8_t* blob, const BlobField& f) {
  if (f.size == 1) return blob[f.off];
  if (f.size == 2) return f.is_signed ? static_cast<int16_t>(get_le16(blob + f.off)) : get_le16(blob + f.off);
  return f.is_signed ? static_cast<int64_t>(static_cast<int32_t>(get_le32(blob + f.off))) : get_le32(blob + f.off);
}

std::string show_q30(int64_t v) { return fmt::format("{:.9f}", std::ldexp(static_cast<double>(v), -kPoleFracBits)); }
std::string show_mk_as(int64_t v, const char* unit) { return fmt::format("{:g} {}", static_cast<double>(v) / 1000.0, unit); }
std::string show_role(int64_t v) {
  if (v == kModelRoleUnchecked) return "unchecked";
  const char* n = wire::channel_role_name(static_cast<uint8_t>(v));
  return n ? n : std::to_string(v);
}

// Every field of the blob's layout (common/model_blob.hpp) but the constants and the CRC. dt_ms
// and the ambient channel are the blob's: when the table's differ, those fields differ first.
std::vector<BlobField> blob_fields(uint16_t dt_ms, uint8_t ambient_channel) {
  auto plain = [](const char* unit) {
    return [unit](int64_t v) { return fmt::format("{}{}", v, unit); };
  };
  std::vector<BlobField> f;
  f.push_back({kBlobOffBreakpointCount, 1, false, "breakpoints", "number of breakpoints", plain("")});
  f.push_back({kBlobOffAmbientChannel, 1, false, "ambient_channel", "ambient channel", [](int64_t v) {
                 return v == kModelAmbientNone ? std::string("none") : std::to_string(v + 1);
               }});
  f.push_back({kBlobOffEnabledMask, 1, false, "enabled_mask", "channel mask", plain("")});
  f.push_back({kBlobOffDtMs, 2, false, "dt_ms", "sample period", plain(" ms")});
  for (std::size_t k = 0; k < kModelEarlyStopPhases; ++k)
    f.push_back({kBlobOffStopEnds + 2 * k, 2, false, at("stop_phase_end_s", k), fmt::format("end of stop phase {}", k + 1), plain(" s")});
  for (std::size_t i = 0; i < kModelMaxBreakpoints; ++i)
    f.push_back({kBlobOffSpeeds + 2 * i, 2, false, sub(at("breakpoints", i), "speed_rpm"), fmt::format("breakpoint {} speed", i), plain(" rpm")});
  for (std::size_t i = 0; i < kModelMaxBreakpoints; ++i)
    for (std::size_t j = 0; j < kModelChannels; ++j) {
      const std::size_t off = kBlobOffBreakpoints + kBlobBreakpointSize * i + kBlobChannelCoeffSize * j;
      const std::string p = at("breakpoints", i);
      f.push_back({off, 4, true, at(sub(p, "a"), j), fmt::format("breakpoint {}, channel {} pole", i, j + 1), show_q30});
      f.push_back({off + 4, 4, true, at(sub(p, "b_K"), j), fmt::format("breakpoint {}, channel {} heat gain", i, j + 1),
                   [](int64_t v) { return fmt::format("{:g} K", static_cast<double>(v) / 1024.0 / 1000.0); }});
    }
  for (std::size_t k = 0; k < kModelEarlyStopPhases; ++k)
    for (std::size_t j = 0; j < kModelChannels; ++j)
      f.push_back({kBlobOffStopPoles + 4 * (kModelChannels * k + j), 4, true, at(sub(at("stop_phases", k), "a"), j),
                   fmt::format("stop phase {}, channel {} pole", k + 1, j + 1), show_q30});
  auto evidence = [dt_ms](int64_t v) { return fmt::format("{:g} K min", evidence_K_min(static_cast<uint16_t>(v), dt_ms)); };
  for (std::size_t j = 0; j < kModelChannels; ++j) {
    const std::string p = at("channels", j), d = sub(p, "detector");
    const std::string ch = fmt::format("channel {} ", j + 1);
    f.push_back({kBlobOffRoles + j, 1, false, sub(p, "role"), ch + "role", show_role});
    f.push_back({kBlobOffDrift + 2 * j, 2, false, sub(d, "drift_K"), ch + "drift", [](int64_t v) { return show_mk_as(v, "K"); }});
    f.push_back({kBlobOffLowDrift + 2 * j, 2, false, sub(d, "low_drift_K"), ch + "lower drift", [](int64_t v) { return show_mk_as(v, "K"); }});
    f.push_back({kBlobOffWarnEvidence + 2 * j, 2, false, sub(d, "warn_evidence_K_min"), ch + "WARN evidence", evidence});
    f.push_back({kBlobOffAlarmEvidence + 2 * j, 2, false, sub(d, "alarm_evidence_K_min"), ch + "ALARM evidence", evidence});
    f.push_back({kBlobOffLowWarnEvidence + 2 * j, 2, false, sub(d, "low_warn_evidence_K_min"), ch + "lower WARN evidence", evidence});
    f.push_back({kBlobOffAbsLimits + 4 * j, 4, true, sub(j == ambient_channel ? p : d, "abs_limit_c"), ch + "absolute limit",
                 [](int64_t v) { return show_mk_as(v, "degC"); }});
    f.push_back({kBlobOffMaxRise + 2 * j, 2, false, sub(d, "max_rise_K_per_min"), ch + "rate-of-rise limit",
                 [](int64_t v) { return show_mk_as(v, "K/min"); }});
    f.push_back({kBlobOffCarriers + j, 1, false, sub(p, "carrier_channel"), ch + "carrier",
                 [](int64_t v) { return v == kModelNoCarrier ? std::string("none") : fmt::format("channel {}", v); }});
    f.push_back({kBlobOffCouplings + 4 * j, 4, true, sub(p, "coupling_per_step"), ch + "coupling", show_q30});
  }
  return f;
}

const char* const kEdited = "the file was edited after `btsm reduce` wrote it, and the module would get the blob's value; "
                            "re-run reduce (or flash a blob file)";

// The first field whose bytes differ between the blob and the table's encoding ("" when none).
std::string first_difference(const uint8_t* blob, const uint8_t* table, uint16_t dt_ms, uint8_t ambient_channel,
                             const std::string& blob_key) {
  for (const BlobField& f : blob_fields(dt_ms, ambient_channel)) {
    const int64_t b = raw_value(blob, f), t = raw_value(table, f);
    if (b != t)
      return fmt::format("{} contradicts \"scheduled_model\" at {} ({}: {} in the table, {} in the blob): {}", blob_key, f.path,
                         f.label, f.show(t), f.show(b), kEdited);
  }
  return {};
}

// What the blob does not hold but the table says about it: the node of each channel (reduce
// derives the role byte from it, so another node is another model), and values on channels the
// blob has no model for (it holds zeros there).
std::string unencoded_contradiction(const json& sm, const ReducedModelF64& t, const std::string& blob_key) {
  for (std::size_t j = 0; j < kModelChannels; ++j) {
    const auto ch = static_cast<uint8_t>(j);
    const std::string p = at("channels", j);
    const json& node = member(sm["channels"][j], p, "node");
    const bool predicts = model_predicts(t.enabled_mask, t.ambient_channel, ch);
    std::string want;  // what the node must be
    if (predicts) {
      if (!node.is_string() || role_for_node(node.get<std::string>()) != t.role[j])
        want = fmt::format("the node the blob's channel {} model is for (role {})", j + 1, show_role(t.role[j]));
    } else if (j == t.ambient_channel) {
      if (node != "ambient") want = "\"ambient\" (the blob's ambient channel)";
    } else if (!node.is_null()) {
      want = fmt::format("null (the blob has no model for channel {})", j + 1);
    }
    if (!want.empty())
      return fmt::format("{} contradicts \"scheduled_model\" at {}.node (channel {} node: {} in the table, not {}): {}", blob_key, p,
                         j + 1, io::printable(io::json_excerpt(node)), want, kEdited);
    if (predicts) continue;
    auto nonzero = [&](double v, const std::string& path) {
      return v == 0 ? std::string()
                    : fmt::format("{} contradicts \"scheduled_model\" at {} ({:g} in the table, but the blob has no model "
                                  "for channel {}: 0): {}",
                                  blob_key, path, v, j + 1, kEdited);
    };
    for (std::size_t i = 0; i < t.n_breakpoints; ++i)
      for (const auto& [v, key] : {std::pair{t.a[i][j], "a"}, std::pair{t.b_K[i][j], "b_K"}})
        if (auto why = nonzero(v, at(sub(at("breakpoints", i), key), j)); !why.empty()) return why;
    for (std::size_t k = 0, i = 0; k < kModelEarlyStopPhases; ++k)
      if (t.stop_end_s[k] != 0)
        if (auto why = nonzero(t.stop_a[k][j], at(sub(at("stop_phases", i++), "a"), j)); !why.empty()) return why;
  }
  return {};
}

// A table that cannot be read whole because its channel mask or ambient channel was changed (a
// channel enabled has no detector) is named by that change, the cause, instead of the symptom.
std::string header_difference(const json& sm, const ModelSchedule& s, const std::string& blob_key) {
  ReducedModelF64 h;
  try {
    read_header(sm, h);
  } catch (const std::invalid_argument&) {
    return {};
  }
  ModelSchedule hs = s;
  hs.dt_ms = h.dt_ms;
  hs.enabled_mask = h.enabled_mask;
  hs.ambient_channel = h.ambient_channel;
  std::vector<uint8_t> blob(kReducedModelBlobSize), table(kReducedModelBlobSize);
  encode_schedule(s, blob.data());
  encode_schedule(hs, table.data());
  return first_difference(blob.data(), table.data(), s.dt_ms, s.ambient_channel, blob_key);
}

}  // namespace

ReducedModelF64 scheduled_model_from_json(const json& sm) {
  ReducedModelF64 m;
  read_header(sm, m);
  read_breakpoints(sm, m);
  read_stop_phases(sm, m);
  const json& chans = array(member(sm, "", "channels"), "channels", kModelChannels);
  for (std::size_t j = 0; j < kModelChannels; ++j) read_channel(chans[j], j, m);
  return m;
}

std::string scheduled_model_contradiction(const json& sm, std::span<const uint8_t> blob, const std::string& blob_key) {
  ReducedModel decoded;
  if (!decode(blob.data(), blob.size(), decoded).ok()) return {};  // check_model_blob names that
  try {
    const ReducedModelF64 t = scheduled_model_from_json(sm);
    ReducedModel q;
    const ModelCheck c = quantize_fields(t, q);
    if (!c.ok()) {
      std::string where;
      if (c.breakpoint != 0xFF) where += fmt::format(", breakpoint {}", c.breakpoint);
      if (c.channel != 0xFF) where += fmt::format(", channel {}", c.channel + 1);
      return fmt::format("{} contradicts \"scheduled_model\": the table holds a value no blob can ({}{}): {}", blob_key,
                         model_status_name(c.status), where, kEdited);
    }
    std::vector<uint8_t> table(kReducedModelBlobSize);
    encode(q, table.data());
    if (auto why = first_difference(blob.data(), table.data(), decoded.schedule.dt_ms, decoded.schedule.ambient_channel,
                                        blob_key);
        !why.empty())
      return why;
    return unencoded_contradiction(sm, t, blob_key);
  } catch (const std::invalid_argument& e) {
    if (auto why = header_difference(sm, decoded.schedule, blob_key); !why.empty()) return why;
    return fmt::format("\"scheduled_model\" is not the table `btsm reduce` writes: {}; the blob cannot be checked against it: "
                       "re-run reduce (or flash a blob file)",
                       io::printable(e.what()));
  }
}

}  // namespace btsm::thermal
