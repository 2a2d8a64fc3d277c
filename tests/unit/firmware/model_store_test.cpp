// Model store: authenticated upload, validation NACKs, and power loss at every EEPROM write.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <iterator>
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

// Uploads `blob` (development key) through `store` and boots a second store on the same EEPROM:
// the new model is active with sequence `seq` before and after the reboot.
void upload_and_reboot(sim::NativeBoard& board, ModelStore<Storage>& store, ModelRuntime& rt,
                       const std::vector<uint8_t>& blob, uint32_t seq) {
  const auto key = test::dev_key();
  ASSERT_EQ(upload(board, store, rt, blob, key, key).commit, Nack::Ok);
  EXPECT_EQ(store.active_seq(), seq);
  ModelStore<Storage> rebooted(board.storage);
  rebooted.boot(rt);
  EXPECT_EQ(rebooted.active_seq(), seq);
  EXPECT_EQ(active_blob(rebooted), blob) << "another model than the last one flashed is active after the reboot";
}

// Field by field (the structs have padding).
void expect_same(const ModelRuntime& rt, const ModelSchedule& s, const ChannelLimits* l) {
  EXPECT_EQ(rt.n_breakpoints, s.n_breakpoints);
  EXPECT_EQ(rt.ambient_channel, s.ambient_channel);
  EXPECT_EQ(rt.enabled_mask, s.enabled_mask);
  EXPECT_EQ(rt.dt_ms, s.dt_ms);
  for (int k = 0; k < kModelEarlyStopPhases; ++k) EXPECT_EQ(rt.stop_end_s[k], s.stop_end_s[k]);
  for (int j = 0; j < kModelChannels; ++j) {
    EXPECT_EQ(rt.role[j], s.role[j]) << j;
    EXPECT_EQ(rt.limits[j].drift_mK, l[j].drift_mK) << j;
    EXPECT_EQ(rt.limits[j].low_drift_mK, l[j].low_drift_mK) << j;
    EXPECT_EQ(rt.limits[j].warn_evidence, l[j].warn_evidence) << j;
    EXPECT_EQ(rt.limits[j].alarm_evidence, l[j].alarm_evidence) << j;
    EXPECT_EQ(rt.limits[j].low_warn_evidence, l[j].low_warn_evidence) << j;
    EXPECT_EQ(rt.limits[j].abs_limit_mK, l[j].abs_limit_mK) << j;
    EXPECT_EQ(rt.limits[j].max_rise_mK_per_min, l[j].max_rise_mK_per_min) << j;
  }
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
  expect_same(parsed, ref.schedule, ref.limits);
  expect_same(loaded, ref.schedule, ref.limits);
  EXPECT_EQ(loaded.role[0], 3) << "the channel map survives the reboot";
  // A second model goes to the other slot with the next sequence number.
  upload_and_reboot(board, again, loaded, test::model_blob(1.0), 2u);
}

// A slot with sequence 0xFFFFFFFF (a corrupted or hostile image): the next model gets sequence 1
// (0 skipped), and at the next boot that one is the newer (serial-number order), not the old one
// (probe 5).
TEST(ModelStore, TheSequenceWrapsAndTheNewestModelStaysActive) {
  sim::NativeBoard board(fast_eeprom());
  const auto key = test::dev_key();
  ModelRuntime m;
  {
    ModelStore<Storage> store(board.storage);
    store.boot(m);
    ASSERT_EQ(upload(board, store, m, test::model_blob(), key, key).commit, Nack::Ok);
  }
  // Renumber slot 0's model to 0xFFFFFFFF, its CRC with it.
  std::vector<uint8_t>& ee = board.eeprom();
  const uint16_t base = eeprom_layout::slot_addr(0);
  uint8_t seq[4];
  put_le32(seq, 0xFFFFFFFFu);
  std::memcpy(&ee[base + eeprom_layout::kHdrSeq], seq, 4);
  put_le32(&ee[base + eeprom_layout::kHdrCrc],
           crc32(&ee[eeprom_layout::blob_addr(0)], eeprom_layout::kBlobSize, crc32(seq, 4)));
  ModelStore<Storage> store(board.storage);
  store.boot(m);
  ASSERT_EQ(store.active_seq(), 0xFFFFFFFFu);
  // 0 is skipped: INFO reports 0 without an active model, and flash-model would see no change
  upload_and_reboot(board, store, m, test::model_blob(1.0), 1u);  // the old model came back at the reset
  upload_and_reboot(board, store, m, test::model_blob(), 2u);
}

