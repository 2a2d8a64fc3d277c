// Model upload against the fake module: round trip with read-back, 20-byte chunk frames,
// wrong key, replayed commit, invalid blobs, blob file formats.
#include "common/crc.hpp"
#include "fake_module.hpp"
#include "host/link/model_flash.hpp"
#include "host/link/serial_transport.hpp"
#include "link_test_support.hpp"
#include "module_on_pty.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <iostream>

using namespace btsm;
using namespace btsm::link;
using btsm::test::FakeModule;
using btsm::test::FakeModuleOptions;

namespace {

struct Rig : test::ModuleOnPty {
  explicit Rig(FakeModuleOptions o = {}) : ModuleOnPty(o, test::quick_session(3)) {}
};

}  // namespace

TEST(FlashModel, RoundTripWithReadBackAndTwentyByteFrames) {
  Rig rig;
  const auto blob = test::make_test_blob(1);
  size_t progress_calls = 0;
  FlashOptions fo;
  fo.progress = [&](const FlashProgress&) { ++progress_calls; };
  const FlashSummary s = flash_model(rig.session, blob, test::fake_module_key(), fo);
  EXPECT_TRUE(s.verified);
  std::cout << "464-byte blob: " << s.chunks << " chunks, largest encoded chunk frame " << s.max_chunk_frame
            << " bytes\n";
  EXPECT_EQ(s.device_id, 0x0000DE70u);
  EXPECT_LE(s.max_chunk_frame, 20u);       // every chunk fits one BLE write
  EXPECT_GE(s.chunks, blob.size() / 10);    // <= 10 data bytes per 20-byte frame
  EXPECT_EQ(s.model_seq_after, s.model_seq_before + 1);
  EXPECT_EQ(rig.module.active_model(), blob);
  EXPECT_GT(progress_calls, s.chunks);
  EXPECT_EQ(read_model(rig.session, blob.size()), blob);
}

TEST(FlashModel, WrongKeyIsRefusedAndOldModelKept) {
  Rig rig;
  const auto old_blob = test::make_test_blob(1);
  flash_model(rig.session, old_blob, test::fake_module_key());
  DeviceKey wrong = test::fake_module_key();
  wrong[5] ^= 0x01;
  try {
    flash_model(rig.session, test::make_test_blob(2), wrong);
    FAIL() << "expected AUTH_FAILED";
  } catch (const NackError& e) {
    EXPECT_EQ(e.code(), static_cast<uint8_t>(wire::Nack::AuthFailed));
    EXPECT_NE(std::string(e.what()).find("AUTH_FAILED"), std::string::npos);
  }
  EXPECT_EQ(rig.module.active_model(), old_blob);
  EXPECT_EQ(rig.module.model_seq(), 1u);
  EXPECT_EQ(read_model(rig.session, old_blob.size()), old_blob);
}

TEST(FlashModel, ReplayedCommitIsRefused) {
  Rig rig;
  const auto blob_a = test::make_test_blob(1);
  flash_model(rig.session, blob_a, test::fake_module_key());
  const auto captured = rig.module.commit_payloads().back();  // an attacker recorded this
  ASSERT_EQ(captured.size(), 32u);

  // 1. Replay alone: no upload session -> NO_SESSION.
  try {
    rig.session.request(wire::MsgType::ModelCommit, captured, std::nullopt);
    FAIL();
  } catch (const NackError& e) {
    EXPECT_EQ(e.code(), static_cast<uint8_t>(wire::Nack::NoSession));
  }
  // 2. Replay inside a fresh session with the same blob: the nonce is new -> AUTH_FAILED.
  const auto ch = rig.session.model_begin(static_cast<uint16_t>(blob_a.size()), crc32(blob_a.data(), blob_a.size()));
  (void)ch;
  for (size_t off = 0; off < blob_a.size(); off += 10)
    rig.session.model_chunk(static_cast<uint16_t>(off),
                            std::span<const uint8_t>(blob_a).subspan(off, std::min<size_t>(10, blob_a.size() - off)));
  try {
    rig.session.request(wire::MsgType::ModelCommit, captured, std::nullopt);
    FAIL();
  } catch (const NackError& e) {
    EXPECT_EQ(e.code(), static_cast<uint8_t>(wire::Nack::AuthFailed));
  }
  EXPECT_EQ(rig.module.model_seq(), 1u);
  EXPECT_EQ(rig.module.commits_accepted(), 1u);
}

