// End-to-end: the firmware App on the native simulated board, talking the wire protocol.
#include <gtest/gtest.h>

#include "firmware/app.hpp"
#include "test_support.hpp"

namespace btsm {
namespace {

using NativeApp = App<sim::NativeBoard>;

struct AppFixture : ::testing::Test {
  const double temps[5] = {20.0, 35.5, 42.0, 22.0, 60.0};
  std::unique_ptr<sim::NativeBoard> board;
  std::unique_ptr<NativeApp> app;
  std::unique_ptr<test::HostLink> link;
  uint8_t seq = 1;

  void boot(sim::NativeBoardOptions o = {}) {
    board = std::make_unique<sim::NativeBoard>(o);
    for (int j = 0; j < 5; ++j) board->front_end().probe_ohm[j] = test::pt1000_ohm(temps[j]);
    link = std::make_unique<test::HostLink>(*board);
    restart();
  }
  void restart() {
    app = std::make_unique<NativeApp>(*board);
    app->init();
  }
  void run(double seconds) { board->run_until_us(*app, board->now_us() + static_cast<uint64_t>(seconds * 1e6)); }

  // Sends a request and runs until a frame of `reply` type with our seq arrives (max 5 s).
  std::optional<test::Frame> request(wire::MsgType type, const std::vector<uint8_t>& payload, wire::MsgType reply) {
    const uint8_t s = seq++;
    link->send(type, s, payload);
    for (int i = 0; i < 500; ++i) {
      run(0.01);
      link->collect();
      for (size_t k = 0; k < link->frames.size(); ++k) {
        const auto& f = link->frames[k];
        if (f.seq == s && (f.type == wire::type_code(reply) || f.type == wire::type_code(wire::MsgType::Ack))) {
          test::Frame out = f;
          link->frames.erase(link->frames.begin() + static_cast<long>(k));
          return out;
        }
      }
    }
    return std::nullopt;
  }
  wire::Ack ack_of(const std::optional<test::Frame>& f) {
    wire::Ack a{};
    EXPECT_TRUE(f.has_value());
    if (f) {
      EXPECT_TRUE(wire::decode_ack(f->payload.data(), static_cast<uint8_t>(f->payload.size()), a));
    }
    return a;
  }
  std::vector<wire::Sample> samples() {
    std::vector<wire::Sample> out;
    link->collect();
    for (const auto& f : link->frames) {
      if (f.type != wire::type_code(wire::MsgType::Sample)) continue;
      wire::Sample s;
      EXPECT_TRUE(wire::decode_sample(f.payload.data(), static_cast<uint8_t>(f.payload.size()), s));
      out.push_back(s);
    }
    return out;
  }
  wire::Info info() {
    auto f = request(wire::MsgType::GetInfo, {}, wire::MsgType::Info);
    wire::Info i{};
    EXPECT_TRUE(f && f->type == wire::type_code(wire::MsgType::Info));
    if (f) {
      EXPECT_TRUE(wire::decode_info(f->payload.data(), static_cast<uint8_t>(f->payload.size()), i));
    }
    return i;
  }

  // MODEL_AUTH's tag for the MODEL_BEGIN of `blob` answered with `nonce`.
  static std::vector<uint8_t> auth_tag(const std::array<uint8_t, 32>& key, const std::vector<uint8_t>& nonce,
                                       const std::vector<uint8_t>& blob) {
    uint8_t context[wire::kModelAuthContextSize];
    wire::encode_model_auth_context(static_cast<uint16_t>(blob.size()), crc32(blob.data(), blob.size()), context);
    HmacSha256 mac(key.data(), key.size());
    mac.update(nonce.data(), nonce.size());
    mac.update(context, sizeof context);
    std::vector<uint8_t> tag(32);
    mac.final(tag.data());
    return tag;
  }