// The firmware steps the model with coefficients read from EEPROM and interpolated member by
// member (only those of modelled channels), or the stop phase's poles; the common step()
// interpolates a whole decoded model. Same predictions and states, bit for bit, at breakpoints,
// inside segments, above the top one and through every stop phase, whichever channel is ambient
// or not modelled.
TEST(ModelStore, StepFromEepromMatchesTheCommonModelAtEverySpeed) {
  const auto key = test::dev_key();
  struct Map {
    uint8_t mask, ambient;
  };
  for (const Map map : {Map{0x1F, 3}, Map{0x0F, 3}, Map{0x1B, 4}, Map{0x17, 0xFF}}) {
    sim::NativeBoard board(fast_eeprom());
    thermal::ReducedModelF64 f = test::model_f64(0.5);
    f.enabled_mask = map.mask;
    f.ambient_channel = map.ambient;
    for (int j = 0; j < kModelChannels; ++j) {
      const bool on = (map.mask >> j) & 1U;
      f.role[j] = j == map.ambient ? kModelRoleAmbient : (on ? kModelRoleUnchecked : kModelRoleNotModelled);
      for (int i = 0; i < 3; ++i)
        if (on && j != map.ambient && f.a[i][j] == 0.0) f.a[i][j] = 0.997, f.b_K[i][j] = i ? 0.001 * i : 0.0;
      for (int k = 0; k < 2; ++k)
        if (on && j != map.ambient && f.stop_a[k][j] == 0.0) f.stop_a[k][j] = 0.99;
    }
    ReducedModel ref;
    ASSERT_TRUE(thermal::quantize(f, ref).ok()) << int(map.mask);
    std::vector<uint8_t> blob(kReducedModelBlobSize);
    encode(ref, blob.data());
    ModelStore<Storage> store(board.storage);
    ModelRuntime m;
    store.boot(m);
    ASSERT_EQ(upload(board, store, m, blob, key, key).commit, Nack::Ok) << int(map.mask);
    ReducedModelState fw, common;
    const int32_t measured[kModelChannels] = {31000, 26000, 24000, 21500, 23000};
    ASSERT_TRUE(store.init_state(m, fw, 21500, measured));
    ASSERT_TRUE(init_from_measurement(ref.schedule.ambient_channel, ref.schedule.enabled_mask, common, 21500, measured));
    std::mt19937 rng(5);
    std::vector<uint16_t> speeds = {0, 6000, 5999, 6001, 3000, 3000, 12000, 13000, 1, 11999, 0, 65534};
    for (int i = 0; i < 300; ++i) speeds.push_back(uint16_t(rng() % 14000));
    for (int i = 0; i < 600; ++i) speeds.push_back(0);  // 50 min stopped: every stop phase
    for (int i = 0; i < 100; ++i) speeds.push_back(uint16_t(rng() % 3 ? 0 : rng() % 14000));
    int k = 0;
    for (const uint16_t rpm : speeds) {
      int32_t p_fw[kModelChannels], p_common[kModelChannels];
      const int32_t ambient = 21500 + (k++ % 7) * 100;
      store.step_model(m, fw, rpm, ambient, p_fw);
      step(ref, common, rpm, ambient, p_common);
      ASSERT_EQ(std::memcmp(&fw, &common, sizeof fw), 0) << "mask " << int(map.mask) << " rpm " << rpm << " step " << k;
      for (int j = 0; j < kModelChannels; ++j)
        ASSERT_EQ(p_fw[j], p_common[j]) << "mask " << int(map.mask) << " rpm " << rpm << " channel " << j;
    }
  }
}

