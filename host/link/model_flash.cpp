#include "host/link/model_flash.hpp"

#include "common/crc.hpp"
#include "common/hmac.hpp"
#include "common/model_blob.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace btsm::link {

using namespace btsm::wire;

namespace {

// INFO.model_crc names the active blob: the CRC stored in the blob (model_blob.hpp), which
// some firmware builds may report as the CRC-32 over the whole blob instead; both identify it.
bool info_crc_matches(uint32_t info_crc, std::span<const uint8_t> blob) {
  if (blob.size() == kReducedModelBlobSize && info_crc == blob_stored_crc(blob.data())) return true;
  return info_crc == crc32(blob.data(), blob.size());
}

// MODEL_AUTH, the step that lets the module write. A retried MODEL_AUTH whose first attempt was
// accepted (its ACK lost) finds the session past the challenge: NO_SESSION then means "already
// authenticated", which the first chunk confirms or refutes.
void authenticate_upload(Session& session, const DeviceKey& key, const AuthChallenge& challenge, uint16_t total_len,
                         uint32_t blob_crc32, const Info& info) {
  ModelAuth a{};
  const auto tag = model_auth_tag(key, std::span<const uint8_t>(challenge.nonce, kNonceSize), total_len, blob_crc32);
  std::copy(tag.begin(), tag.end(), a.hmac);
  uint8_t p[kMaxPayload];
  const uint8_t len = encode_model_auth(a, p);
  int attempts = 0;
  try {
    session.request(MsgType::ModelAuth, std::span<const uint8_t>(p, len), std::nullopt, &attempts);
  } catch (const NackError& e) {
    if (e.code() == static_cast<uint8_t>(Nack::UnknownType))
      throw LinkError(LinkErrorKind::kProtocol,  // the operation failed (exit 1), the device is there
                      fmt::format("the module (firmware {}.{}.{}) does not know MODEL_AUTH: that firmware writes model "
                                  "chunks before it checks the key. Update it (`btsm flash-firmware`), then flash the "
                                  "model again; nothing was written",
                                  info.fw_major, info.fw_minor, info.fw_patch));
    if (attempts > 1 && e.code() == static_cast<uint8_t>(Nack::NoSession)) return;
    throw;
  }
}

// A link failure once MODEL_COMMIT is on its way: say what is known about the module's model and
// how to find out the rest, instead of a bare "device hung up".
[[noreturn]] void link_lost_after_commit(const LinkError& e, bool commit_acknowledged, std::span<const uint8_t> blob,
                                         const Info& before) {
  const uint32_t new_crc = blob.size() == kReducedModelBlobSize ? blob_stored_crc(blob.data()) : crc32(blob.data(), blob.size());
  const std::string check = fmt::format("Check with `btsm info`: model crc {:08x} with a model seq other than {} is the new model", new_crc,
                                        before.model_seq);
  if (commit_acknowledged)
    throw LinkError(e.kind(), fmt::format("the module accepted the commit (the new model is stored), then the link was lost "
                                          "before the read-back verified it: {}. {}",
                                          e.what(), check));
  throw LinkError(e.kind(), fmt::format("the link was lost after MODEL_COMMIT was sent: {}. Whether the module took the new "
                                        "model is unknown. {}; crc {:08x} seq {} means the previous model is still active "
                                        "and nothing changed (flash again)",
                                        e.what(), check, before.model_crc, before.model_seq));
}

}  // namespace

std::array<uint8_t, 32> model_auth_tag(const DeviceKey& key, std::span<const uint8_t> nonce, uint16_t total_len,
                                       uint32_t blob_crc32) {
  uint8_t context[kModelAuthContextSize];
  encode_model_auth_context(total_len, blob_crc32, context);
  std::array<uint8_t, 32> tag{};
  HmacSha256 mac;
  mac.init(key.data(), key.size());
  mac.update(nonce.data(), nonce.size());
  mac.update(context, sizeof context);
  mac.final(tag.data());
  return tag;
}

namespace {
std::string role_text(uint8_t model_role) {
  if (model_role == kModelRoleUnchecked) return "a node without a role name";
  const char* n = channel_role_name(model_role);
  return n ? n : fmt::format("role {}", model_role);
}
}  // namespace

