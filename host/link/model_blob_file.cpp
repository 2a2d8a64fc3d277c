#include "host/link/model_blob_file.hpp"

#include "common/byte_order.hpp"
#include "common/model_blob.hpp"
#include "host/io/hex.hpp"
#include "host/io/input_error.hpp"
#include "host/io/input_file.hpp"
#include "host/io/json_input.hpp"
#include "host/thermal/reduced_model_json.hpp"

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

// A reduced-model JSON whose "scheduled_model" table says another model than its blob was edited
// after `btsm reduce` wrote both: flashing would send the blob's values, not the ones a user reads
// (and may have raised). Every field the blob encodes is compared (thermal/reduced_model_json).
std::vector<uint8_t> checked_against_table(std::vector<uint8_t> blob, const nlohmann::json& j, const std::string& path,
                                           const std::string& blob_key) {
  if (j.is_object() && j.contains("scheduled_model"))
    if (const std::string why = thermal::scheduled_model_contradiction(j["scheduled_model"], blob, blob_key); !why.empty())
      throw io::InputError(path + ": " + why);
  return blob;
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
        return checked_against_table(io::hex_to_bytes((*node)[key].get_ref<const std::string&>(), path + ": \"" + key + "\""), j,
                                     path, std::string("\"") + key + "\"");
      }
    for (const char* key : {"blob_file", "blob_path", "file", "path"}) {
      if (node->contains(key) && (*node)[key].is_string()) {
        std::filesystem::path p = (*node)[key].get<std::string>();
        if (p.is_relative()) p = std::filesystem::path(path).parent_path() / p;
        return checked_against_table(read_blob_file(p.string()), j, path, std::string("\"") + key + "\" (" + p.string() + ")");
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
