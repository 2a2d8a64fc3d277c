// Model store: authenticated upload, validation NACKs, and power loss at every EEPROM write.
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "common/hmac.hpp"
#include "firmware/model_store.hpp"
#include "test_support.hpp"

namespace btsm {
namespace {

using Storage = sim::NativeBoard::Storage;
using Nack = wire::Nack;

sim::NativeBoardOptions fast_eeprom() {
  sim::NativeBoardOptions o;
  o.eeprom_write_us = 0;
  return o;
}

std::array<uint8_t, 32> tag_for(const std::array<uint8_t, 32>& key, const uint8_t* nonce,
                                const std::vector<uint8_t>& blob) {
  HmacSha256 mac(key.data(), key.size());
  mac.update(nonce, 16);
  mac.update(blob.data(), blob.size());
  std::array<uint8_t, 32> tag;
  mac.final(tag.data());
  return tag;
}

std::array<uint8_t, 32> auth_tag_for(const std::array<uint8_t, 32>& key, const uint8_t* nonce,
                                     const std::vector<uint8_t>& blob) {
  uint8_t context[wire::kModelAuthContextSize];
  wire::encode_model_auth_context(static_cast<uint16_t>(blob.size()), crc32(blob.data(), blob.size()), context);
  HmacSha256 mac(key.data(), key.size());
  mac.update(nonce, 16);
  mac.update(context, sizeof context);
  std::array<uint8_t, 32> tag;
  mac.final(tag.data());
  return tag;
}

struct Upload {
  Nack begin = Nack::Ok, auth = Nack::Ok, last_chunk = Nack::Ok, commit = Nack::Ok;
  uint16_t detail = 0;
  bool power_lost = false;
};

// Runs a whole upload through the store, stepping EEPROM writes; stops at a power loss. `key` is
// the host's key (MODEL_AUTH and commit tags), `device_key` the module's.
Upload upload(sim::NativeBoard& board, ModelStore<Storage>& store, ModelRuntime& model,
              const std::vector<uint8_t>& blob, const std::array<uint8_t, 32>& key,
              const std::array<uint8_t, 32>& device_key, uint8_t nonce_byte = 7,
              const std::array<uint8_t, 32>* forced_tag = nullptr) {
  Upload u;
  uint8_t nonce[16];
  std::memset(nonce, nonce_byte, sizeof nonce);
  auto drain = [&] {
    while (store.busy()) {
      store.step();
      if (board.reset_pending()) return false;
    }
    return true;
  };
  u.begin = store.begin(static_cast<uint16_t>(blob.size()), crc32(blob.data(), blob.size()), nonce);
  if (u.begin != Nack::Ok) return u;
  const auto auth = auth_tag_for(key, nonce, blob);
  u.auth = store.authenticate(auth.data(), device_key.data(), 32);
  if (u.auth != Nack::Ok) return u;
  if (!drain()) { u.power_lost = true; return u; }
  for (size_t off = 0; off < blob.size(); off += 11) {
    const uint8_t n = static_cast<uint8_t>(std::min<size_t>(11, blob.size() - off));
    u.last_chunk = store.chunk(static_cast<uint16_t>(off), blob.data() + off, n, u.detail);
    if (u.last_chunk != Nack::Ok) return u;
    if (!drain()) { u.power_lost = true; return u; }
  }
  const auto tag = forced_tag ? *forced_tag : tag_for(key, nonce, blob);
  u.commit = store.commit(tag.data(), u.detail);
  if (u.commit != Nack::Ok) return u;
  if (!drain()) { u.power_lost = true; return u; }
  store.activate_committed(model);
  return u;
}

std::vector<uint8_t> active_blob(ModelStore<Storage>& store) {
  std::vector<uint8_t> b(kReducedModelBlobSize);
  for (size_t i = 0; i < b.size(); ++i) b[i] = store.read_active_byte(static_cast<uint16_t>(i));
  return b;
}

TEST(ModelStore, EmptyEepromHasNoModel) {
  sim::NativeBoard board(fast_eeprom());
  ModelStore<Storage> store(board.storage);
  ModelRuntime m;
  store.boot(m);
  EXPECT_EQ(store.state(), wire::ModelState::None);
  EXPECT_EQ(store.active_blob_crc(), 0u);
}

TEST(ModelStore, AcceptedUploadSurvivesReboot) {
  sim::NativeBoard board(fast_eeprom());
  const auto key = test::dev_key();
  const auto blob = test::model_blob();
  ASSERT_EQ(blob.size(), kReducedModelBlobSize);
  ModelRuntime m;
  {
    ModelStore<Storage> store(board.storage);
    store.boot(m);
    const Upload u = upload(board, store, m, blob, key, key);
    ASSERT_EQ(u.commit, Nack::Ok);
    EXPECT_TRUE(store.active());
    EXPECT_EQ(store.active_seq(), 1u);
    EXPECT_EQ(store.active_blob_crc(), blob_stored_crc(blob.data()));
  }
  ModelStore<Storage> again(board.storage);
  ModelRuntime loaded;
  again.boot(loaded);
  ASSERT_TRUE(again.active());
  EXPECT_EQ(active_blob(again), blob);
  ReducedModel ref;
  ModelRuntime parsed;
  ASSERT_TRUE(decode(blob.data(), blob.size(), ref).ok());
  ASSERT_TRUE(again.load_slot(0, parsed).ok());
  EXPECT_EQ(parsed.n_breakpoints, ref.n_breakpoints);
  EXPECT_EQ(parsed.ambient_channel, ref.ambient_channel);
  EXPECT_EQ(parsed.enabled_mask, ref.enabled_mask);
  for (int j = 0; j < kModelChannels; ++j) {
    EXPECT_EQ(parsed.limits[j].warn_band_mK, ref.limits[j].warn_band_mK);
    EXPECT_EQ(parsed.limits[j].alarm_band_mK, ref.limits[j].alarm_band_mK);
    EXPECT_EQ(parsed.limits[j].abs_limit_mK, ref.limits[j].abs_limit_mK);
    EXPECT_EQ(parsed.limits[j].max_rise_mK_per_min, ref.limits[j].max_rise_mK_per_min);
  }
  EXPECT_EQ(loaded.dt_ms, ref.dt_ms);
  EXPECT_EQ(loaded.n_breakpoints, ref.n_breakpoints);
  EXPECT_EQ(std::memcmp(loaded.speed_rpm, ref.speed_rpm, sizeof ref.speed_rpm), 0);
  EXPECT_EQ(loaded.limits[0].alarm_band_mK, ref.limits[0].alarm_band_mK);
  // A second model goes to the other slot with the next sequence number.
  const auto blob2 = test::model_blob(1.0);
  ASSERT_EQ(upload(board, again, loaded, blob2, key, key).commit, Nack::Ok);
  EXPECT_EQ(again.active_seq(), 2u);
  ModelStore<Storage> third(board.storage);
  third.boot(loaded);
  EXPECT_EQ(third.active_seq(), 2u);
  EXPECT_EQ(active_blob(third), blob2);
}

// The firmware steps the model with coefficients read from EEPROM and interpolated member by
// member (only those of modelled channels); the common step() interpolates a whole decoded model.
// Same predictions and state, bit for bit, at breakpoints, inside segments, above the top one
// and at standstill, whichever channel is ambient or disabled.
TEST(ModelStore, StepFromEepromMatchesTheCommonModelAtEverySpeed) {
  const auto key = test::dev_key();
  for (const uint8_t mask : {uint8_t(0x1F), uint8_t(0x0F), uint8_t(0x1B)}) {
    sim::NativeBoard board(fast_eeprom());
    auto blob = test::model_blob(0.5);
    blob[kBlobOffEnabledMask] = mask;  // channel 4 disabled (0x0F) or channel 3 (0x1B)
    test::fix_blob_crc(blob);
    ReducedModel ref;
    ASSERT_TRUE(decode(blob.data(), blob.size(), ref).ok()) << int(mask);
    ModelStore<Storage> store(board.storage);
    ModelRuntime m;
    store.boot(m);
    ASSERT_EQ(upload(board, store, m, blob, key, key).commit, Nack::Ok) << int(mask);
    ReducedModelState fw, common;
    fw.x_q20 = common.x_q20 = 3 << 20;  // 3 K above ambient
    std::mt19937 rng(5);
    std::vector<uint16_t> speeds = {0, 6000, 5999, 6001, 3000, 3000, 12000, 13000, 1, 11999, 0, 65534};
    for (int i = 0; i < 300; ++i) speeds.push_back(uint16_t(rng() % 14000));
    for (const uint16_t rpm : speeds) {
      int32_t p_fw[kModelChannels], p_common[kModelChannels];
      store.step_model(m, fw, rpm, 21500, p_fw);
      step(ref, common, rpm, 21500, p_common);
      ASSERT_EQ(fw.x_q20, common.x_q20) << "mask " << int(mask) << " rpm " << rpm;
      for (int j = 0; j < kModelChannels; ++j)
        ASSERT_EQ(p_fw[j], p_common[j]) << "mask " << int(mask) << " rpm " << rpm << " channel " << j;
    }
  }
}

struct Rejection {
  const char* name;
  void (*edit)(std::vector<uint8_t>&);
  Nack expected;
};

TEST(ModelStore, InvalidBlobsAreNackedAndTheOldModelStaysActive) {
  const Rejection cases[] = {
      {"blob-internal CRC", [](std::vector<uint8_t>& b) { b[100] ^= 1; }, Nack::BlobCrc},
      {"version", [](std::vector<uint8_t>& b) { b[kBlobOffVersion] = 9; test::fix_blob_crc(b); }, Nack::BlobVersion},
      {"magic", [](std::vector<uint8_t>& b) { b[0] = 'X'; test::fix_blob_crc(b); }, Nack::BlobVersion},
      {"unstable pole a = 1.0",
       [](std::vector<uint8_t>& b) { put_le32(b.data() + kBlobOffBreakpoints + kBlobBreakpointSize, 1UL << 30); test::fix_blob_crc(b); },
       Nack::BlobInvalid},
      {"NaN-like gain out of range (b = max)",
       [](std::vector<uint8_t>& b) { put_le32(b.data() + kBlobOffBreakpoints + kBlobBreakpointSize + 4, 0x7FFFFFFF); test::fix_blob_crc(b); },
       Nack::BlobInvalid},
      {"alarm band below warn band",
       [](std::vector<uint8_t>& b) { put_le16(b.data() + kBlobOffAlarmBands, 1); test::fix_blob_crc(b); },
       Nack::BlobInvalid},
  };
  const auto key = test::dev_key();
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    sim::NativeBoard board(fast_eeprom());
    ModelStore<Storage> store(board.storage);
    ModelRuntime m;
    store.boot(m);
    const auto good = test::model_blob();
    ASSERT_EQ(upload(board, store, m, good, key, key).commit, Nack::Ok);
    ModelRuntime before = m;
    auto bad = good;
    c.edit(bad);
    const Upload u = upload(board, store, m, bad, key, key);
    EXPECT_EQ(u.commit, c.expected);
    EXPECT_EQ(store.active_seq(), 1u);
    EXPECT_EQ(active_blob(store), good);
    EXPECT_EQ(std::memcmp(&before, &m, sizeof m), 0) << "runtime model untouched by the failed upload";
    ModelStore<Storage> rebooted(board.storage);
    rebooted.boot(m);
    EXPECT_EQ(rebooted.active_seq(), 1u);
    EXPECT_EQ(active_blob(rebooted), good);
  }
}

TEST(ModelStore, WrongKeyReplayAndProtocolErrorsAreRefused) {
  sim::NativeBoard board(fast_eeprom());
  ModelStore<Storage> store(board.storage);
  ModelRuntime m;
  store.boot(m);
  const auto key = test::dev_key();
  const auto blob = test::model_blob();
  ASSERT_EQ(upload(board, store, m, blob, key, key).commit, Nack::Ok);
  // Tags made with another key: MODEL_AUTH refuses, and nothing of the upload is written.
  auto other = key;
  other[0] ^= 0x80;
  const auto blob2 = test::model_blob(2.0);
  const std::vector<uint8_t> image = board.eeprom();
  const uint64_t writes = board.eeprom_writes();
  EXPECT_EQ(upload(board, store, m, blob2, other, key).auth, Nack::AuthFailed);
  EXPECT_EQ(board.eeprom_writes(), writes);
  EXPECT_TRUE(board.eeprom() == image);
  EXPECT_EQ(active_blob(store), blob);
  // Replay: the tag of an earlier session (nonce 7) presented in a session with nonce 9.
  uint8_t nonce7[16];
  std::memset(nonce7, 7, 16);
  const auto old_tag = tag_for(key, nonce7, blob2);
  EXPECT_EQ(upload(board, store, m, blob2, key, key, 9, &old_tag).commit, Nack::AuthFailed);
  EXPECT_EQ(store.active_seq(), 1u);
  // Commit without a session (the nonce was used up by the failed commit).
  uint16_t detail = 0;
  EXPECT_EQ(store.commit(old_tag.data(), detail), Nack::NoSession);
  uint8_t data[4] = {1, 2, 3, 4};
  EXPECT_EQ(store.chunk(0, data, 4, detail), Nack::NoSession);
  // Chunks and commit after MODEL_BEGIN but before MODEL_AUTH; MODEL_AUTH without MODEL_BEGIN;
  // a second MODEL_AUTH with the spent nonce. None of it writes EEPROM.
  const std::vector<uint8_t> before_sessions = board.eeprom();
  uint8_t nonce[16] = {};
  EXPECT_EQ(store.authenticate(old_tag.data(), key.data(), 32), Nack::NoSession);
  ASSERT_EQ(store.begin(static_cast<uint16_t>(blob2.size()), crc32(blob2.data(), blob2.size()), nonce), Nack::Ok);
  EXPECT_EQ(store.chunk(0, data, 4, detail), Nack::NoSession);
  EXPECT_FALSE(store.busy());
  const auto good_auth = auth_tag_for(key, nonce, blob2);
  auto bad_auth = good_auth;
  bad_auth[31] ^= 1;
  EXPECT_EQ(store.authenticate(bad_auth.data(), key.data(), 32), Nack::AuthFailed);
  EXPECT_EQ(store.authenticate(good_auth.data(), key.data(), 32), Nack::NoSession);
  EXPECT_FALSE(store.busy());
  // The auth tag covers the announced length and CRC: a tag for blob2 does not open a session
  // announced with another CRC, and a commit tag is no auth tag. (Every valid blob ends with its
  // own CRC-32, so the CRC-32 over all of it is the same residue for every valid blob: the content
  // is bound by the commit tag, not by this one.)
  EXPECT_EQ(crc32(blob.data(), blob.size()), crc32(blob2.data(), blob2.size()));
  ASSERT_EQ(store.begin(static_cast<uint16_t>(blob2.size()), crc32(blob2.data(), blob2.size()) ^ 1u, nonce), Nack::Ok);
  EXPECT_EQ(store.authenticate(good_auth.data(), key.data(), 32), Nack::AuthFailed);
  ASSERT_EQ(store.begin(static_cast<uint16_t>(blob2.size()), crc32(blob2.data(), blob2.size()), nonce), Nack::Ok);
  EXPECT_EQ(store.authenticate(tag_for(key, nonce, blob2).data(), key.data(), 32), Nack::AuthFailed);
  EXPECT_FALSE(store.busy());
  EXPECT_TRUE(board.eeprom() == before_sessions);
  // Wrong total length and out-of-order chunk.
  EXPECT_EQ(store.begin(100, 0, nonce), Nack::BadLength);
  ASSERT_EQ(store.begin(static_cast<uint16_t>(kReducedModelBlobSize), 0, nonce), Nack::Ok);
  uint8_t zero_context[wire::kModelAuthContextSize];
  wire::encode_model_auth_context(static_cast<uint16_t>(kReducedModelBlobSize), 0, zero_context);
  std::array<uint8_t, 32> zero_auth;
  {
    HmacSha256 mac(key.data(), key.size());
    mac.update(nonce, 16);
    mac.update(zero_context, sizeof zero_context);
    mac.final(zero_auth.data());
  }
  ASSERT_EQ(store.authenticate(zero_auth.data(), key.data(), 32), Nack::Ok);
  while (store.busy()) store.step();
  EXPECT_EQ(store.chunk(11, data, 4, detail), Nack::BadOffset);
  EXPECT_EQ(detail, 0u);
  store.abort_session();
}

// The key property: a power loss at ANY EEPROM byte write of an upload leaves a valid model --
// the old one (seq 1) or, once the commit marker is complete, the new one (seq 2).
TEST(ModelStore, PowerLossAtEveryWriteIndexLeavesAValidModel) {
  const auto key = test::dev_key();
  const auto old_blob = test::model_blob();
  const auto new_blob = test::model_blob(3.0);
  std::vector<uint8_t> image;
  uint64_t writes_per_upload = 0;
  {
    sim::NativeBoard board(fast_eeprom());
    ModelStore<Storage> store(board.storage);
    ModelRuntime m;
    store.boot(m);
    ASSERT_EQ(upload(board, store, m, old_blob, key, key).commit, Nack::Ok);
    image = board.eeprom();
    const uint64_t w0 = board.eeprom_writes();
    ASSERT_EQ(upload(board, store, m, new_blob, key, key).commit, Nack::Ok);
    writes_per_upload = board.eeprom_writes() - w0;
  }
  ASSERT_GT(writes_per_upload, kReducedModelBlobSize / 2);
  int old_seen = 0, new_seen = 0;
  for (uint64_t k = 0; k <= writes_per_upload; ++k) {
    for (uint8_t torn : {uint8_t(0xFF), uint8_t(0x00), uint8_t(0x5A)}) {
      sim::NativeBoard board(fast_eeprom());
      board.eeprom() = image;
      ModelRuntime m;
      ModelStore<Storage> store(board.storage);
      store.boot(m);
      ASSERT_EQ(store.active_seq(), 1u);
      board.cut_power_at_write(k, torn);
      const Upload u = upload(board, store, m, new_blob, key, key);
      ASSERT_EQ(u.power_lost, k < writes_per_upload) << "write " << k;
      board.mcu_reset();
      ModelStore<Storage> after(board.storage);
      ModelRuntime loaded;
      after.boot(loaded);
      ASSERT_TRUE(after.active()) << "no valid model after power loss at write " << k;
      const auto got = active_blob(after);
      if (after.active_seq() == 1u) {
        ASSERT_EQ(got, old_blob) << k;
        ++old_seen;
      } else {
        ASSERT_EQ(after.active_seq(), 2u) << k;
        ASSERT_EQ(got, new_blob) << k;
        ++new_seen;
      }
    }
  }
  EXPECT_GT(old_seen, 0);
  EXPECT_GT(new_seen, 0);
}

}  // namespace
}  // namespace btsm
