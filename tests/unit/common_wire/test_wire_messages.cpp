// Message codecs: round trips, exact length checks, value checks, names, chunk sizing.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <set>
#include <string>

#include "wire_test_support.hpp"

namespace btsm::wire {
namespace {

using testing::Bytes;

// Decodes `payload` with `dec`, re-encodes with `enc`; the bytes must be identical.
template <class Msg>
void expect_canonical(const Bytes& payload, bool (*dec)(const uint8_t*, uint8_t, Msg&),
                      uint8_t (*enc)(const Msg&, uint8_t*)) {
  Msg m{};
  ASSERT_TRUE(dec(payload.data(), static_cast<uint8_t>(payload.size()), m));
  uint8_t again[kMaxPayload];
  const uint8_t n = enc(m, again);
  ASSERT_EQ(n, payload.size());
  EXPECT_EQ(Bytes(again, again + n), payload);
}

// Every length except the valid one(s) must be refused.
template <class Msg>
void expect_rejects_other_lengths(uint8_t type, bool (*dec)(const uint8_t*, uint8_t, Msg&)) {
  uint8_t min_len = 0, max_len = 0;
  ASSERT_TRUE(payload_length_range(type, min_len, max_len));
  uint8_t buf[255] = {};
  for (int len = 0; len < 255; ++len) {
    if (len >= min_len && len <= max_len) continue;
    Msg m{};
    EXPECT_FALSE(dec(buf, static_cast<uint8_t>(len), m)) << msg_type_name(type) << " len " << len;
  }
}

TEST(WireMessages, SampleRoundTripIncludingI24Extremes) {
  std::mt19937 rng(3);
  for (int i = 0; i < 2000; ++i) {
    Sample s{};
    s.sample_index = rng();
    s.time_ms = rng();
    s.speed_rpm = static_cast<uint16_t>(rng());
    for (uint8_t c = 0; c < kChannels; ++c) {
      const int pick = static_cast<int>(rng() % 4);
      s.temp_mK[c] = pick == 0   ? kMissing
                     : pick == 1 ? kInt24Max
                                 : static_cast<int32_t>(rng() % 16777216) - 8388608;
      s.predicted_mK[c] = static_cast<int32_t>(rng() % 16777216) - 8388608;
      s.channel_status[c] = static_cast<uint8_t>(rng());
    }
    s.overall = static_cast<uint8_t>(rng() & ~kOverallReservedMask);
    uint8_t p[kMaxPayload];
    ASSERT_EQ(encode_sample(s, p), kSampleSize);
    Sample back{};
    ASSERT_TRUE(decode_sample(p, kSampleSize, back));
    EXPECT_EQ(back.sample_index, s.sample_index);
    EXPECT_EQ(back.time_ms, s.time_ms);
    EXPECT_EQ(back.speed_rpm, s.speed_rpm);
    for (uint8_t c = 0; c < kChannels; ++c) {
      EXPECT_EQ(back.temp_mK[c], s.temp_mK[c]);
      EXPECT_EQ(back.channel_status[c], s.channel_status[c]);
      EXPECT_EQ(back.predicted_mK[c], s.predicted_mK[c]);
    }
    EXPECT_EQ(back.overall, s.overall);
    expect_canonical(Bytes(p, p + kSampleSize), decode_sample, encode_sample);
  }
  EXPECT_EQ(kSampleSize, 46);
}

TEST(WireMessages, SampleRejectsValuesItCannotCarry) {
  Sample s{};
  uint8_t p[kMaxPayload];
  s.temp_mK[2] = kInt24Max + 1;
  EXPECT_EQ(encode_sample(s, p), 0);
  s.temp_mK[2] = 0;
  s.predicted_mK[4] = kInt24Min - 1;
  EXPECT_EQ(encode_sample(s, p), 0);
  s.predicted_mK[4] = 0;
  s.overall = 0x20;
  EXPECT_EQ(encode_sample(s, p), 0);
  s.overall = 0;
  ASSERT_EQ(encode_sample(s, p), kSampleSize);
  for (uint8_t bit : {0x20, 0x40, 0x80}) {
    p[kSampleSize - 1] = bit;
    EXPECT_FALSE(decode_sample(p, kSampleSize, s)) << int(bit);
  }
  expect_rejects_other_lengths(type_code(MsgType::Sample), decode_sample);
}

TEST(WireMessages, InfoRoundTripAndModelStateCheck) {
  Info info{1, 4, 2, kProtocolVersion, 0x01020304, 0xCBF43926, 42, 3600, 1, 0x08,
            65535, 1, 2, 3, 4, 5};
  uint8_t p[kMaxPayload];
  ASSERT_EQ(encode_info(info, p), kInfoSize);
  Info back{};
  ASSERT_TRUE(decode_info(p, kInfoSize, back));
  // Field by field (the struct has padding, so no memcmp).
  EXPECT_EQ(back.fw_major, 1);
  EXPECT_EQ(back.fw_minor, 4);
  EXPECT_EQ(back.fw_patch, 2);
  EXPECT_EQ(back.protocol_version, kProtocolVersion);
  EXPECT_EQ(back.device_id, 0x01020304u);
  EXPECT_EQ(back.model_crc, 0xCBF43926u);
  EXPECT_EQ(back.model_seq, 42u);
  EXPECT_EQ(back.uptime_s, 3600u);
  EXPECT_EQ(back.model_state, 1);
  EXPECT_EQ(back.reset_cause, 0x08);
  EXPECT_EQ(back.adc_timeouts, 65535);
  EXPECT_EQ(back.frame_errors, 1);
  EXPECT_EQ(back.kalman_rejects, 2);
  EXPECT_EQ(back.sensor_faults, 3);
  EXPECT_EQ(back.resets, 4);
  EXPECT_EQ(back.watchdog_resets, 5);
  expect_canonical(Bytes(p, p + kInfoSize), decode_info, encode_info);
  EXPECT_EQ(get_le32(p + 8), 0xCBF43926u);  // model_crc at its documented offset
  p[20] = kModelStateCount;
  EXPECT_FALSE(decode_info(p, kInfoSize, back));
  info.model_state = kModelStateCount;
  EXPECT_EQ(encode_info(info, p), 0);
  expect_rejects_other_lengths(type_code(MsgType::Info), decode_info);
}

TEST(WireMessages, AckRoundTripAndUnknownStatusRejected) {
  for (uint8_t code = 0; code < kNackCodeCount; ++code) {
    const Ack a{0x7E, 0x45, code, 0xBEEF};
    uint8_t p[kMaxPayload];
    ASSERT_EQ(encode_ack(a, p), kAckSize);
    Ack back{};
    ASSERT_TRUE(decode_ack(p, kAckSize, back));
    EXPECT_EQ(back.acked_seq, a.acked_seq);
    EXPECT_EQ(back.acked_type, a.acked_type);
    EXPECT_EQ(back.status, code);
    EXPECT_EQ(back.detail, 0xBEEF);
  }
  uint8_t p[kAckSize] = {1, 2, kNackCodeCount, 0, 0};
  Ack a{};
  EXPECT_FALSE(decode_ack(p, kAckSize, a));
  a.status = 0xFF;
  EXPECT_EQ(encode_ack(a, p), 0);
  expect_rejects_other_lengths(type_code(MsgType::Ack), decode_ack);
}

TEST(WireMessages, FixedBlobMessagesRoundTrip) {
  AuthChallenge ch{};
  for (uint8_t i = 0; i < kNonceSize; ++i) ch.nonce[i] = static_cast<uint8_t>(255 - i);
  expect_canonical(testing::payload_of(ch, encode_auth_challenge), decode_auth_challenge,
                   encode_auth_challenge);
  expect_rejects_other_lengths(type_code(MsgType::AuthChallenge), decode_auth_challenge);

  ModelCommit c{};
  for (uint8_t i = 0; i < kHmacSize; ++i) c.hmac[i] = static_cast<uint8_t>(i);
  const Bytes cp = testing::payload_of(c, encode_model_commit);
  ASSERT_EQ(cp.size(), kHmacSize);
  expect_canonical(cp, decode_model_commit, encode_model_commit);
  expect_rejects_other_lengths(type_code(MsgType::ModelCommit), decode_model_commit);

  ModelAuth a{};
  for (uint8_t i = 0; i < kHmacSize; ++i) a.hmac[i] = static_cast<uint8_t>(200 - i);
  const Bytes ap = testing::payload_of(a, encode_model_auth);
  ASSERT_EQ(ap.size(), kHmacSize);
  expect_canonical(ap, decode_model_auth, encode_model_auth);
  expect_rejects_other_lengths(type_code(MsgType::ModelAuth), decode_model_auth);
}

// The bytes MODEL_AUTH's tag covers after the nonce: its own type code (so no commit tag can
// serve as an auth tag), then the MODEL_BEGIN values, little-endian.
TEST(WireMessages, ModelAuthContextLayout) {
  uint8_t ctx[kModelAuthContextSize];
  encode_model_auth_context(464, 0x11223344, ctx);
  const Bytes want = {0x4A, 0xD0, 0x01, 0x44, 0x33, 0x22, 0x11};
  EXPECT_EQ(Bytes(ctx, ctx + kModelAuthContextSize), want);
  EXPECT_STREQ(msg_type_name(0x4A), "MODEL_AUTH");
  EXPECT_TRUE(is_host_to_module(type_code(MsgType::ModelAuth)));
}

TEST(WireMessages, ModelBytesLengthsOffsetsAndBounds) {
  for (uint8_t len = 1; len <= kMaxModelData; ++len) {
    ModelChunk m{};
    m.offset = static_cast<uint16_t>(kMaxModelBlobSize - len);
    m.len = len;
    for (uint8_t i = 0; i < len; ++i) m.data[i] = static_cast<uint8_t>(i ^ 0x5A);
    uint8_t p[kMaxPayload];
    ASSERT_EQ(encode_model_chunk(m, p), 2 + len);
    ModelChunk back{};
    ASSERT_TRUE(decode_model_chunk(p, static_cast<uint8_t>(2 + len), back));
    EXPECT_EQ(back.offset, m.offset);
    ASSERT_EQ(back.len, len);
    EXPECT_EQ(std::memcmp(back.data, m.data, len), 0);
    expect_canonical(Bytes(p, p + 2 + len), decode_model_data, encode_model_data);
    // One byte past the largest blob is refused on both sides.
    m.offset = static_cast<uint16_t>(m.offset + 1);
    EXPECT_EQ(encode_model_chunk(m, p), 0);
    put_le16(p, m.offset);
    EXPECT_FALSE(decode_model_chunk(p, static_cast<uint8_t>(2 + len), back));
  }
  ModelChunk empty{};
  uint8_t p[kMaxPayload];
  EXPECT_EQ(encode_model_chunk(empty, p), 0);
  expect_rejects_other_lengths(type_code(MsgType::ModelChunk), decode_model_chunk);
  expect_rejects_other_lengths(type_code(MsgType::ModelData), decode_model_data);
}

TEST(WireMessages, SetSpeedRangeAndTachSentinel) {
  for (uint32_t rpm = 0; rpm <= 0xFFFF; ++rpm) {
    uint8_t p[2];
    put_le16(p, static_cast<uint16_t>(rpm));
    SetSpeed m{};
    const bool valid = rpm <= kMaxSpeedRpm || rpm == kSpeedFromTach;
    ASSERT_EQ(decode_set_speed(p, 2, m), valid) << rpm;
    ASSERT_EQ(encode_set_speed(SetSpeed{static_cast<uint16_t>(rpm)}, p), valid ? 2 : 0) << rpm;
  }
  expect_rejects_other_lengths(type_code(MsgType::SetSpeed), decode_set_speed);
}

TEST(WireMessages, ConfigKeysRangesDefaultsAndCodec) {
  int known = 0;
  for (int key = 0; key < 256; ++key) {
    ConfigRange r{};
    const bool is_known = config_key_range(static_cast<uint8_t>(key), r);
    ASSERT_EQ(is_known, config_key_name(static_cast<uint8_t>(key)) != nullptr) << key;
    uint8_t p[kConfigValueSize];
    ConfigValue m{};
    if (!is_known) {
      EXPECT_EQ(encode_set_config(ConfigValue{static_cast<uint8_t>(key), 0}, p), 0);
      p[0] = static_cast<uint8_t>(key);
      put_le32(p + 1, 0);
      EXPECT_FALSE(decode_set_config(p, kConfigValueSize, m)) << key;
      GetConfig g{};
      EXPECT_FALSE(decode_get_config(p, 1, g));
      continue;
    }
    ++known;
    EXPECT_LE(r.min, r.default_value);
    EXPECT_LE(r.default_value, r.max);
    for (int32_t v : {r.min, r.default_value, r.max}) {
      ASSERT_EQ(encode_set_config(ConfigValue{static_cast<uint8_t>(key), v}, p), kConfigValueSize);
      ASSERT_TRUE(decode_set_config(p, kConfigValueSize, m));
      EXPECT_EQ(m.key, key);
      EXPECT_EQ(m.value, v);
      expect_canonical(Bytes(p, p + kConfigValueSize), decode_config, encode_config);
    }
    for (int64_t v : {int64_t{r.min} - 1, int64_t{r.max} + 1}) {
      if (v < INT32_MIN || v > INT32_MAX) continue;
      const int32_t bad = static_cast<int32_t>(v);
      EXPECT_EQ(encode_set_config(ConfigValue{static_cast<uint8_t>(key), bad}, p), 0);
      p[0] = static_cast<uint8_t>(key);
      put_le32(p + 1, static_cast<uint32_t>(bad));
      EXPECT_FALSE(decode_set_config(p, kConfigValueSize, m)) << key << " = " << bad;
    }
    GetConfig g{static_cast<uint8_t>(key)};
    expect_canonical(testing::payload_of(g, encode_get_config), decode_get_config,
                     encode_get_config);
  }
  EXPECT_EQ(known, 7 + kChannels);
  // Contract defaults: 5 s sample period, R_ref 6.80 kOhm, roles ch1..ch5.
  ConfigRange r{};
  ASSERT_TRUE(config_key_range(type_code(MsgType::Sample) /* 0x01 = SamplePeriodMs */, r));
  EXPECT_EQ(r.default_value, 5000);
  ASSERT_TRUE(config_key_range(static_cast<uint8_t>(ConfigKey::RrefMilliohm), r));
  EXPECT_EQ(r.default_value, 6800000);
  // kalman_q = 0 would leave the filter without process noise (unusable): out of range.
  ASSERT_TRUE(config_key_range(static_cast<uint8_t>(ConfigKey::KalmanProcessNoise), r));
  EXPECT_EQ(r.min, 1);
  EXPECT_FALSE(config_value_valid(static_cast<uint8_t>(ConfigKey::KalmanProcessNoise), 0));
  EXPECT_TRUE(config_value_valid(static_cast<uint8_t>(ConfigKey::KalmanProcessNoise), 1));
  ASSERT_TRUE(config_key_range(channel_role_key(3), r));
  EXPECT_EQ(r.default_value, static_cast<int32_t>(ChannelRole::Ambient));
  EXPECT_STREQ(config_key_name(channel_role_key(0)), "channel_role_1");
  EXPECT_STREQ(channel_role_name(static_cast<uint8_t>(default_channel_role(0))), "rear_bearing");
  EXPECT_EQ(channel_role_name(kChannelRoleCount), nullptr);
  // Every role below the count has a name, and the names are distinct (set-config parses them).
  for (uint8_t a = 0; a < kChannelRoleCount; ++a) {
    ASSERT_NE(channel_role_name(a), nullptr) << int(a);
    for (uint8_t b = 0; b < a; ++b) EXPECT_STRNE(channel_role_name(a), channel_role_name(b));
    EXPECT_EQ(channel_role_from_name(channel_role_name(a)), a);  // the names read back as their role
  }
  EXPECT_EQ(channel_role_from_name("unknown"), -1);
  EXPECT_EQ(channel_role_from_name("Shaft"), -1);
  EXPECT_EQ(channel_role_from_name(""), -1);
  EXPECT_STREQ(channel_role_name(static_cast<uint8_t>(ChannelRole::Shaft)), "shaft");
  EXPECT_TRUE(config_value_valid(channel_role_key(4), static_cast<int32_t>(ChannelRole::Shaft)));
  EXPECT_FALSE(config_value_valid(channel_role_key(4), kChannelRoleCount));
  expect_rejects_other_lengths(type_code(MsgType::SetConfig), decode_set_config);
  expect_rejects_other_lengths(type_code(MsgType::GetConfig), decode_get_config);
}

TEST(WireMessages, ModelBeginAndReadBounds) {
  uint8_t p[kMaxPayload];
  ModelBegin b{};
  for (uint32_t total : {0u, 1u, 464u, 465u, 65535u}) {
    b = ModelBegin{static_cast<uint16_t>(total), 0xCBF43926};
    const bool valid = total >= 1 && total <= kMaxModelBlobSize;
    EXPECT_EQ(encode_model_begin(b, p), valid ? 6 : 0) << total;
    put_le16(p, static_cast<uint16_t>(total));
    put_le32(p + 2, 0xCBF43926);
    ModelBegin back{};
    EXPECT_EQ(decode_model_begin(p, 6, back), valid) << total;
    if (valid) {
      EXPECT_EQ(back.blob_crc32, 0xCBF43926u);
    }
  }
  expect_rejects_other_lengths(type_code(MsgType::ModelBegin), decode_model_begin);

  struct Case {
    uint16_t offset;
    uint8_t len;
    bool valid;
  };
  for (const Case& c : {Case{0, 1, true}, Case{0, 56, true}, Case{408, 56, true},
                        Case{0, 0, false}, Case{0, 57, false}, Case{409, 56, false},
                        Case{0xFFFF, 1, false}}) {
    EXPECT_EQ(encode_model_read(ModelRead{c.offset, c.len}, p), c.valid ? 3 : 0);
    put_le16(p, c.offset);
    p[2] = c.len;
    ModelRead back{};
    EXPECT_EQ(decode_model_read(p, 3, back), c.valid) << c.offset << "+" << int(c.len);
  }
  expect_rejects_other_lengths(type_code(MsgType::ModelRead), decode_model_read);
}

TEST(WireMessages, EmptyMessagesOnlyAcceptZeroLength) {
  for (MsgType t : {MsgType::GetInfo, MsgType::AckAlarm, MsgType::Reboot}) {
    uint8_t lo = 1, hi = 1;
    ASSERT_TRUE(payload_length_range(type_code(t), lo, hi));
    EXPECT_EQ(lo, 0);
    EXPECT_EQ(hi, 0);
  }
  EXPECT_TRUE(decode_empty(0));
  for (int len = 1; len < 256; ++len) EXPECT_FALSE(decode_empty(static_cast<uint8_t>(len)));
}

TEST(WireMessages, EveryRepresentativeFrameDecodesThroughTheFrameLayer) {
  // Each frame goes through encode -> decoder -> message decode -> re-encode unchanged.
  for (const auto& f : testing::representative_frames()) {
    if (msg_type_name(f.type) == nullptr) continue;  // raw stress frames
    FrameDecoder d;
    const auto got = testing::feed(d, f.wire());
    ASSERT_EQ(got.size(), 1u) << f.name;
    EXPECT_STREQ(msg_type_name(d.type()), f.name.c_str());
    uint8_t lo = 0, hi = 0;
    ASSERT_TRUE(payload_length_range(d.type(), lo, hi));
    EXPECT_GE(d.payload_len(), lo);
    EXPECT_LE(d.payload_len(), hi);
    EXPECT_LE(hi, kMaxPayload) << f.name;
    EXPECT_EQ(Bytes(d.payload(), d.payload() + d.payload_len()), f.payload);
  }
}

TEST(WireMessages, TypeCodesNamesAndDirections) {
  std::set<std::string> names;
  int known = 0;
  for (int t = 0; t < 256; ++t) {
    const char* n = msg_type_name(static_cast<uint8_t>(t));
    uint8_t lo = 0, hi = 0;
    EXPECT_EQ(n != nullptr, payload_length_range(static_cast<uint8_t>(t), lo, hi)) << t;
    if (n == nullptr) continue;
    ++known;
    names.insert(n);
  }
  EXPECT_EQ(known, 17);
  EXPECT_EQ(names.size(), 17u);
  EXPECT_FALSE(is_host_to_module(type_code(MsgType::Sample)));
  EXPECT_TRUE(is_host_to_module(type_code(MsgType::ModelCommit)));
}

TEST(WireMessages, NackNamesAreDistinctAndExplained) {
  std::set<std::string> names;
  for (uint8_t c = 0; c < kNackCodeCount; ++c) {
    names.insert(nack_name(c));
    EXPECT_STRNE(nack_description(c), "unknown NACK code (newer firmware?)");
  }
  EXPECT_EQ(names.size(), kNackCodeCount);
  EXPECT_STREQ(nack_name(static_cast<uint8_t>(Nack::AuthFailed)), "AUTH_FAILED");
  EXPECT_STREQ(nack_name(static_cast<uint8_t>(Nack::BlobInvalid)), "BLOB_INVALID");
  EXPECT_STREQ(nack_name(kNackCodeCount), "UNKNOWN_NACK");
}

// Simulates a whole model upload: every MODEL_CHUNK frame fits one 20-byte BLE write, chunks are
// as large as possible, contain no '+', and reassemble to the blob.
TEST(WireMessages, ModelChunkFitKeepsEveryEncodedChunkWithinOneBleWrite) {
  std::mt19937 rng(11);
  for (int blob_kind = 0; blob_kind < 4; ++blob_kind) {
    Bytes blob(kMaxModelBlobSize);
    for (auto& b : blob) {
      b = blob_kind == 0   ? static_cast<uint8_t>(rng())
          : blob_kind == 1 ? kFlag                                  // worst case: all escaped
          : blob_kind == 2 ? static_cast<uint8_t>(0x10 + rng() % 8)  // no escapes
                           : static_cast<uint8_t>(rng() % 2 ? kAtModeChar : 0x00);
    }
    for (int seq_base = 0; seq_base < 256; seq_base += 37) {
      Bytes reassembled(blob.size());
      size_t off = 0;
      uint8_t seq = static_cast<uint8_t>(seq_base);
      size_t chunks = 0;
      while (off < blob.size()) {
        const uint8_t n = model_chunk_fit(seq, static_cast<uint16_t>(off), blob.data() + off,
                                          blob.size() - off);
        ASSERT_GE(n, 1);
        ModelChunk c{};
        c.offset = static_cast<uint16_t>(off);
        c.len = n;
        std::memcpy(c.data, blob.data() + off, n);
        uint8_t wire[kMaxEncodedFrame];
        const size_t size = encode_message_frame(MsgType::ModelChunk, seq, c, encode_model_chunk,
                                                 wire, sizeof wire);
        ASSERT_GT(size, 0u);
        ASSERT_LE(size, kBleWriteSize) << "offset " << off;
        for (size_t i = 0; i < size; ++i) ASSERT_NE(wire[i], kAtModeChar);
        FrameDecoder d;
        for (size_t i = 0; i < size; ++i) {
          if (d.push(wire[i])) {
            ModelChunk back{};
            ASSERT_TRUE(decode_model_chunk(d.payload(), d.payload_len(), back));
            std::memcpy(reassembled.data() + back.offset, back.data, back.len);
          }
        }
        // Maximal: one more byte would not fit (unless the blob ended).
        if (off + n < blob.size() && n < kBleWriteSize - 10) {
          c.len = static_cast<uint8_t>(n + 1);
          std::memcpy(c.data, blob.data() + off, n + 1u);
          ASSERT_GT(encode_message_frame(MsgType::ModelChunk, seq, c, encode_model_chunk, wire,
                                         sizeof wire),
                    kBleWriteSize);
        }
        off += n;
        ++seq;
        ++chunks;
      }
      EXPECT_EQ(reassembled, blob);
      // At most 10 data bytes fit (2 flags + 8 fixed raw bytes + data <= 20).
      EXPECT_GE(chunks, (kMaxModelBlobSize + 9) / 10u);
    }
  }
  EXPECT_EQ(model_chunk_fit(0, 0, nullptr, 0), 0);
}

}  // namespace
}  // namespace btsm::wire
