#pragma once
// Test helper: a valid reduced-model blob for the spindle and the host side of the authenticated
// model upload (MODEL_BEGIN -> AUTH_CHALLENGE, MODEL_AUTH with HMAC-SHA256(device key, nonce ||
// auth context), MODEL_CHUNKs each ACKed, MODEL_COMMIT with HMAC-SHA256(device key, nonce ||
// blob)), written over any simulated link; and the same upload tried by a host without the key.
//
// A Link provides: void send(const std::vector<uint8_t>&); void step(double sim_s);
// test::Capture& capture().
#include "common/crc.hpp"
#include "common/hmac.hpp"
#include "common/model_blob.hpp"
#include "common/device_key.hpp"
#include "host/thermal/model_reference.hpp"
#include "wire_capture.hpp"

#include <array>
#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace btsm::test {

// A plausible model of the spindle (2 breakpoints: stopped, 6000 rpm; one first-order model
// per channel with the module's default channel roles) with wide detector thresholds so it never
// raises an alarm on its own; `variant` changes the WARN threshold so two models have different
// blobs and CRCs.
inline std::vector<uint8_t> spindle_model_blob(int variant) {
  thermal::ReducedModelF64 f;
  f.dt_ms = 5000;
  f.n_breakpoints = 2;
  f.speed_rpm[0] = 0;
  f.speed_rpm[1] = 6000;
  f.ambient_channel = 3;
  f.enabled_mask = 0x1F;
  const double tau_s[2][5] = {{13000, 13600, 17400, 0, 14600}, {2400, 2800, 2900, 0, 2600}};  // stopped, 6000 rpm
  const double rise_k[5] = {13.6, 12.2, 10.7, 0.0, 6.1};  // steady rises at 6000 rpm
  const uint8_t roles[5] = {3, 4, 2, kModelRoleAmbient, kModelRoleUnchecked};
  for (int j = 0; j < 5; ++j) {
    f.role[j] = roles[j];
    f.detector[j].drift_K = 5.0;
    f.detector[j].low_drift_K = 5.0;
    f.detector[j].warn_evidence_K_min = 200.0 + variant;
    f.detector[j].alarm_evidence_K_min = 400.0;
    f.detector[j].low_warn_evidence_K_min = 200.0;
    f.detector[j].abs_limit_c = 120.0;
    f.detector[j].max_rise_K_per_min = 0.0;
    if (j == 3) continue;
    // The bearings and the shaft ride on the housing (ch2): the most carrier terms a model can
    // have (a carrier is plain), so the firmware bench measures the costliest model step.
    // DC-matched with the housing's steady rise.
    const bool carried = j != 1;
    const double c = carried ? 0.3 * (1.0 - std::exp(-5.0 / tau_s[1][j])) : 0.0;
    f.carrier[j] = carried ? 2 : 0;
    f.couple[j] = c;
    for (int k = 0; k < 2; ++k) {
      f.a[k][j] = std::exp(-5.0 / tau_s[k][j]);
      f.b_K[k][j] = k == 0 ? 0.0 : rise_k[j] * (1.0 - f.a[k][j]) - c * rise_k[1];
    }
  }
  ReducedModel q{};
  const ModelCheck c = thermal::quantize(f, q);
  if (c.status != ModelStatus::kOk) throw std::runtime_error(std::string("test model: ") + model_status_name(c.status));
  std::vector<uint8_t> blob(kReducedModelBlobSize);
  encode(q, blob.data());
  return blob;
}

inline std::array<uint8_t, 32> development_key() {
  std::array<uint8_t, 32> k{};
  for (uint8_t i = 0; i < 32; ++i) k[i] = device_key::dev_key_byte(i);
  return k;
}

