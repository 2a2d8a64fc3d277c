// Model upload against the fake module: round trip with read-back, 20-byte chunk frames,
// wrong key (refused before any chunk), firmware without MODEL_AUTH, replayed commit, invalid
// blobs, blob file formats, the link lost at the commit.
#include "common/crc.hpp"
#include "common/model_blob.hpp"
#include "fake_module.hpp"
#include "host/link/model_flash.hpp"
#include "host/link/serial_transport.hpp"
#include "link_test_support.hpp"
#include "module_on_pty.hpp"

#include <gtest/gtest.h>

#include <fmt/format.h>

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
  const uint64_t staged = rig.module.staged_bytes();
  DeviceKey wrong = test::fake_module_key();
  wrong[5] ^= 0x01;
  try {
    flash_model(rig.session, test::make_test_blob(2), wrong);
    FAIL() << "expected AUTH_FAILED";
  } catch (const NackError& e) {
    EXPECT_EQ(e.code(), static_cast<uint8_t>(wire::Nack::AuthFailed));
    EXPECT_EQ(e.request_type(), wire::type_code(wire::MsgType::ModelAuth)) << "refused at MODEL_AUTH, before any chunk";
    EXPECT_NE(std::string(e.what()).find("AUTH_FAILED"), std::string::npos);
  }
  EXPECT_EQ(rig.module.staged_bytes(), staged);
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
  // 2. A fresh session with the same blob: without the key the chunks are refused, the recorded
  //    tag is no MODEL_AUTH tag for the new nonce, and the replayed commit finds no session.
  const auto ch = rig.session.model_begin(static_cast<uint16_t>(blob_a.size()), crc32(blob_a.data(), blob_a.size()));
  (void)ch;
  auto expect_nack = [&](wire::MsgType type, std::span<const uint8_t> payload, wire::Nack code) {
    try {
      rig.session.request(type, payload, std::nullopt);
      FAIL() << wire::msg_type_name(wire::type_code(type));
    } catch (const NackError& e) {
      EXPECT_EQ(e.code(), static_cast<uint8_t>(code)) << wire::msg_type_name(wire::type_code(type));
    }
  };
  std::vector<uint8_t> chunk = {0, 0};
  chunk.insert(chunk.end(), blob_a.begin(), blob_a.begin() + 10);
  expect_nack(wire::MsgType::ModelChunk, chunk, wire::Nack::NoSession);
  expect_nack(wire::MsgType::ModelAuth, captured, wire::Nack::AuthFailed);
  expect_nack(wire::MsgType::ModelCommit, captured, wire::Nack::NoSession);
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
  // Bad input is an io::InputError, a std::invalid_argument: the CLI's exit code 2.
  EXPECT_THROW(load_model_blob(dir.path + "/c.json"), std::invalid_argument);
  EXPECT_THROW(load_model_blob(dir.path + "/d.json"), std::invalid_argument);
  EXPECT_THROW(load_model_blob(dir.path + "/missing.bin"), std::invalid_argument);
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

TEST(FlashModel, FirmwareWithoutModelAuthIsNamedAndGetsNoChunk) {
  FakeModuleOptions o;
  o.legacy_upload = true;
  Rig rig(o);
  try {
    flash_model(rig.session, test::make_test_blob(1), test::fake_module_key());
    FAIL() << "an older firmware must be refused";
  } catch (const LinkError& e) {
    EXPECT_EQ(e.kind(), LinkErrorKind::kProtocol);
    const std::string m = e.what();
    EXPECT_NE(m.find("MODEL_AUTH"), std::string::npos) << m;
    EXPECT_NE(m.find("flash-firmware"), std::string::npos) << m;
  }
  EXPECT_EQ(rig.module.staged_bytes(), 0u);
  EXPECT_TRUE(rig.module.active_model().empty());
}

// The link dies at the commit: the error says what is known (acknowledged or not), that the
// outcome is otherwise unknown, and which INFO values show the new model.
TEST(FlashModel, LinkLostAtTheCommitSaysWhatIsKnownAndHowToCheck) {
  using HangUp = FakeModuleOptions::HangUp;
  for (const HangUp h : {HangUp::kBeforeCommitAck, HangUp::kAfterCommitAck}) {
    SCOPED_TRACE(h == HangUp::kBeforeCommitAck ? "before the commit ACK" : "after the commit ACK");
    FakeModuleOptions o;
    o.hang_up = h;
    Rig rig(o);
    const auto blob = test::make_test_blob(4);
    const std::string crc = fmt::format("{:08x}", blob_stored_crc(blob.data()));
    try {
      flash_model(rig.session, blob, test::fake_module_key());
      FAIL() << "the link was lost";
    } catch (const NackError& e) {
      FAIL() << "a NACK instead of the lost link: " << e.what();
    } catch (const LinkError& e) {
      const std::string m = e.what();
      EXPECT_NE(e.kind(), LinkErrorKind::kProtocol) << m;  // still "link lost" for the exit code
      EXPECT_NE(m.find("btsm info"), std::string::npos) << m;
      EXPECT_NE(m.find(crc), std::string::npos) << m;
      if (h == HangUp::kBeforeCommitAck)
        EXPECT_NE(m.find("unknown"), std::string::npos) << m;
      else
        EXPECT_NE(m.find("accepted the commit"), std::string::npos) << m;
    }
    EXPECT_EQ(rig.module.model_seq(), 1u);  // the module did take the model both times
  }
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

// A model without an ambient channel predicts nothing: the module showed NORMAL on every sample
// and a 30 W bearing fault never ALARMed (probe 5). flash-model refuses it (a conflict) and `info`
// names it; a model with its ambient passes.
TEST(FlashModel, AModelWithoutAnAmbientChannelIsAConflict) {
  const auto role = [](wire::ChannelRole r) { return static_cast<uint8_t>(r); };
  const uint8_t module[5] = {role(wire::ChannelRole::RearBearing), role(wire::ChannelRole::Housing),
                             role(wire::ChannelRole::FrontBearing), role(wire::ChannelRole::Ambient),
                             role(wire::ChannelRole::Shaft)};
  const uint8_t no_ambient[5] = {module[0], module[1], module[2], kModelRoleNotModelled, module[4]};
  const ChannelMapCheck bad = check_channel_map(no_ambient, module);
  ASSERT_EQ(bad.conflicts.size(), 1u);
  EXPECT_NE(bad.conflicts[0].find("the model has no ambient channel"), std::string::npos) << bad.conflicts[0];
  const uint8_t with_ambient[5] = {module[0], module[1], module[2], kModelRoleAmbient, module[4]};
  EXPECT_TRUE(check_channel_map(with_ambient, module).ok());
}
