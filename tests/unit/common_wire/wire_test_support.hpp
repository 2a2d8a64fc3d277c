// Helpers shared by the wire tests: encode to vectors, collect what a decoder accepts, and a set
// of representative frames (every message type plus escape-heavy edge cases).
#ifndef BTSM_TESTS_COMMON_WIRE_SUPPORT_HPP
#define BTSM_TESTS_COMMON_WIRE_SUPPORT_HPP

#include <cstdint>
#include <string>
#include <vector>

#include "common/wire_frame.hpp"
#include "common/wire_messages.hpp"

namespace btsm::wire::testing {

using Bytes = std::vector<uint8_t>;

// A decoded (or intended) frame: raw bytes header..CRC, which identify it completely.
struct RawFrame {
  Bytes raw;
  bool operator==(const RawFrame&) const = default;
};

inline Bytes encode(uint8_t type, uint8_t seq, const Bytes& payload) {
  Bytes out(kMaxEncodedFrame);
  const size_t n = encode_frame(type, seq, payload.data(), static_cast<uint8_t>(payload.size()),
                                out.data(), out.size());
  out.resize(n);
  return out;
}

inline RawFrame raw_of(uint8_t version, uint8_t type, uint8_t seq, const Bytes& payload) {
  Bytes raw(kMaxRawFrame);
  const size_t n = build_raw_frame(version, type, seq, payload.data(),
                                   static_cast<uint8_t>(payload.size()), raw.data());
  raw.resize(n);
  return RawFrame{raw};
}

inline Bytes stuff(const Bytes& raw) {
  Bytes out;
  auto sink = [&out](uint8_t b) { out.push_back(b); };
  write_stuffed(sink, raw.data(), raw.size());
  return out;
}

inline std::vector<RawFrame> feed(FrameDecoder& d, const Bytes& stream) {
  std::vector<RawFrame> got;
  for (uint8_t b : stream) {
    if (d.push(b)) got.push_back(RawFrame{Bytes(d.raw(), d.raw() + d.raw_size())});
  }
  return got;
}

struct NamedFrame {
  std::string name;
  uint8_t type;
  uint8_t seq;
  Bytes payload;
  RawFrame raw() const { return raw_of(kProtocolVersion, type, seq, payload); }
  Bytes wire() const { return encode(type, seq, payload); }
};

template <class Msg>
Bytes payload_of(const Msg& m, uint8_t (*enc)(const Msg&, uint8_t*)) {
  uint8_t buf[kMaxPayload];
  const uint8_t n = enc(m, buf);
  return Bytes(buf, buf + n);
}

// One realistic frame per message type plus frames made of reserved bytes.
inline std::vector<NamedFrame> representative_frames() {
  std::vector<NamedFrame> f;
  Sample s{};
  s.sample_index = 0x7E7D2B01;
  s.time_ms = 123456789;
  s.speed_rpm = 12000;
  for (uint8_t i = 0; i < kChannels; ++i) {
    s.temp_mK[i] = 25000 + 1234 * i;
    s.channel_status[i] = i;
    s.predicted_mK[i] = i == 4 ? kMissing : 24900 + 1000 * i;
  }
  s.overall = static_cast<uint8_t>(DiagState::Alarm) | kOverallModelActive;
  f.push_back({"SAMPLE", type_code(MsgType::Sample), 0x2B, payload_of(s, encode_sample)});
  Info info{1, 2, 3, kProtocolVersion, 0xDEADBEEF, 0x12345678, 7, 86400, 1, 8, 1, 2, 3, 4, 5, 6};
  f.push_back({"INFO", type_code(MsgType::Info), 0x7E, payload_of(info, encode_info)});
  Ack ack{0x7D, type_code(MsgType::ModelChunk), static_cast<uint8_t>(Nack::BadOffset), 0x7E2B};
  f.push_back({"ACK", type_code(MsgType::Ack), 3, payload_of(ack, encode_ack)});
  AuthChallenge ch{};
  for (uint8_t i = 0; i < kNonceSize; ++i) ch.nonce[i] = static_cast<uint8_t>(0x70 + i);
  f.push_back({"AUTH_CHALLENGE", type_code(MsgType::AuthChallenge), 4,
               payload_of(ch, encode_auth_challenge)});
  ModelData md{};
  md.offset = 400;
  md.len = kMaxModelData;
  for (uint8_t i = 0; i < md.len; ++i) md.data[i] = static_cast<uint8_t>(i * 13);
  f.push_back({"MODEL_DATA", type_code(MsgType::ModelData), 5, payload_of(md, encode_model_data)});
  ConfigValue cfg{static_cast<uint8_t>(ConfigKey::RrefMilliohm), 6800000};
  f.push_back({"CONFIG", type_code(MsgType::Config), 6, payload_of(cfg, encode_config)});
  f.push_back({"GET_INFO", type_code(MsgType::GetInfo), 7, {}});
  f.push_back({"SET_SPEED", type_code(MsgType::SetSpeed), 8,
               payload_of(SetSpeed{kSpeedFromTach}, encode_set_speed)});
  ConfigValue sc{channel_role_key(2), static_cast<int32_t>(ChannelRole::FrontBearing)};
  f.push_back({"SET_CONFIG", type_code(MsgType::SetConfig), 9, payload_of(sc, encode_set_config)});
  f.push_back({"ACK_ALARM", type_code(MsgType::AckAlarm), 10, {}});
  f.push_back({"MODEL_BEGIN", type_code(MsgType::ModelBegin), 11,
               payload_of(ModelBegin{464, 0x2B2B2B2B}, encode_model_begin)});
  ModelChunk mc{};
  mc.offset = 0x7E;
  mc.len = 10;
  for (uint8_t i = 0; i < mc.len; ++i) mc.data[i] = static_cast<uint8_t>(0x2B + i);
  f.push_back({"MODEL_CHUNK", type_code(MsgType::ModelChunk), 12,
               payload_of(mc, encode_model_chunk)});
  ModelCommit commit{};
  for (uint8_t i = 0; i < kHmacSize; ++i) commit.hmac[i] = static_cast<uint8_t>(i * 41 + 3);
  f.push_back({"MODEL_COMMIT", type_code(MsgType::ModelCommit), 13,
               payload_of(commit, encode_model_commit)});
  f.push_back({"MODEL_READ", type_code(MsgType::ModelRead), 14,
               payload_of(ModelRead{408, 56}, encode_model_read)});
  f.push_back({"REBOOT", type_code(MsgType::Reboot), 15, {}});
  f.push_back({"GET_CONFIG", type_code(MsgType::GetConfig), 16,
               payload_of(GetConfig{static_cast<uint8_t>(ConfigKey::SamplePeriodMs)},
                          encode_get_config)});
  ModelAuth auth{};
  for (uint8_t i = 0; i < kHmacSize; ++i) auth.hmac[i] = static_cast<uint8_t>(i * 29 + 0x7D);
  f.push_back({"MODEL_AUTH", type_code(MsgType::ModelAuth), 17, payload_of(auth, encode_model_auth)});
  // Every byte of the maximum payload needs escaping: 130 wire bytes.
  f.push_back({"MAX_ALL_FLAGS", 0x7E, 0x7D, Bytes(kMaxPayload, kFlag)});
  f.push_back({"MAX_ALL_PLUS", 0x2B, 0x2B, Bytes(kMaxPayload, kAtModeChar)});
  return f;
}

}  // namespace btsm::wire::testing

#endif  // BTSM_TESTS_COMMON_WIRE_SUPPORT_HPP
