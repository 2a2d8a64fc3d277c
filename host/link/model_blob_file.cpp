#include "host/link/model_blob_file.hpp"

#include "common/byte_order.hpp"
#include "common/model_blob.hpp"
#include "host/io/hex.hpp"
#include "host/io/input_error.hpp"
#include "host/io/input_file.hpp"
#include "host/io/json_input.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>

namespace btsm::link {

namespace {

std::vector<uint8_t> bytes_of(const std::string& s) { return std::vector<uint8_t>(s.begin(), s.end()); }

bool looks_like_json(std::string_view content, const std::string& path) {
  if (std::filesystem::path(path).extension() == ".json") return true;
  const auto first = content.find_first_not_of(" \t\r\n");
  return first != std::string_view::npos && content[first] == '{';
}

// Where a reduced-model JSON's "blob_hex" and its "scheduled_model" disagree ("" when they agree
// or the blob does not decode: check_model_blob() then names that). `btsm reduce` writes both from
// one model; an edit to either is caught here instead of flashing something the table above it
// does not describe. Compared: what a user reads and might edit -- sample period, channel mask, the
// ambient channel, the breakpoint speeds and the poles (to their Q1.30 resolution).
std::string blob_contradicts_schedule(const std::vector<uint8_t>& blob, const nlohmann::json& sm) {
  ReducedModel m;
  if (!decode(blob.data(), blob.size(), m).ok()) return {};
  if (!sm.is_object()) return "\"scheduled_model\" is not an object";
  // A compared field that is no number would be skipped by the comparison below: name it.
  auto not_number = [](const nlohmann::json& j, const char* key) {
    return j.is_object() && j.contains(key) && !j[key].is_number();
  };
  for (const char* key : {"dt_ms", "enabled_mask"})
    if (not_number(sm, key)) return std::string(key) + " is " + io::json_excerpt(sm[key]) + ", not a number";
  if (sm.contains("breakpoints") && sm["breakpoints"].is_array())
    for (std::size_t i = 0; i < sm["breakpoints"].size(); ++i) {
      const nlohmann::json& bp = sm["breakpoints"][i];
      if (not_number(bp, "speed_rpm")) return fmt::format("breakpoint {}: speed_rpm is {}, not a number", i, io::json_excerpt(bp["speed_rpm"]));
      if (bp.is_object() && bp.contains("a") && bp["a"].is_array())
        for (std::size_t k = 0; k < bp["a"].size(); ++k)
          if (!bp["a"][k].is_number() && !bp["a"][k].is_null())
            return fmt::format("breakpoint {} channel {}: pole is {}, not a number", i, k + 1, io::json_excerpt(bp["a"][k]));
    }
  const ModelSchedule& s = m.schedule;
  auto number = [&](const nlohmann::json& j, const char* key, double& v) {
    if (!j.is_object() || !j.contains(key) || !j[key].is_number()) return false;
    v = j[key].get<double>();
    return true;
  };
  double v = 0;
  if (number(sm, "dt_ms", v) && v != s.dt_ms) return fmt::format("dt_ms {} in the blob, {} in scheduled_model", s.dt_ms, v);
  if (number(sm, "enabled_mask", v) && v != s.enabled_mask)
    return fmt::format("enabled_mask {} in the blob, {} in scheduled_model", s.enabled_mask, v);
  if (sm.contains("ambient_channel")) {
    const nlohmann::json& a = sm["ambient_channel"];
    const int blob_ch = s.ambient_channel == kModelAmbientNone ? 0 : s.ambient_channel + 1;
    const int json_ch = a.is_number_integer() ? a.get<int>() : 0;
    if ((a.is_null() || a.is_number_integer()) && blob_ch != json_ch)
      return fmt::format("ambient channel {} in the blob, {} in scheduled_model", blob_ch ? std::to_string(blob_ch) : "none",
                         json_ch ? std::to_string(json_ch) : "none");
  }
  if (!sm.contains("breakpoints") || !sm["breakpoints"].is_array()) return {};
  const nlohmann::json& bps = sm["breakpoints"];
  if (bps.size() != s.n_breakpoints)
    return fmt::format("{} breakpoints in the blob, {} in scheduled_model", s.n_breakpoints, bps.size());
  for (uint8_t i = 0; i < s.n_breakpoints; ++i) {
    if (number(bps[i], "speed_rpm", v) && v != s.speed_rpm[i])
      return fmt::format("breakpoint {}: {} rpm in the blob, {} in scheduled_model", i, s.speed_rpm[i], v);
    if (!bps[i].is_object() || !bps[i].contains("a") || !bps[i]["a"].is_array() || bps[i]["a"].size() != kModelChannels) continue;
    for (uint8_t j = 0; j < kModelChannels; ++j) {
      const nlohmann::json& aj = bps[i]["a"][j];
      if (!aj.is_number() || !model_predicts(s.enabled_mask, s.ambient_channel, j)) continue;
      const double blob_a = std::ldexp(static_cast<double>(m.bp[i].ch[j].a_q30), -kPoleFracBits);
      if (std::abs(blob_a - aj.get<double>()) > 1e-6)
        return fmt::format("breakpoint {} channel {}: pole {:.9f} in the blob, {:.9f} in scheduled_model", i, j + 1, blob_a,
                           aj.get<double>());
    }
  }
  return {};
}

}  // namespace

std::vector<uint8_t> model_blob_from_content(std::string_view content, const std::string& path,
                                             const std::function<std::vector<uint8_t>(const std::string&)>& read_blob_file) {
  if (!looks_like_json(content, path)) return std::vector<uint8_t>(content.begin(), content.end());
  const nlohmann::json j = io::parse_json_text(content, path);
  // The blob may sit at the top level or inside a "blob" / "model" object.
  const nlohmann::json* node = &j;
  if (j.is_object())
    for (const char* obj : {"blob", "model"})
      if (j.contains(obj) && j[obj].is_object()) node = &j[obj];
  if (j.is_object() && j.contains("format")) {
    // flash-model takes what `btsm reduce` writes ("btsm-reduced-model-N"); the fitted model from
    // `btsm fit` has no blob, and a format that is no string says the file is not ours.
    const nlohmann::json& f = j["format"];
    if (!f.is_string() || f.get_ref<const std::string&>().rfind("btsm-reduced-model", 0) != 0)
      throw io::InputError(path + ": \"format\" is " + io::json_excerpt(f) +
                           (f.is_string() && f.get_ref<const std::string&>().rfind("btsm-thermal-model", 0) == 0
                                ? ", a fitted model from `btsm fit`: reduce it first (`btsm reduce MODEL.json --out reduced.json`) and flash that"
                                : ", not a reduced model from `btsm reduce` (\"btsm-reduced-model-2\")"));
  }
  if (node->is_object()) {
    // Two places a blob could come from are one too many: say which was meant instead of picking.
    std::vector<std::string> given;
    for (const char* key : {"blob_hex", "hex", "blob", "blob_file", "blob_path", "file", "path"})
      if (node->contains(key)) {
        if (!(*node)[key].is_string())
          throw io::InputError(path + ": \"" + key + "\" is " + io::json_excerpt((*node)[key]) + ", not a string (" +
                               (std::string(key).find("hex") != std::string::npos || std::string(key) == "blob"
                                                  ? "the blob as hex digits)"
                                                  : "the path of a blob file)"));
        given.push_back(std::string("\"") + key + "\"");
      }
    if (given.size() > 1)
      throw io::InputError(path + ": gives the blob twice (" + given[0] + " and " + given[1] + "); keep the one meant");
    for (const char* key : {"blob_hex", "hex", "blob"})
      if (node->contains(key) && (*node)[key].is_string()) {
        auto blob = io::hex_to_bytes((*node)[key].get_ref<const std::string&>(), path + ": \"" + key + "\"");
        if (j.is_object() && j.contains("scheduled_model"))
          if (const std::string why = blob_contradicts_schedule(blob, j["scheduled_model"]); !why.empty())
            throw io::InputError(path + ": \"" + key + "\" contradicts \"scheduled_model\" (" + why +
                                 "): the file was edited after `btsm reduce` wrote it; reduce again, or flash a blob file");
        return blob;
      }
    for (const char* key : {"blob_file", "blob_path", "file", "path"}) {
      if (node->contains(key) && (*node)[key].is_string()) {
        std::filesystem::path p = (*node)[key].get<std::string>();
        if (p.is_relative()) p = std::filesystem::path(path).parent_path() / p;
        return read_blob_file(p.string());
      }
    }
  }
  throw io::InputError(path + ": this JSON holds no model blob (looked for \"blob_hex\" or \"blob_file\"): "
                              "write the blob with `btsm reduce ... --blob model.bin` and flash model.bin");
}

std::vector<uint8_t> load_model_blob(const std::string& path) {
  const std::string content = io::read_input_file(path, kMaxModelFileBytes, "model file", io::FileKind::Binary);
  return model_blob_from_content(content, path, [](const std::string& blob_path) {
    return bytes_of(io::read_input_file(blob_path, kMaxBlobFileBytes, "model blob", io::FileKind::Binary));
  });
}

std::string check_model_blob(std::span<const uint8_t> blob) {
  if (blob.size() != kReducedModelBlobSize)
    return fmt::format("model blob is {} bytes, expected {}", blob.size(), kReducedModelBlobSize);
  ReducedModel m;
  const ModelCheck c = decode(blob.data(), blob.size(), m);
  if (c.ok()) return {};
  if (c.status == ModelStatus::kBadVersion)
    return fmt::format("model blob format version {} is not supported: this btsm and its firmware read version {} "
                       "(one first-order model per channel); reduce the fitted model again with this btsm",
                       c.channel, kReducedModelVersion);
  std::string where;
  if (c.breakpoint != 0xFF) where = fmt::format(" (breakpoint {})", c.breakpoint);
  else if (c.channel != 0xFF) where = fmt::format(" (channel {})", c.channel + 1);
  return std::string(model_status_name(c.status)) + where;
}

std::string describe_model_speeds(const uint16_t* speeds, uint8_t n) {
  if (n < 2) return "no running breakpoint";
  std::string list;
  for (uint8_t i = 1; i < n; ++i) list += fmt::format("{}{}", i > 1 ? ", " : "", speeds[i]);
  // Why say it: below the lowest breakpoint the module interpolates towards the stop, above the top
  // one it keeps the top one; `reduce` printed (and reduced.json keeps) where that holds.
  return fmt::format("running breakpoints {} rpm (0 rpm = stopped; interpolated between them, above {} rpm the {} rpm model; "
                     "the range where it holds is what `reduce` printed as valid)",
                     list, speeds[n - 1], speeds[n - 1]);
}

std::string describe_model_speeds(std::span<const uint8_t> blob) {
  if (blob.size() < kBlobOffSpeeds + 2 * kModelMaxBreakpoints) return {};
  const uint8_t n = blob[kBlobOffBreakpointCount];
  if (n > kModelMaxBreakpoints) return {};
  uint16_t speeds[kModelMaxBreakpoints] = {};
  for (uint8_t i = 0; i < n; ++i) speeds[i] = get_le16(blob.data() + kBlobOffSpeeds + 2 * i);
  return describe_model_speeds(speeds, n);
}

}  // namespace btsm::link