// A module updated to this firmware with a version-1 model in its EEPROM (an intact slot: marker,
// sequence, CRC all good) does not run it: the model state is Rejected, no prediction is made from
// bytes of another layout.
TEST(ModelStore, StoredVersionOneModelIsNotLoadedAtBoot) {
  std::ifstream f(std::string(BTSM_TEST_DATA_DIR) + "/model-blob-v1/spindle_v1.bin", std::ios::binary);
  const std::vector<uint8_t> v1((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  ASSERT_EQ(v1.size(), kReducedModelBlobSize);
  sim::NativeBoard board(fast_eeprom());
  uint8_t seq[4];
  put_le32(seq, 1);
  std::vector<uint8_t>& ee = board.eeprom();
  const uint16_t base = eeprom_layout::slot_addr(0);
  ee[base + eeprom_layout::kHdrMarker] = eeprom_layout::kMarker0;
  ee[base + eeprom_layout::kHdrMarker + 1] = eeprom_layout::kMarker1;
  std::memcpy(&ee[base + eeprom_layout::kHdrSeq], seq, 4);
  put_le32(&ee[base + eeprom_layout::kHdrCrc], crc32(v1.data(), v1.size(), crc32(seq, 4)));
  put_le16(&ee[base + eeprom_layout::kHdrLen], eeprom_layout::kBlobSize);
  std::memcpy(&ee[eeprom_layout::blob_addr(0)], v1.data(), v1.size());
  ModelStore<Storage> store(board.storage);
  ModelRuntime m;
  store.boot(m);
  EXPECT_EQ(store.state(), wire::ModelState::Rejected);
  EXPECT_FALSE(store.active());
  ModelRuntime parsed;
  const ModelCheck c = store.load_slot(0, parsed);
  EXPECT_EQ(c.status, ModelStatus::kBadVersion);
  EXPECT_EQ(c.channel, 1) << "the version found";
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
      {"alarm evidence below warn evidence",
       [](std::vector<uint8_t>& b) { put_le16(b.data() + kBlobOffAlarmEvidence, 1); test::fix_blob_crc(b); },
       Nack::BlobInvalid},
      {"format version 1 (one shared state)",
       [](std::vector<uint8_t>& b) { b[kBlobOffVersion] = 1; test::fix_blob_crc(b); }, Nack::BlobVersion},
      {"reserved byte set", [](std::vector<uint8_t>& b) { b[kBlobOffReserved + 1] = 1; test::fix_blob_crc(b); },
       Nack::BlobInvalid},
      {"coupling without a carrier",
       [](std::vector<uint8_t>& b) { put_le32(b.data() + kBlobOffCouplings, 5); test::fix_blob_crc(b); }, Nack::BlobInvalid},
      {"channel 1 carried by itself", [](std::vector<uint8_t>& b) { b[kBlobOffCarriers] = 1; test::fix_blob_crc(b); },
       Nack::BlobInvalid},
      {"carrier is the ambient channel", [](std::vector<uint8_t>& b) { b[kBlobOffCarriers] = 4; test::fix_blob_crc(b); },
       Nack::BlobInvalid},
      {"channel map: housing channel claims ambient",
       [](std::vector<uint8_t>& b) { b[kBlobOffRoles + 1] = kModelRoleAmbient; test::fix_blob_crc(b); },
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
    if (bad[kBlobOffVersion] != kReducedModelVersion && bad[0] == 'B') {
      EXPECT_EQ(u.detail >> 8, bad[kBlobOffVersion]) << "the NACK names the version found";
    }
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
