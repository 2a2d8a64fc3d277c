#include "host/link/model_blob_file.hpp"

#include "common/byte_order.hpp"
#include "common/model_blob.hpp"
#include "host/io/hex.hpp"
#include "host/io/input_error.hpp"
#include "host/io/input_file.hpp"
#include "host/io/json_input.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <filesystem>

namespace btsm::link {

namespace {

std::vector<uint8_t> bytes_of(const std::string& s) { return std::vector<uint8_t>(s.begin(), s.end()); }

bool looks_like_json(std::string_view content, const std::string& path) {
  if (std::filesystem::path(path).extension() == ".json") return true;
  const auto first = content.find_first_not_of(" \t\r\n");
  return first != std::string_view::npos && content[first] == '{';
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
  if (node->is_object()) {
    for (const char* key : {"blob_hex", "hex", "blob"})
      if (node->contains(key) && (*node)[key].is_string())
        return io::hex_to_bytes((*node)[key].get_ref<const std::string&>(), path + ": \"" + key + "\"");
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