  // Full upload over the protocol; returns the status of the first refusal or of the COMMIT ACK.
  uint8_t upload(const std::vector<uint8_t>& blob, const std::array<uint8_t, 32>& key, std::vector<uint8_t>* commit_payload = nullptr) {
    std::vector<uint8_t> p(6);
    put_le16(p.data(), static_cast<uint16_t>(blob.size()));
    put_le32(p.data() + 2, crc32(blob.data(), blob.size()));
    auto ch = request(wire::MsgType::ModelBegin, p, wire::MsgType::AuthChallenge);
    if (!ch || ch->type != wire::type_code(wire::MsgType::AuthChallenge)) return ack_of(ch).status;
    EXPECT_EQ(ch->payload.size(), 16u);
    const wire::Ack auth = ack_of(request(wire::MsgType::ModelAuth, auth_tag(key, ch->payload, blob), wire::MsgType::Ack));
    if (auth.status != 0) return auth.status;
    size_t off = 0;
    while (off < blob.size()) {
      const uint8_t n = wire::model_chunk_fit(seq, static_cast<uint16_t>(off), blob.data() + off, blob.size() - off);
      EXPECT_GT(n, 0);
      std::vector<uint8_t> c(2 + n);
      put_le16(c.data(), static_cast<uint16_t>(off));
      std::copy(blob.begin() + static_cast<long>(off), blob.begin() + static_cast<long>(off + n), c.begin() + 2);
      const wire::Ack a = ack_of(request(wire::MsgType::ModelChunk, c, wire::MsgType::Ack));
      if (a.status != 0) return a.status;
      off += n;
    }
    HmacSha256 mac(key.data(), key.size());
    mac.update(ch->payload.data(), 16);
    mac.update(blob.data(), blob.size());
    std::vector<uint8_t> tag(32);
    mac.final(tag.data());
    if (commit_payload) *commit_payload = tag;
    return ack_of(request(wire::MsgType::ModelCommit, tag, wire::MsgType::Ack)).status;
  }
};

TEST_F(AppFixture, ReportsTheSetTemperaturesWithin10mK) {
  boot();
  run(60.0);
  const auto s = samples();
  ASSERT_GE(s.size(), 11u);
  ASSERT_LE(s.size(), 13u);  // one SAMPLE per 5 s sweep
  for (size_t i = 1; i < s.size(); ++i) EXPECT_EQ(s[i].sample_index, s[i - 1].sample_index + 1);
  const wire::Sample& last = s.back();
  for (int j = 0; j < 5; ++j) {
    EXPECT_NEAR(last.temp_mK[j] / 1000.0, temps[j], 0.01) << "channel " << j + 1;
    EXPECT_EQ(last.channel_status[j], 0) << "channel " << j + 1;
    EXPECT_EQ(last.predicted_mK[j], wire::kMissing) << "no model flashed yet";
  }
  EXPECT_EQ(last.overall & wire::kOverallModelActive, 0);
  EXPECT_EQ(board->watchdog_resets(), 0u);
  EXPECT_FALSE(board->reset_pending());
}

// kalman_q = 0 used to be accepted and left every filter unusable (every channel then reported
// 0.000 degC): it is out of range now (NACK BadValue, configuration unchanged), and the smallest
// value, 1 (mK)^2/s, filters normally.
TEST_F(AppFixture, KalmanProcessNoiseZeroIsRefusedAndTheMinimumWorks) {
  boot();
  run(6.0);
  std::vector<uint8_t> p(5);
  p[0] = static_cast<uint8_t>(wire::ConfigKey::KalmanProcessNoise);
  put_le32(p.data() + 1, 0);
  const wire::Ack a = ack_of(request(wire::MsgType::SetConfig, p, wire::MsgType::Ack));
  EXPECT_EQ(a.status, static_cast<uint8_t>(wire::Nack::BadValue));
  EXPECT_EQ(a.detail, p[0]);
  EXPECT_EQ(app->config().kalman_q, 400u);
  put_le32(p.data() + 1, 1);
  EXPECT_EQ(ack_of(request(wire::MsgType::SetConfig, p, wire::MsgType::Ack)).status, 0);
  EXPECT_EQ(app->config().kalman_q, 1u);
  link->frames.clear();
  run(60.0);
  auto s = samples();
  ASSERT_GE(s.size(), 10u);
  for (int j = 0; j < 5; ++j) EXPECT_NEAR(s.back().temp_mK[j] / 1000.0, temps[j], 0.01) << "channel " << j + 1;
}

TEST_F(AppFixture, FaultyChannelReportsSensorFaultAndNoTemperature) {
  boot();
  run(12.0);
  board->front_end().probe_fault[1] = sim::ProbeFault::kOpenSense;
  board->front_end().probe_fault[2] = sim::ProbeFault::kShort;
  link->frames.clear();
  board->host_receive();
  run(15.5);  // three samples: the rotating open-wire check reaches every channel within three
  const auto s = samples();
  ASSERT_FALSE(s.empty());
  const wire::Sample& last = s.back();
  EXPECT_EQ(last.temp_mK[1], wire::kMissing);
  EXPECT_EQ(last.channel_status[1] & wire::kStatusStateMask, static_cast<uint8_t>(wire::DiagState::SensorFault));
  EXPECT_NE(last.channel_status[1] & wire::kFaultOpen, 0);
  EXPECT_EQ(last.temp_mK[2], wire::kMissing);
  EXPECT_NE(last.channel_status[2] & wire::kFaultShort, 0);
  EXPECT_NEAR(last.temp_mK[0] / 1000.0, temps[0], 0.01);
  EXPECT_EQ(last.overall & wire::kStatusStateMask, static_cast<uint8_t>(wire::DiagState::SensorFault));
  // Missing ADC: every channel faults.
  board->front_end().chip_missing = true;
  link->frames.clear();
  run(10.5);
  const auto s2 = samples();
  ASSERT_FALSE(s2.empty());
  for (int j = 0; j < 5; ++j) {
    EXPECT_EQ(s2.back().temp_mK[j], wire::kMissing);
    EXPECT_NE(s2.back().channel_status[j] & wire::kFaultAdc, 0);
  }
}

// A transmit buffer far smaller than a frame: every frame goes out in many claims of the UART's
// transmit space (serial.tx_claim / tx_commit), resumed poll after poll, escapes split across
// claims included. Every sample arrives intact (a lost or corrupted byte fails the CRC and drops the
// frame: a gap in the indices), and so does a request's reply.
TEST_F(AppFixture, FramesSurviveATransmitBufferSmallerThanAFrame) {
  sim::NativeBoardOptions o;
  o.tx_buffer_bytes = 5;
  boot(o);
  run(26.0);
  const auto s = samples();
  ASSERT_GE(s.size(), 5u);
  for (size_t k = 0; k < s.size(); ++k) {
    EXPECT_EQ(s[k].sample_index, k);
    EXPECT_NEAR(s[k].temp_mK[2] / 1000.0, temps[2], 0.01);
  }
  link->frames.clear();
  const wire::Info i = info();
  EXPECT_EQ(i.device_id, 0x0000DE70u);
}

TEST_F(AppFixture, InfoConfigAndSpeedCommands) {
  boot();
  run(6.0);
  wire::Info i = info();
  EXPECT_EQ(i.device_id, 0x0000DE70u);
  EXPECT_EQ(i.protocol_version, wire::kProtocolVersion);
  EXPECT_EQ(i.model_state, static_cast<uint8_t>(wire::ModelState::None));
  EXPECT_EQ(i.resets, 1u);
  // SET_CONFIG is range checked and persisted.
  std::vector<uint8_t> p(5);
  p[0] = 0x01;
  put_le32(p.data() + 1, 10);  // 10 ms period: out of range
  EXPECT_EQ(ack_of(request(wire::MsgType::SetConfig, p, wire::MsgType::Ack)).status,
            static_cast<uint8_t>(wire::Nack::BadValue));
  put_le32(p.data() + 1, 2000);
  EXPECT_EQ(ack_of(request(wire::MsgType::SetConfig, p, wire::MsgType::Ack)).status, 0);
  EXPECT_EQ(app->config().sample_period_ms, 2000u);
  auto g = request(wire::MsgType::GetConfig, {0x01}, wire::MsgType::Config);
  ASSERT_TRUE(g && g->type == wire::type_code(wire::MsgType::Config));
  EXPECT_EQ(get_le32(g->payload.data() + 1), 2000u);
  // Unknown type and bad length.
  EXPECT_EQ(ack_of(request(static_cast<wire::MsgType>(0x7A), {}, wire::MsgType::Ack)).status,
            static_cast<uint8_t>(wire::Nack::UnknownType));
  EXPECT_EQ(ack_of(request(wire::MsgType::SetSpeed, {1}, wire::MsgType::Ack)).status,
            static_cast<uint8_t>(wire::Nack::BadLength));
  // SET_SPEED overrides the tach; 0xFFFF goes back to the tach.
  board->set_spindle_rpm(3000);
  std::vector<uint8_t> sp(2);
  put_le16(sp.data(), 8000);
  EXPECT_EQ(ack_of(request(wire::MsgType::SetSpeed, sp, wire::MsgType::Ack)).status, 0);
  link->frames.clear();
  run(4.5);
  auto s = samples();
  ASSERT_FALSE(s.empty());
  EXPECT_EQ(s.back().speed_rpm, 8000);
  EXPECT_EQ(s.back().overall & wire::kOverallSpeedFromTach, 0);
  put_le16(sp.data(), wire::kSpeedFromTach);
  EXPECT_EQ(ack_of(request(wire::MsgType::SetSpeed, sp, wire::MsgType::Ack)).status, 0);
  link->frames.clear();
  run(4.5);
  s = samples();
  ASSERT_FALSE(s.empty());
  EXPECT_EQ(s.back().speed_rpm, 3000);
  EXPECT_NE(s.back().overall & wire::kOverallSpeedFromTach, 0);
  // The configuration survives a reboot; the reset counter persists.
  EXPECT_EQ(ack_of(request(wire::MsgType::Reboot, {}, wire::MsgType::Ack)).status, 0);
  run(0.1);
  ASSERT_TRUE(board->reset_pending());
  board->mcu_reset();
  restart();
  EXPECT_EQ(app->config().sample_period_ms, 2000u);
  run(1.0);
  EXPECT_EQ(info().resets, 2u);
}

TEST_F(AppFixture, AuthenticatedModelUploadAndRefusals) {
  boot();
  run(6.0);
  const auto key = test::dev_key();
  const auto blob = test::model_blob();
  std::vector<uint8_t> tag;
  ASSERT_EQ(upload(blob, key, &tag), 0);
  wire::Info i = info();
  EXPECT_EQ(i.model_seq, 1u);
  EXPECT_EQ(i.model_state, static_cast<uint8_t>(wire::ModelState::Active));
  EXPECT_EQ(i.model_crc, blob_stored_crc(blob.data()));
  // Replay of the accepted COMMIT: the nonce is used up.
  EXPECT_EQ(ack_of(request(wire::MsgType::ModelCommit, tag, wire::MsgType::Ack)).status,
            static_cast<uint8_t>(wire::Nack::NoSession));
  // Wrong key: refused, old model kept.
  auto wrong = key;
  wrong[5] ^= 1;
  EXPECT_EQ(upload(test::model_blob(1.0), wrong), static_cast<uint8_t>(wire::Nack::AuthFailed));
  EXPECT_EQ(info().model_seq, 1u);
  // Read-back of the active blob.
  std::vector<uint8_t> rd = {0, 0, 40};
  auto d = request(wire::MsgType::ModelRead, rd, wire::MsgType::ModelData);
  ASSERT_TRUE(d && d->type == wire::type_code(wire::MsgType::ModelData));
  EXPECT_TRUE(std::equal(blob.begin(), blob.begin() + 40, d->payload.begin() + 2));
  // Predictions are reported once the model runs.
  link->frames.clear();
  run(11.0);
  const auto s = samples();
  ASSERT_FALSE(s.empty());
  EXPECT_NE(s.back().overall & wire::kOverallModelActive, 0);
  EXPECT_NE(s.back().predicted_mK[0], wire::kMissing);
  EXPECT_EQ(s.back().predicted_mK[3], s.back().temp_mK[3]) << "ambient channel predicts ambient";
  // The model survives a reboot.
  board->mcu_reset();
  restart();
  EXPECT_EQ(app->model_seq(), 1u);
}

// A host without the key: MODEL_BEGIN gets its nonce, but nothing it sends afterwards writes EEPROM.
TEST_F(AppFixture, KeylessHostWritesNoEepromByte) {
  boot();
  run(6.0);
  const auto key = test::dev_key();
  ASSERT_EQ(upload(test::model_blob(), key), 0);
  run(1.0);
  const std::vector<uint8_t> image = board->eeprom();
  const uint64_t writes = board->eeprom_writes();
  auto wrong = key;
  wrong[0] ^= 0x40;
  const auto blob = test::model_blob(1.0);
  std::vector<uint8_t> p(6);
  put_le16(p.data(), static_cast<uint16_t>(blob.size()));
  put_le32(p.data() + 2, crc32(blob.data(), blob.size()));
  auto ch = request(wire::MsgType::ModelBegin, p, wire::MsgType::AuthChallenge);
  ASSERT_TRUE(ch && ch->type == wire::type_code(wire::MsgType::AuthChallenge));
  std::vector<uint8_t> chunk(2 + 8);
  std::copy(blob.begin(), blob.begin() + 8, chunk.begin() + 2);
  EXPECT_EQ(ack_of(request(wire::MsgType::ModelChunk, chunk, wire::MsgType::Ack)).status,
            static_cast<uint8_t>(wire::Nack::NoSession));
  EXPECT_EQ(ack_of(request(wire::MsgType::ModelAuth, auth_tag(wrong, ch->payload, blob), wire::MsgType::Ack)).status,
            static_cast<uint8_t>(wire::Nack::AuthFailed));
  // The nonce is spent: the right tag for it no longer opens the session.
  EXPECT_EQ(ack_of(request(wire::MsgType::ModelAuth, auth_tag(key, ch->payload, blob), wire::MsgType::Ack)).status,
            static_cast<uint8_t>(wire::Nack::NoSession));
  EXPECT_EQ(ack_of(request(wire::MsgType::ModelChunk, chunk, wire::MsgType::Ack)).status,
            static_cast<uint8_t>(wire::Nack::NoSession));
  run(1.0);
  EXPECT_EQ(board->eeprom_writes(), writes);
  EXPECT_TRUE(board->eeprom() == image);
  EXPECT_EQ(info().model_seq, 1u);
}

// The model's channel map against the module's roles: a channel whose configured role is not the
// node its model was reduced for gets no prediction (so no model checks), and no channel does when
// the model's ambient channel is no longer the ambient; restoring the role restores them.
TEST_F(AppFixture, ChannelsWhoseRoleDisagreesWithTheModelGetNoPrediction) {
  boot();
  run(6.0);
  ASSERT_EQ(upload(test::model_blob(), test::dev_key()), 0);
  auto set_role = [&](uint8_t channel_index, wire::ChannelRole role) {
    std::vector<uint8_t> p(5);
    p[0] = wire::channel_role_key(channel_index);
    put_le32(p.data() + 1, static_cast<uint32_t>(role));
    ASSERT_EQ(ack_of(request(wire::MsgType::SetConfig, p, wire::MsgType::Ack)).status, 0);
  };
  auto last = [&] {
    link->frames.clear();
    run(11.0);
    const auto s = samples();
    EXPECT_FALSE(s.empty());
    return s.empty() ? wire::Sample{} : s.back();
  };
  wire::Sample s = last();
  for (int j : {0, 1, 2, 4}) EXPECT_NE(s.predicted_mK[j], wire::kMissing) << j;
  // Probes swapped in the configuration: ch1 now says front bearing, ch3 rear bearing.
  set_role(0, wire::ChannelRole::FrontBearing);
  set_role(2, wire::ChannelRole::RearBearing);
  s = last();
  EXPECT_EQ(s.predicted_mK[0], wire::kMissing);
  EXPECT_EQ(s.predicted_mK[2], wire::kMissing);
  EXPECT_NE(s.predicted_mK[1], wire::kMissing) << "the housing's role still matches";
  EXPECT_NE(s.predicted_mK[4], wire::kMissing) << "a channel the model does not check (role unchecked)";
  set_role(0, wire::ChannelRole::RearBearing);
  set_role(2, wire::ChannelRole::FrontBearing);
  set_role(3, wire::ChannelRole::Spare);  // the model's ambient channel is no ambient any more
  s = last();
  for (int j = 0; j < 5; ++j) EXPECT_EQ(s.predicted_mK[j], wire::kMissing) << j;
  set_role(3, wire::ChannelRole::Ambient);
  s = last();
  for (int j = 0; j < 5; ++j) EXPECT_NE(s.predicted_mK[j], wire::kMissing) << j;
}

TEST_F(AppFixture, DeviceWithoutKeyRefusesModelWrites) {
  sim::NativeBoardOptions o;
  o.erased_key = true;
  boot(o);
  run(1.0);
  std::vector<uint8_t> p(6);
  put_le16(p.data(), static_cast<uint16_t>(kReducedModelBlobSize));
  const wire::Ack a = ack_of(request(wire::MsgType::ModelBegin, p, wire::MsgType::AuthChallenge));
  EXPECT_EQ(a.status, static_cast<uint8_t>(wire::Nack::AuthFailed));
  EXPECT_EQ(a.detail, 1u);
  EXPECT_EQ(info().device_id, 0u);
}

TEST_F(AppFixture, StoppedMainLoopIsResetByTheWatchdog) {
  boot();
  run(3.0);
  board->advance_us(2'500'000);  // firmware stuck: nobody polls
  EXPECT_TRUE(board->reset_pending());
  EXPECT_EQ(board->watchdog_resets(), 1u);
  board->mcu_reset();
  restart();
  run(1.0);
  const wire::Info i = info();
  EXPECT_EQ(i.watchdog_resets, 1u);
  EXPECT_EQ(i.reset_cause & 0x08, 0x08);
}

}  // namespace
}  // namespace btsm
