#pragma once
// Model upload with authentication and read-back:
//   GET_INFO (device id, current model) -> MODEL_BEGIN {len, crc32} -> AUTH_CHALLENGE {nonce}
//   -> MODEL_AUTH {HMAC-SHA256(key, nonce || 0x4A || len || crc32)}: the module writes nothing
//      before this proof of the key
//   -> MODEL_CHUNKs sized so each encoded frame fits one 20-byte BLE write, each ACKed
//   -> MODEL_COMMIT {HMAC-SHA256(key, nonce || blob)} -> MODEL_READ back, byte and CRC compare
//   -> GET_INFO: model_crc and model_seq confirm the module runs the new model.
// The module stages the blob and only switches to it after a valid commit (two-phase), so any
// failure before the commit ACK leaves the previous model in place; this code says so.
#include "host/link/device_keys.hpp"
#include "host/link/model_blob_file.hpp"
#include "host/link/session.hpp"

#include <functional>
#include <string>
#include <vector>

namespace btsm::link {

struct FlashProgress {
  size_t bytes_sent = 0, total = 0;
  const char* phase = "";  // "upload", "commit", "verify"
};

struct FlashOptions {
  bool validate_locally = true;  // refuse an invalid blob before talking to the module
  std::function<void(const FlashProgress&)> progress;
};

struct FlashSummary {
  uint32_t device_id = 0;
  size_t blob_size = 0;
  size_t chunks = 0;            // MODEL_CHUNK frames sent (incl. resends after BAD_OFFSET)
  size_t max_chunk_frame = 0;   // largest encoded chunk frame, bytes (<= 20)
  size_t offset_resyncs = 0;    // BAD_OFFSET answers that moved us to the module's offset
  bool commit_confirmed_by_info = false;  // commit ACK was lost, INFO proved success
  uint32_t model_crc = 0;       // INFO after the commit
  uint32_t model_seq_before = 0, model_seq_after = 0;
  bool verified = false;        // read-back identical and INFO matches
};

// Runs the whole upload; throws NackError (with the module's reason, the previous model kept)
// or LinkError. `key` authenticates the upload (MODEL_AUTH) and the commit. A link lost once
// MODEL_COMMIT is sent is a LinkError of the same kind whose message says whether the commit was
// acknowledged, that the outcome is otherwise unknown, and which INFO values (`btsm info`) show
// the new model.
FlashSummary flash_model(Session& session, std::span<const uint8_t> blob, const DeviceKey& key,
                         const FlashOptions& opts = {});

// Reads `len` bytes of the active model back with MODEL_READ.
std::vector<uint8_t> read_model(Session& session, size_t len);

// HMAC-SHA256(key, nonce || wire::encode_model_auth_context(total_len, blob_crc32)): MODEL_AUTH.
std::array<uint8_t, 32> model_auth_tag(const DeviceKey& key, std::span<const uint8_t> nonce, uint16_t total_len,
                                       uint32_t blob_crc32);
// The model's channel map (the module role each channel's model was reduced for, model_blob.hpp)
// against the module's configured roles, channel by channel.
struct ChannelMapCheck {
  struct Channel {
    uint8_t model_role = 0;   // model_blob.hpp code (0 not modelled, 1 ambient, 0xFF unchecked)
    uint8_t module_role = 0;  // wire ChannelRole
    std::string verdict;      // "ok", "not modelled", "unchecked", "warning", "conflict"
    std::string text;         // one line for people, e.g. "ch1: model rear_bearing, module rear_bearing"
  };
  std::vector<Channel> channels;      // five
  std::vector<std::string> conflicts;  // the module would check a channel against another node's model
  std::vector<std::string> warnings;   // the model predicts a channel the module does not diagnose, ...
  bool ok() const { return conflicts.empty(); }
};
ChannelMapCheck check_channel_map(const uint8_t model_roles[5], const uint8_t module_roles[5]);
// The role bytes of a version-2 blob (false for anything else).
bool blob_channel_roles(std::span<const uint8_t> blob, uint8_t roles[5]);
// The active model's format version and role bytes read from the module (two MODEL_READs);
// version 0 when the module has no active model.
struct ActiveModelMap {
  uint8_t version = 0;
  uint8_t roles[5] = {};
  uint8_t n_breakpoints = 0;          // the speeds the model knows (entry 0 = the stop)
  uint16_t speed_rpm[7] = {};
};
ActiveModelMap read_active_model_map(Session& session);

// HMAC-SHA256(key, nonce || blob) as the module computes it.
std::array<uint8_t, 32> model_commit_tag(const DeviceKey& key, std::span<const uint8_t> nonce,
                                         std::span<const uint8_t> blob);

}  // namespace btsm::link
