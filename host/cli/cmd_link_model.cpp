// btsm flash-model: authenticated upload of a reduced model blob, with read-back.
#include "cmd_link_support.hpp"
#include "host/link/device_keys.hpp"
#include "host/io/json_input.hpp"
#include "host/io/utf8_text.hpp"
#include "host/link/model_blob_file.hpp"
#include "host/link/model_flash.hpp"
#include "host/link/recorder.hpp"

#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>

namespace btsm::cli {
namespace {

using namespace btsm::link;

struct FlashModelArgs {
  LinkOptions link;
  std::string file, key_file;
  bool json = false, force = false;
};

// A --key-file is read and checked before connecting: a bad key file is bad input (exit 2)
// whether or not a module answers. Its device id is in its name (<device_id>.key).
struct KeyFromFile {
  uint32_t device_id = 0;
  DeviceKey key{};
};

KeyFromFile read_key_file(const std::string& key_file) {
  const auto p = std::filesystem::absolute(key_file);
  const auto id = parse_device_id(p.stem().string());
  KeyStore ks(p.parent_path().string());
  if (!id || ks.path_for(*id) != p.string())
    throw CommandError(kExitUsage, "--key-file must be named <device_id>.key (8 hex digits), got " + io::printable(key_file));
  return {*id, ks.load(*id)};
}

// The signing key: the --key-file read before connecting (for this module), or the key store's.
DeviceKey signing_key(const std::optional<KeyFromFile>& from_file, const FlashModelArgs& a, uint32_t module_device_id) {
  if (!from_file) return KeyStore::from_environment().load(module_device_id);
  if (from_file->device_id != module_device_id)
    throw CommandError(kExitUsage, fmt::format("--key-file {} is for device {}, the module is {}", io::printable(a.key_file),
                                               device_id_text(from_file->device_id), device_id_text(module_device_id)));
  return from_file->key;
}

void print_flash_summary(const FlashModelArgs& a, const FlashSummary& s) {
  std::cerr << fmt::format("flash-model: module {} now runs model crc {:08x} (seq {} -> {}), {} chunks, read-back "
                           "verified\n",
                           device_id_text(s.device_id), s.model_crc, s.model_seq_before, s.model_seq_after, s.chunks);
  if (a.json)
    print_json({{"device_id", device_id_text(s.device_id)}, {"bytes", s.blob_size}, {"chunks", s.chunks},
                {"max_chunk_frame_bytes", s.max_chunk_frame}, {"offset_resyncs", s.offset_resyncs},
                {"commit_ack_lost_then_confirmed_by_info", s.commit_confirmed_by_info},
                {"model_crc", fmt::format("{:08x}", s.model_crc)}, {"model_seq", s.model_seq_after},
                {"verified", s.verified}});
}

// The blob's channel map against the module's roles: printed; a channel the module would check
// against another node's model refuses the upload unless --force (nothing is sent).
void check_map_before_flashing(const FlashModelArgs& a, Session& session, const std::vector<uint8_t>& blob) {
  const ChannelRoles roles = read_channel_roles(session);
  uint8_t model_roles[5];
  if (!blob_channel_roles(blob, model_roles)) return;
  const ChannelMapCheck mc = check_channel_map(model_roles, roles.role);
  std::cerr << "flash-model: channel map (model -> module roles" << (roles.from_module ? "" : ", module roles are defaults")
            << "):\n";
  for (const auto& ch : mc.channels) std::cerr << "  " << ch.text << "\n";
  for (const auto& w : mc.warnings) std::cerr << "flash-model: WARNING: " << w << "\n";
  if (mc.ok()) return;
  std::string all;
  for (const auto& w : mc.conflicts) all += "\n  " + w;
  if (!a.force)
    throw CommandError(kExitFailure, "the model's channel map disagrees with the module's channel roles; nothing was sent:" +
                                         all + "\n(--force flashes anyway)");
  std::cerr << "flash-model: WARNING (forced): the channel map disagrees:" << all << "\n";
}

// reduced.json keeps where the module's model holds in speed (reduce's speed check): said before
// flashing, loudly when reduce was forced past a gap. A raw blob does not carry it.
void print_speed_coverage(const nlohmann::json& c);

void print_valid_speed_range(const std::string& file) {
  nlohmann::json j;
  try {
    j = io::read_json_file(file, kMaxModelFileBytes, "model file");
  } catch (const std::exception&) {
    return;  // a raw blob (or a JSON load_model_blob already accepted without the check)
  }
  if (!j.is_object() || !j.contains("speed_coverage") || !j["speed_coverage"].is_object()) return;
  try {
    print_speed_coverage(j["speed_coverage"]);
  } catch (const nlohmann::json::exception& e) {  // informative only: the blob itself was checked
    std::cerr << "flash-model: WARNING: " << io::printable(file) << ": speed_coverage is malformed (" << io::printable(io::without_json_exception_ids(e.what()))
              << "); not shown\n";
  }
}

void print_speed_coverage(const nlohmann::json& c) {
  const auto& r = c.value("valid_speed_range_rpm", nlohmann::json::array());
  if (r.is_array() && r.size() == 2 && r[0].is_number() && r[1].is_number())
    std::cerr << fmt::format("flash-model: valid (reduce's speed check) for {:.0f}-{:.0f} rpm\n", r[0].get<double>(), r[1].get<double>());
  if (c.contains("gaps") && c["gaps"].is_array())
    for (const auto& g : c["gaps"])
      if (g.is_object())
        std::cerr << fmt::format("flash-model: WARNING: ch{}: the model is off by {:.2f} K at {:.0f}-{:.0f} rpm (reduce was forced): a "
                                 "healthy spindle running there for long WARNs\n",
                                 g.value("channel", 0), g.value("worst_steady_error_K", 0.0), g.value("from_rpm", 0.0),
                                 g.value("to_rpm", 0.0));
}

void run_flash_model(const FlashModelArgs& a) {
  // The key file is read and checked before connecting (its device id is compared after).
  std::optional<KeyFromFile> from_file;
  if (!a.key_file.empty()) from_file = read_key_file(a.key_file);
  const auto blob = load_model_blob(a.file);
  const std::string why = check_model_blob(blob);
  if (!why.empty()) throw CommandError(kExitUsage, a.file + ": " + why);
  std::cerr << "flash-model: " << describe_model_speeds(blob) << "\n";
  print_valid_speed_range(a.file);
  auto conn = connect(a.link);
  const auto info = conn.session->get_info();
  check_map_before_flashing(a, *conn.session, blob);
  const DeviceKey key = signing_key(from_file, a, info.device_id);
  const bool tty = ::isatty(STDERR_FILENO);
  FlashOptions fo;
  fo.progress = [&](const FlashProgress& p) {
    if (!tty) return;
    std::cerr << fmt::format("\rflash-model: {:<7} {:>4}/{} bytes", p.phase, p.bytes_sent, p.total) << std::flush;
  };
  const FlashSummary s = flash_model(*conn.session, blob, key, fo);
  if (tty) std::cerr << "\n";
  print_flash_summary(a, s);
}

void register_flash_model(CLI::App& app) {
  auto a = std::make_shared<FlashModelArgs>();
  auto* c = app.add_subcommand("flash-model", "Upload a reduced model blob to the module, authenticated, with read-back");
  c->footer(
      "FILE is the blob written by `btsm reduce --blob model.bin`, or a JSON holding it as \"blob_hex\"\n"
      "(or naming it with \"blob_file\"). The blob is validated first (size 464, CRC, version, poles,\n"
      "gains). The upload: GET_INFO (device id) -> MODEL_BEGIN -> AUTH_CHALLENGE (single-use nonce) ->\n"
      "MODEL_AUTH with HMAC-SHA256(device key, nonce || 0x4A || length || CRC-32): the module writes\n"
      "nothing before this proof of the key -> chunks that each fit one 20-byte BLE write, each\n"
      "acknowledged -> MODEL_COMMIT with HMAC-SHA256(device key, nonce || blob) -> MODEL_READ of the\n"
      "whole blob and CRC compare -> INFO shows the new CRC and sequence. The key comes from the key\n"
      "store (`btsm keys path`) for the module's device id. The module keeps its previous model unless\n"
      "the commit is accepted; a refusal prints the module's reason (AUTH_FAILED = wrong key,\n"
      "BLOB_INVALID, ...). A link lost after MODEL_COMMIT was sent exits 3 and says what `btsm info`\n"
      "shows if the new model is active. Bad input (not a blob, not hex, a bad key file) exits 2.\n"
      "The blob's channel map (the node each channel's model predicts) is compared with the module's channel\n"
      "roles first: a channel the module would check against another node's model is refused unless --force.");
  add_link_options(*c, a->link);
  c->add_option("file", a->file, "model blob (.bin) or JSON with the blob")->required()->check(existing_input_file());
  c->add_option("--key-file", a->key_file, "use this key file instead of the key store (must be mode 0600)");
  c->add_flag("--json", a->json, "print the summary as JSON");
  c->add_flag("--force", a->force, "flash even when the model's channel map disagrees with the module's channel roles");
  c->callback([a] { guarded([&] { run_flash_model(*a); }); });
}

}  // namespace

void register_link_model_commands(CLI::App& app) { register_flash_model(app); }

}  // namespace btsm::cli