// Largest chunk whose encoded MODEL_CHUNK frame fits one 20-byte BLE write.
inline uint8_t chunk_len_at(const std::vector<uint8_t>& blob, size_t off) {
  for (uint8_t n = 16; n > 0; --n) {
    if (off + n > blob.size()) continue;
    uint8_t p[2 + 16];
    p[0] = uint8_t(off);
    p[1] = uint8_t(off >> 8);
    for (uint8_t i = 0; i < n; ++i) p[2 + i] = blob[off + i];
    if (frame(uint8_t(wire::MsgType::ModelChunk), 0, p, uint8_t(2 + n)).size() <= wire::kBleWriteSize) return n;
  }
  return uint8_t(std::min<size_t>(1, blob.size() - off));
}

template <class Link>
bool wait_for(Link& link, double max_s, const std::function<bool()>& done, double step_s = 0.01) {
  for (double t = 0; t < max_s; t += step_s) {
    if (done()) return true;
    link.step(step_s);
  }
  return done();
}

// Sends one request and returns the status of its ACK (-1: no ACK within max_s).
template <class Link>
int request_status(Link& link, wire::MsgType type, uint8_t& seq, const uint8_t* p, uint8_t len, double max_s = 2.0) {
  Capture& cap = link.capture();
  const size_t a0 = cap.acks.size();
  link.send(frame(uint8_t(type), seq++, p, len));
  if (!wait_for(link, max_s, [&] { return cap.acks.size() > a0; })) return -1;
  return cap.acks.back().status;
}

// MODEL_BEGIN for `blob`; returns the module's nonce.
template <class Link>
wire::AuthChallenge begin_upload(Link& link, const std::vector<uint8_t>& blob, uint8_t& seq) {
  Capture& cap = link.capture();
  uint8_t p[wire::kMaxPayload];
  p[0] = uint8_t(blob.size());
  p[1] = uint8_t(blob.size() >> 8);
  put_le32(p + 2, crc32(blob.data(), blob.size()));
  const size_t ch0 = cap.challenges.size();
  link.send(frame(uint8_t(wire::MsgType::ModelBegin), seq++, p, 6));
  if (!wait_for(link, 2.0, [&] { return cap.challenges.size() > ch0; }))
    throw std::runtime_error("no AUTH_CHALLENGE after MODEL_BEGIN");
  return cap.challenges.back();
}

// MODEL_AUTH's tag with `key` for the MODEL_BEGIN of `blob` answered by `nonce`.
inline std::array<uint8_t, 32> auth_tag(const std::array<uint8_t, 32>& key, const wire::AuthChallenge& nonce,
                                        const std::vector<uint8_t>& blob) {
  uint8_t context[wire::kModelAuthContextSize];
  wire::encode_model_auth_context(uint16_t(blob.size()), crc32(blob.data(), blob.size()), context);
  HmacSha256 mac(key.data(), key.size());
  mac.update(nonce.nonce, wire::kNonceSize);
  mac.update(context, sizeof context);
  std::array<uint8_t, 32> tag{};
  mac.final(tag.data());
  return tag;
}

// Sends every chunk of `blob`; returns the first non-OK ACK status (0: all accepted, -1: no ACK).
template <class Link>
int send_chunks(Link& link, const std::vector<uint8_t>& blob, uint8_t& seq) {
  uint8_t p[wire::kMaxPayload];
  for (size_t off = 0; off < blob.size();) {
    const uint8_t n = chunk_len_at(blob, off);
    p[0] = uint8_t(off);
    p[1] = uint8_t(off >> 8);
    for (uint8_t i = 0; i < n; ++i) p[2 + i] = blob[off + i];
    const int st = request_status(link, wire::MsgType::ModelChunk, seq, p, uint8_t(2 + n));
    if (st != 0) return st;
    off += n;
  }
  return 0;
}