TEST(FlashModel, InvalidBlobsAreRefusedLocallyOrByTheModule) {
  Rig rig;
  auto blob = test::make_test_blob(1);
  blob[100] ^= 0xFF;  // breaks the stored CRC
  try {
    flash_model(rig.session, blob, test::fake_module_key());
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("CRC"), std::string::npos) << e.what();
  }
  EXPECT_EQ(rig.module.commit_payloads().size(), 0u);  // nothing was sent
  FlashOptions fo;
  fo.validate_locally = false;
  try {
    flash_model(rig.session, blob, test::fake_module_key(), fo);
    FAIL();
  } catch (const NackError& e) {
    EXPECT_EQ(e.code(), static_cast<uint8_t>(wire::Nack::BlobCrc));
  }
  EXPECT_TRUE(rig.module.active_model().empty());
}

TEST(FlashModel, LoadsBinJsonHexAndJsonPath) {
  test::TempDir dir;
  const auto blob = test::make_test_blob(3);
  {
    std::ofstream(dir.path + "/m.bin", std::ios::binary).write(reinterpret_cast<const char*>(blob.data()),
                                                              static_cast<std::streamsize>(blob.size()));
    std::string hex;
    char b[3];
    for (uint8_t v : blob) {
      std::snprintf(b, sizeof b, "%02x", v);
      hex += b;
    }
    std::ofstream(dir.path + "/a.json") << "{\"blob_hex\": \"" << hex << "\", \"dt_ms\": 5000}";
    std::ofstream(dir.path + "/b.json") << "{\"blob_file\": \"m.bin\"}";
    std::ofstream(dir.path + "/c.json") << "{\"other\": 1}";
    std::ofstream(dir.path + "/d.json") << "{\"blob_hex\": \"0g\"}";
  }
  EXPECT_EQ(load_model_blob(dir.path + "/m.bin"), blob);
  EXPECT_EQ(load_model_blob(dir.path + "/a.json"), blob);
  EXPECT_EQ(load_model_blob(dir.path + "/b.json"), blob);
  EXPECT_THROW(load_model_blob(dir.path + "/c.json"), std::runtime_error);
  EXPECT_THROW(load_model_blob(dir.path + "/d.json"), std::runtime_error);
  EXPECT_THROW(load_model_blob(dir.path + "/missing.bin"), std::runtime_error);
  EXPECT_EQ(check_model_blob(blob), "");
  EXPECT_NE(check_model_blob(std::span<const uint8_t>(blob).first(100)), "");
}

TEST(FlashModel, BusyAnswersAreRetriedNotFatal) {
  FakeModuleOptions o;
  o.busy_every = 5;
  Rig rig(o);
  const auto blob = test::make_test_blob(5);
  EXPECT_TRUE(flash_model(rig.session, blob, test::fake_module_key()).verified);
  EXPECT_GT(rig.session.busy_answers(), 0u);
  EXPECT_EQ(rig.module.active_model(), blob);
}

// A blob of format version 1 (one state shared by all channels; tests/data/model-blob-v1) is
// refused before anything is sent, by a message that names its version and what to do.
TEST(FlashModel, VersionOneBlobIsRefusedNamingItsVersion) {
  const auto v1 = load_model_blob(std::string(BTSM_TEST_DATA_DIR) + "/model-blob-v1/spindle_v1.bin");
  ASSERT_EQ(v1.size(), 464u);
  const std::string why = check_model_blob(v1);
  EXPECT_NE(why.find("version 1"), std::string::npos) << why;
  EXPECT_NE(why.find("reduce"), std::string::npos) << why;
  Rig rig;
  try {
    flash_model(rig.session, v1, test::fake_module_key());
    FAIL() << "a version-1 blob was flashed";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("version 1"), std::string::npos) << e.what();
  }
  EXPECT_EQ(rig.module.commit_payloads().size(), 0u);
  EXPECT_TRUE(rig.module.active_model().empty());
}
