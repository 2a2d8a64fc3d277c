// Host-in-the-loop, native board: power cuts at >= 200 random EEPROM-write positions while a
// new model is committed; after every reboot the module runs a valid model, the old or the new.
// And a host without the device key cannot change a single EEPROM byte.
#include "boards/sim/native_board.hpp"
#include "firmware/app.hpp"
#include "model_upload.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <random>

namespace btsm::test {
namespace {

struct NativeLink {
  NativeLink() { boot(); }
  void boot() {
    app = std::make_unique<App<sim::NativeBoard>>(board);
    app->init();
  }
  void send(const std::vector<uint8_t>& b) { board.host_send(b); }
  void step(double s) {
    if (board.reset_pending()) return;  // power is off until the test reboots the MCU
    board.run_until_us(*app, board.now_us() + uint64_t(s * 1e6));
    cap.feed(board.host_receive());
  }
  Capture& capture() { return cap; }
  void reboot() {
    board.mcu_reset();
    cap = Capture();
    boot();
  }

  sim::NativeBoard board;
  std::unique_ptr<App<sim::NativeBoard>> app;
  Capture cap;
};

TEST(HilPowerLoss, EveryBootHasTheOldOrTheNewModel) {
  const auto blob_a = spindle_model_blob(0), blob_b = spindle_model_blob(1);
  const uint32_t crc_a = blob_stored_crc(blob_a.data()), crc_b = blob_stored_crc(blob_b.data());
  ASSERT_NE(crc_a, crc_b);

  // Module with model A stored; its EEPROM image is the starting point of every trial.
  NativeLink base;
  uint8_t seq = 0;
  base.step(1.0);
  ASSERT_EQ(upload_model(base, blob_a, seq), 0);
  base.step(0.5);
  ASSERT_EQ(get_info(base, seq).model_crc, crc_a);
  const std::vector<uint8_t> image_a = base.board.eeprom();

  // How many EEPROM writes one upload of model B takes (the firmware streams the chunks into
  // the inactive slot and commits with a header write at the end: all of it is "model writes").
  uint64_t commit_writes = 0;
  {
    NativeLink l;
    l.board.eeprom() = image_a;
    l.reboot();
    l.step(0.5);
    const uint64_t w0 = l.board.eeprom_writes();
    ASSERT_EQ(upload_model(l, blob_b, seq), 0);
    commit_writes = l.board.eeprom_writes() - w0;
    ASSERT_EQ(get_info(l, seq).model_crc, crc_b);
  }
  ASSERT_GE(commit_writes, 464u) << "an upload must write the whole blob";

  std::mt19937_64 rng(20240607);
  // Random cut positions over the whole upload, plus every one of the last 16 writes (where the
  // commit record goes), plus some positions just after the upload completed (then the supply
  // is cut right after the ACK instead).
  std::vector<uint64_t> cuts;
  std::uniform_int_distribution<uint64_t> pick(0, commit_writes + 29);
  for (int i = 0; i < 200; ++i) cuts.push_back(pick(rng));
  for (uint64_t k = commit_writes - 16; k < commit_writes + 4; ++k) cuts.push_back(k);
  int old_model = 0, new_model = 0;
  const int kTrials = int(cuts.size());
  for (int trial = 0; trial < kTrials; ++trial) {
    const uint64_t cut = cuts[size_t(trial)];
    SCOPED_TRACE("trial " + std::to_string(trial) + ", power cut at write " + std::to_string(cut));
    NativeLink l;
    l.board.eeprom() = image_a;
    l.reboot();
    l.step(0.3);
    l.board.cut_power_at_write(cut, uint8_t(rng()));  // the torn cell gets a random value
    int status = -1;
    try {
      status = upload_model(l, blob_b, seq);
    } catch (const std::runtime_error&) {
      // the module went dark in the middle of the upload: expected
    }
    if (cut < commit_writes) {
      ASSERT_TRUE(l.board.reset_pending());
      ASSERT_EQ(l.board.pending_reset_cause(), sim::NativeBoard::ResetCause::kPowerLoss);
    } else {
      ASSERT_EQ(status, 0) << "upload completed before the cut position";
    }
    l.reboot();
    l.step(6.0);  // boot, one full sample sweep
    const wire::Info info = get_info(l, seq);
    ASSERT_TRUE(info.model_crc == crc_a || info.model_crc == crc_b) << "model crc " << info.model_crc;
    (info.model_crc == crc_a ? old_model : new_model)++;
    ASSERT_FALSE(l.cap.samples.empty());
    EXPECT_NE(l.cap.samples.back().overall & wire::kOverallModelActive, 0) << "no active model after boot";
  }
  std::printf("%d trials (cuts during %llu-write uploads, some just after): %d booted the old model, %d the new one\n", kTrials,
              static_cast<unsigned long long>(commit_writes), old_model, new_model);
  EXPECT_GT(old_model, 0);
  EXPECT_GT(new_model, 0);
}

// Everything a keyless host can send (chunks before and after a MODEL_AUTH with a wrong key's
// tag, a commit with a wrong tag) is refused, and the whole EEPROM stays byte for byte as it was:
// neither the inactive slot (the fallback model) nor its commit marker is written.
TEST(HilUploadAuth, KeylessHostCannotChangeAnEepromByte) {
  NativeLink l;
  uint8_t seq = 0;
  l.step(6.0);  // boot (its counter write) and a sweep
  const std::vector<uint8_t> before = l.board.eeprom();
  const uint64_t writes_before = l.board.eeprom_writes();
  const KeylessAttempt r = keyless_upload(l, spindle_model_blob(1), seq);
  l.step(1.0);
  EXPECT_EQ(r.chunks_before_auth, int(wire::Nack::NoSession));
  EXPECT_EQ(r.auth, int(wire::Nack::AuthFailed));
  EXPECT_EQ(r.chunks_after_auth, int(wire::Nack::NoSession));
  EXPECT_EQ(r.commit, int(wire::Nack::NoSession));
  EXPECT_EQ(l.board.eeprom_writes(), writes_before);
  EXPECT_TRUE(l.board.eeprom() == before) << "a keyless host changed EEPROM bytes";
  // The key holder still can, right after.
  EXPECT_EQ(upload_model(l, spindle_model_blob(1), seq), 0);
  EXPECT_EQ(get_info(l, seq).model_crc, blob_stored_crc(spindle_model_blob(1).data()));
}

}  // namespace
}  // namespace btsm::test