// What a host without the device key can try, in order, with the module's answers: chunks right
// after MODEL_BEGIN (what older firmware wrote into EEPROM), MODEL_AUTH with a tag of a wrong key,
// chunks again, and MODEL_COMMIT with a wrong tag.
struct KeylessAttempt {
  int chunks_before_auth = 0, auth = 0, chunks_after_auth = 0, commit = 0;
};
template <class Link>
KeylessAttempt keyless_upload(Link& link, const std::vector<uint8_t>& blob, uint8_t& seq) {
  KeylessAttempt r;
  auto wrong_key = development_key();
  wrong_key[7] ^= 0x01;
  const wire::AuthChallenge nonce = begin_upload(link, blob, seq);
  r.chunks_before_auth = send_chunks(link, blob, seq);
  const auto tag = auth_tag(wrong_key, nonce, blob);
  r.auth = request_status(link, wire::MsgType::ModelAuth, seq, tag.data(), 32);
  r.chunks_after_auth = send_chunks(link, blob, seq);
  HmacSha256 mac(wrong_key.data(), wrong_key.size());
  mac.update(nonce.nonce, wire::kNonceSize);
  mac.update(blob.data(), blob.size());
  uint8_t commit_tag[32];
  mac.final(commit_tag);
  r.commit = request_status(link, wire::MsgType::ModelCommit, seq, commit_tag, 32, 5.0);
  return r;
}

// Sends everything up to (not including) MODEL_COMMIT. Returns the commit frame to send.
template <class Link>
std::vector<uint8_t> prepare_upload(Link& link, const std::vector<uint8_t>& blob, uint8_t& seq) {
  Capture& cap = link.capture();
  uint8_t p[wire::kMaxPayload];
  const wire::AuthChallenge nonce = begin_upload(link, blob, seq);
  const auto auth_tag_bytes = auth_tag(development_key(), nonce, blob);
  const int auth = request_status(link, wire::MsgType::ModelAuth, seq, auth_tag_bytes.data(), 32);
  if (auth != 0) throw std::runtime_error("MODEL_AUTH refused, code " + std::to_string(auth));
  for (size_t off = 0; off < blob.size();) {
    const uint8_t n = chunk_len_at(blob, off);
    p[0] = uint8_t(off);
    p[1] = uint8_t(off >> 8);
    for (uint8_t i = 0; i < n; ++i) p[2 + i] = blob[off + i];
    const size_t a0 = cap.acks.size();
    const uint8_t s = seq++;
    link.send(frame(uint8_t(wire::MsgType::ModelChunk), s, p, uint8_t(2 + n)));
    if (!wait_for(link, 2.0, [&] { return cap.acks.size() > a0; }))
      throw std::runtime_error("no ACK for MODEL_CHUNK at offset " + std::to_string(off));
    if (cap.acks.back().status != 0)
      throw std::runtime_error("MODEL_CHUNK at " + std::to_string(off) + " refused, code " +
                               std::to_string(cap.acks.back().status));
    off += n;
  }
  const auto key = development_key();
  HmacSha256 mac(key.data(), key.size());
  mac.update(nonce.nonce, wire::kNonceSize);
  mac.update(blob.data(), blob.size());
  uint8_t tag[32];
  mac.final(tag);
  return frame(uint8_t(wire::MsgType::ModelCommit), seq++, tag, 32);
}

// Full upload; returns the ACK status of MODEL_COMMIT (0 = stored).
template <class Link>
int upload_model(Link& link, const std::vector<uint8_t>& blob, uint8_t& seq) {
  const auto commit = prepare_upload(link, blob, seq);
  Capture& cap = link.capture();
  const size_t a0 = cap.acks.size();
  link.send(commit);
  if (!wait_for(link, 5.0, [&] { return cap.acks.size() > a0; })) return -1;
  return cap.acks.back().status;
}

template <class Link>
wire::Info get_info(Link& link, uint8_t& seq) {
  Capture& cap = link.capture();
  const size_t i0 = cap.infos.size();
  link.send(frame(uint8_t(wire::MsgType::GetInfo), seq++, nullptr, 0));
  if (!wait_for(link, 2.0, [&] { return cap.infos.size() > i0; })) throw std::runtime_error("no INFO answer");
  return cap.infos.back();
}

}  // namespace btsm::test