ChannelMapCheck check_channel_map(const uint8_t model_roles[5], const uint8_t module_roles[5]) {
  ChannelMapCheck c;
  for (int j = 0; j < 5; ++j) {
    ChannelMapCheck::Channel ch;
    ch.model_role = model_roles[j];
    ch.module_role = module_roles[j];
    const char* mod = channel_role_name(module_roles[j]);
    const std::string module = mod ? mod : fmt::format("role {}", module_roles[j]);
    const std::string chn = fmt::format("ch{}", j + 1);
    if (ch.model_role == kModelRoleNotModelled) {
      ch.verdict = "not modelled";
      ch.text = fmt::format("{}: no model, module {}", chn, module);
    } else if (ch.model_role == kModelRoleUnchecked) {
      ch.verdict = "unchecked";
      ch.text = fmt::format("{}: model of {} (not checked against the module's role), module {}", chn,
                            role_text(ch.model_role), module);
    } else if (ch.model_role == ch.module_role) {
      ch.verdict = "ok";
      ch.text = fmt::format("{}: model {}, module {}", chn, role_text(ch.model_role), module);
    } else if (ch.model_role == kModelRoleAmbient || ch.module_role == static_cast<uint8_t>(ChannelRole::Ambient) ||
               is_thermal_role(ch.module_role)) {
      ch.verdict = "conflict";
      ch.text = fmt::format("{}: model {}, module {}  <-- DISAGREE", chn, role_text(ch.model_role), module);
      c.conflicts.push_back(
          ch.model_role == kModelRoleAmbient
              ? fmt::format("the model takes its ambient from {}, but the module's {} is {}: the module would predict nothing", chn, chn, module)
              : fmt::format("{} is {} on the module but the model there predicts the {}: probes or roles swapped? "
                            "(reduce with the module's roles, or set channel_role_{} {})",
                            chn, module, role_text(ch.model_role), j + 1, role_text(ch.model_role)));
    } else {
      ch.verdict = "warning";
      ch.text = fmt::format("{}: model {}, module {} (not diagnosed)", chn, role_text(ch.model_role), module);
      c.warnings.push_back(fmt::format("{} has a model of the {} but the module's role is {}: it is not diagnosed "
                                       "(set channel_role_{} {} to diagnose it)",
                                       chn, role_text(ch.model_role), module, j + 1, role_text(ch.model_role)));
    }
    c.channels.push_back(ch);
  }
  // The module predicts every channel relative to the ambient channel: a model without one
  // predicts nothing and reports NORMAL for ever (probe 5: a 30 W fault never ALARMed).
  bool has_ambient = false, predicts = false;
  for (int j = 0; j < 5; ++j) {
    has_ambient = has_ambient || model_roles[j] == kModelRoleAmbient;
    predicts = predicts || (model_roles[j] != kModelRoleNotModelled && model_roles[j] != kModelRoleAmbient);
  }
  if (predicts && !has_ambient)
    c.conflicts.push_back("the model has no ambient channel: the module predicts every channel relative to its ambient "
                          "channel, so it would predict nothing and flag no fault (reduce again with --channels ...,ambient,...)");
  return c;
}

bool blob_channel_roles(std::span<const uint8_t> blob, uint8_t roles[5]) {
  if (blob.size() != kReducedModelBlobSize || blob_version(blob.data(), blob.size()) != kReducedModelVersion) return false;
  for (int j = 0; j < 5; ++j) roles[j] = blob[kBlobOffRoles + j];
  return true;
}

ActiveModelMap read_active_model_map(Session& session) {
  ActiveModelMap m;
  const ModelData head = session.model_read(0, static_cast<uint8_t>(kBlobOffVersion + 1));
  if (head.len != kBlobOffVersion + 1 || get_le32(head.data) != kReducedModelMagic) return m;
  m.version = head.data[kBlobOffVersion];
  if (m.version != kReducedModelVersion) return m;
  const ModelData r = session.model_read(static_cast<uint16_t>(kBlobOffRoles), kModelChannels);
  for (int j = 0; j < 5 && j < r.len; ++j) m.roles[j] = r.data[j];
  const ModelData n = session.model_read(static_cast<uint16_t>(kBlobOffBreakpointCount), 1);
  const ModelData sp = session.model_read(static_cast<uint16_t>(kBlobOffSpeeds), 2 * kModelMaxBreakpoints);
  if (n.len == 1 && n.data[0] <= kModelMaxBreakpoints && sp.len == 2 * kModelMaxBreakpoints) {
    m.n_breakpoints = n.data[0];
    for (int i = 0; i < kModelMaxBreakpoints; ++i) m.speed_rpm[i] = get_le16(sp.data + 2 * i);
  }
  return m;
}

std::array<uint8_t, 32> model_commit_tag(const DeviceKey& key, std::span<const uint8_t> nonce,
                                         std::span<const uint8_t> blob) {
  std::array<uint8_t, 32> tag{};
  HmacSha256 mac;
  mac.init(key.data(), key.size());
  mac.update(nonce.data(), nonce.size());
  mac.update(blob.data(), blob.size());
  mac.final(tag.data());
  return tag;
}

std::vector<uint8_t> read_model(Session& session, size_t len) {
  std::vector<uint8_t> out;
  out.reserve(len);
  while (out.size() < len) {
    const auto n = static_cast<uint8_t>(std::min<size_t>(kMaxModelData, len - out.size()));
    const ModelData d = session.model_read(static_cast<uint16_t>(out.size()), n);
    out.insert(out.end(), d.data, d.data + d.len);
  }
  return out;
}

FlashSummary flash_model(Session& session, std::span<const uint8_t> blob, const DeviceKey& key,
                         const FlashOptions& opts) {
  FlashSummary s;
  s.blob_size = blob.size();
  if (opts.validate_locally) {
    const std::string why = check_model_blob(blob);
    if (!why.empty()) throw std::runtime_error("model blob rejected before upload: " + why);
  }
  if (blob.empty() || blob.size() > kMaxModelBlobSize)
    throw std::runtime_error(fmt::format("model blob of {} bytes: 1..{} bytes expected", blob.size(), kMaxModelBlobSize));
  auto report = [&](size_t sent, const char* phase) {
    if (opts.progress) opts.progress(FlashProgress{sent, blob.size(), phase});
  };

  const Info before = session.get_info();
  s.device_id = before.device_id;
  s.model_seq_before = before.model_seq;

  const uint32_t crc = crc32(blob.data(), blob.size());
  const AuthChallenge challenge = session.model_begin(static_cast<uint16_t>(blob.size()), crc);
  authenticate_upload(session, key, challenge, static_cast<uint16_t>(blob.size()), crc, before);

  // Upload. BAD_OFFSET carries the offset the module expects next: after a lost ACK it is
  // already past our chunk; after lost chunk data it is behind. Either way continue there.
  size_t offset = 0;
  size_t resyncs_left = 16;
  report(0, "upload");
  while (offset < blob.size()) {
    const uint8_t n = model_chunk_fit(session.next_seq(), static_cast<uint16_t>(offset), blob.data() + offset,
                                      blob.size() - offset, session.chunk_frame_limit());
    if (n == 0) throw std::logic_error("model chunk sizing failed");
    uint8_t payload[kMaxPayload];
    put_le16(payload, static_cast<uint16_t>(offset));
    std::copy(blob.begin() + static_cast<long>(offset), blob.begin() + static_cast<long>(offset + n), payload + 2);
    s.max_chunk_frame = std::max(s.max_chunk_frame,
                                 encoded_frame_size(type_code(MsgType::ModelChunk), session.next_seq(), payload,
                                                    static_cast<uint8_t>(n + 2)));
    ++s.chunks;
    try {
      session.model_chunk(static_cast<uint16_t>(offset), blob.subspan(offset, n));
    } catch (const NackError& e) {
      if (e.code() != static_cast<uint8_t>(Nack::BadOffset) || resyncs_left == 0 || e.detail() > offset + n)
        throw;
      --resyncs_left;
      ++s.offset_resyncs;
      offset = e.detail();
      continue;
    }
    offset += n;
    report(offset, "upload");
  }

  report(blob.size(), "commit");
  const auto tag = model_commit_tag(key, std::span<const uint8_t>(challenge.nonce, kNonceSize), blob);
  int attempts = 0;
  try {
    ModelCommit c{};
    std::copy(tag.begin(), tag.end(), c.hmac);
    uint8_t p[kMaxPayload];
    const uint8_t len = encode_model_commit(c, p);
    session.request(MsgType::ModelCommit, std::span<const uint8_t>(p, len), std::nullopt, &attempts);
  } catch (const NackError& e) {
    // A retried commit whose first attempt was applied (ACK lost) is refused because the nonce
    // is spent. INFO tells the truth: the new model is active exactly when its CRC and a new
    // sequence number show up.
    const bool maybe_applied = attempts > 1 && (e.code() == static_cast<uint8_t>(Nack::NoSession) ||
                                                e.code() == static_cast<uint8_t>(Nack::AuthFailed));
    if (!maybe_applied) throw;
    Info now{};
    try {
      now = session.get_info();
    } catch (const NackError&) {
      throw;
    } catch (const LinkError& lost) {
      link_lost_after_commit(lost, false, blob, before);
    }
    if (!(now.model_seq != before.model_seq && info_crc_matches(now.model_crc, blob))) throw;
    s.commit_confirmed_by_info = true;
  } catch (const LinkError& e) {
    link_lost_after_commit(e, false, blob, before);
  }

  report(0, "verify");
  std::vector<uint8_t> back;
  Info after{};
  try {
    back = read_model(session, blob.size());
    after = session.get_info();
  } catch (const NackError&) {
    throw;
  } catch (const LinkError& e) {
    link_lost_after_commit(e, true, blob, before);
  }
  if (!std::equal(back.begin(), back.end(), blob.begin(), blob.end()))
    throw LinkError(LinkErrorKind::kProtocol,
                    "read-back differs from the uploaded model although the module acknowledged the commit");
  if (crc32(back.data(), back.size()) != crc)
    throw LinkError(LinkErrorKind::kProtocol, "read-back CRC-32 mismatch");
  s.model_crc = after.model_crc;
  s.model_seq_after = after.model_seq;
  if (!info_crc_matches(after.model_crc, blob) || after.model_seq == before.model_seq ||
      after.model_state != static_cast<uint8_t>(ModelState::Active))
    throw LinkError(LinkErrorKind::kProtocol,
                    fmt::format("module INFO after commit: model_crc 0x{:08x} (expected 0x{:08x}), model_seq {} "
                                "(before {}), state {}: the new model is not active",
                                after.model_crc, blob.size() == kReducedModelBlobSize ? blob_stored_crc(blob.data()) : crc, after.model_seq, before.model_seq,
                                after.model_state));
  report(blob.size(), "verify");
  s.verified = true;
  return s;
}

}  // namespace btsm::link
