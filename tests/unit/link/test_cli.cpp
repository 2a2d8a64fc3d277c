// The link commands as a user runs them: a separate process (btsm_link_cli = main.cpp +
// cmd_link.cpp) against the in-process fake module on a pty, with HOME in a temp dir.
#include "fake_module.hpp"
#include "common/model_blob.hpp"
#include "common/device_key.hpp"
#include "host/link/firmware_image.hpp"
#include "host/sim/runner/sim_module.hpp"
#include "host/thermal/recording.hpp"
#include "cli_run.hpp"
#include "link_test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/stat.h>
#include <sys/wait.h>

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>
#include <chrono>
#include <algorithm>
#include <cctype>

using namespace btsm;
using btsm::test::FakeModule;

namespace {

using Result = test::CliResult;

// Runs the CLI with HOME=<home>, XDG_CONFIG_HOME unset, in this process group (ctest's timeout
// stops a hang).
Result run(const test::TempDir& home, const std::string& args, const std::string& cli = BTSM_CLI) {
  return test::run_cli(cli, home.path, args, 0);
}

struct ModuleOnPty {
  test::PtyPair pty;
  FakeModule module;
  explicit ModuleOnPty(test::FakeModuleOptions o = {}) : module(pty.release_master(), o) { module.start(); }
};

}  // namespace

TEST(LinkCli, EveryCommandHasHelp) {
  test::TempDir home;
  for (const char* c : {"list", "scan", "info", "monitor", "record", "set-speed", "set-config", "get-config", "ack-alarm",
                        "flash-model", "flash-firmware", "keys"}) {
    const Result r = run(home, std::string(c) + " --help");
    EXPECT_EQ(r.code, 0) << c << r.err;
    EXPECT_GT(r.out.size(), 200u) << c;
  }
  EXPECT_NE(run(home, "record --help").out.find("# dropped: a-b"), std::string::npos);
  EXPECT_NE(run(home, "set-config --help").out.find("sample_period_ms"), std::string::npos);
}

TEST(LinkCli, InfoRecordSetConfigAgainstTheFakeModule) {
  test::TempDir home;
  test::FakeModuleOptions o;
  o.sample_period = std::chrono::milliseconds(2);
  ModuleOnPty m(o);
  Result r = run(home, "info --json --port " + m.pty.path);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["device_id"], "0000de70");
  EXPECT_EQ(j["channel_roles"]["T4"], "ambient");

  r = run(home, "record --port " + m.pty.path + " --out " + home.path + "/rec.csv --samples 8 --json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["rows"], 8);
  EXPECT_EQ(thermal::read_recording_csv(home.path + "/rec.csv").rows(), 8u);

  r = run(home, "monitor --count 3 --json --port " + m.pty.path);
  ASSERT_EQ(r.code, 0) << r.err;
  std::istringstream lines(r.out);
  std::string line;
  int n = 0;
  while (std::getline(lines, line)) {
    EXPECT_TRUE(nlohmann::json::parse(line).contains("channels"));
    ++n;
  }
  EXPECT_EQ(n, 3);

  EXPECT_EQ(run(home, "set-speed 4500 --port " + m.pty.path).code, 0);
  EXPECT_EQ(m.module.speed(), 4500);
  r = run(home, "set-config sample_period_ms 10 --port " + m.pty.path);
  EXPECT_EQ(r.code, 2);  // refused before sending: outside [1000, 600000]
  EXPECT_NE(r.err.find("sample_period_ms"), std::string::npos);
  r = run(home, "set-config no_such_key 1 --port " + m.pty.path);
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(run(home, "set-config channel_role_5 shaft --port " + m.pty.path).code, 0);
  r = run(home, "set-config channel_role_5 spindle_nose --port " + m.pty.path);
  EXPECT_EQ(r.code, 2);  // not a role: the message lists the names
  EXPECT_NE(r.err.find("shaft"), std::string::npos) << r.err;
  EXPECT_EQ(run(home, "set-config channel_role_5 disabled --port " + m.pty.path).code, 0);
  r = run(home, "info --port /dev/nonexistent-btsm");
  EXPECT_EQ(r.code, 3);
  EXPECT_NE(r.err.find("/dev/nonexistent-btsm"), std::string::npos);
}

// The module's channel roles travel with the recording: `fit` places the probes by them (here the
// fifth probe becomes the shaft node's) and says so, before it fits.
TEST(LinkCli, FitTakesTheProbesFromTheRecordedChannelRoles) {
  test::TempDir home;
  test::FakeModuleOptions o;
  o.sample_period = std::chrono::milliseconds(2);
  ModuleOnPty m(o);
  ASSERT_EQ(run(home, "set-config channel_role_5 shaft --port " + m.pty.path).code, 0);
  Result r = run(home, "record --port " + m.pty.path + " --out " + home.path + "/rec.csv --samples 4");
  ASSERT_EQ(r.code, 0) << r.err;
  std::ifstream rec(home.path + "/rec.csv");
  std::stringstream text;
  text << rec.rdbuf();
  EXPECT_NE(text.str().find("T5=shaft"), std::string::npos) << text.str();
  r = run(home, "fit " + home.path + "/rec.csv --preset spindle4 --sum-c 20478.7 --out " + home.path + "/m.json", BTSM_CLI);
  EXPECT_NE(r.err.find("from the recordings' channel roles:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("shaft=T5"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("no column 'T4'"), std::string::npos) << r.err;  // the preset's default column is gone
}

TEST(LinkCli, KeysAndFlashModel) {
  test::TempDir home;
  ModuleOnPty m;
  const auto blob = test::make_test_blob(1);
  std::ofstream(home.path + "/model.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(blob.data()), static_cast<std::streamsize>(blob.size()));
  // No key yet: a clear error naming the command that creates one.
  Result r = run(home, "flash-model --port " + m.pty.path + " " + home.path + "/model.bin");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("btsm keys"), std::string::npos) << r.err;
  // The development key of the fake module.
  std::string dev;
  for (int i = 0; i < 32; ++i) dev += fmt::format("{:02x}", i);
  ASSERT_EQ(run(home, "keys import 0000de70 " + dev).code, 0);
  const std::string keyfile = home.path + "/.config/btsm/keys/0000de70.key";
  struct stat st {};
  ASSERT_EQ(::stat(keyfile.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  EXPECT_NE(run(home, "keys list").out.find("0000de70"), std::string::npos);
  r = run(home, "flash-model --json --port " + m.pty.path + " " + home.path + "/model.bin");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(nlohmann::json::parse(r.out)["verified"].get<bool>());
  EXPECT_EQ(m.module.active_model(), blob);
  // An exposed key is refused.
  ::chmod(keyfile.c_str(), 0644);
  r = run(home, "flash-model --port " + m.pty.path + " " + home.path + "/model.bin");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("chmod 600"), std::string::npos) << r.err;
  // ... and `keys list` says so instead of listing it as a key.
  r = run(home, "keys list");
  EXPECT_NE(r.out.find("0000de70"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("UNUSABLE"), std::string::npos) << r.out;
  EXPECT_FALSE(nlohmann::json::parse(run(home, "keys list --json").out)[0]["usable"].get<bool>());
}

// A role change that leaves the active model behind was acknowledged without a word, and the
// module then showed NORMAL without predicting (probe 5): set-config says it as `info` does.
// Disabling the last channel in use silenced the module (monitor blamed the link): refused.
TEST(LinkCli, SetConfigWarnsWhenARoleChangeVoidsTheActiveModel) {
  test::TempDir home;
  ModuleOnPty m;
  const auto blob = test::make_test_blob(1);  // ambient on ch4, ch5 not modelled
  std::ofstream(home.path + "/model.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(blob.data()), static_cast<std::streamsize>(blob.size()));
  std::string dev;
  for (int i = 0; i < 32; ++i) dev += fmt::format("{:02x}", i);
  ASSERT_EQ(run(home, "keys import 0000de70 " + dev).code, 0);
  Result r = run(home, "flash-model --port " + m.pty.path + " " + home.path + "/model.bin");
  ASSERT_EQ(r.code, 0) << r.err;
  r = run(home, "set-config channel_role_5 shaft --port " + m.pty.path);  // a channel the model leaves alone
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err.find("WARNING"), std::string::npos) << r.err;
  r = run(home, "set-config channel_role_4 disabled --port " + m.pty.path);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("WARNING: the active model no longer fits the roles: the model takes its ambient from ch4"),
            std::string::npos)
      << r.err;
  for (const char* ch : {"1", "2", "3"}) ASSERT_EQ(run(home, std::string("set-config channel_role_") + ch + " disabled --port " + m.pty.path).code, 0);
  r = run(home, "set-config channel_role_5 disabled --port " + m.pty.path);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("would disable the last channel in use"), std::string::npos) << r.err;
  EXPECT_EQ(run(home, "get-config channel_role_5 --port " + m.pty.path).out, "channel_role_5         shaft\n");
}

// A README block pasted whole ran `set-config --port /tmp/btsm-sim` before the `sim-module &` of
// the line before had made its link: exit 3, and the block went on with the wrong recordings.
// A port that appears a moment later is waited for.
TEST(LinkCli, APortThatAppearsAMomentLaterIsWaitedFor) {
  test::TempDir home;
  ModuleOnPty m;
  const std::string late = home.path + "/late-link";
  std::thread maker([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(800));
    ASSERT_EQ(::symlink(m.pty.path.c_str(), late.c_str()), 0);
  });
  const Result r = run(home, "info --port " + late);
  maker.join();
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("0000de70"), std::string::npos) << r.out;
}

std::string dev_key_hex() {
  std::string dev;
  for (int i = 0; i < 32; ++i) dev += fmt::format("{:02x}", i);
  return dev;
}

// flash-model's own inputs: a JSON naming a device as its blob file, hex that is not hex or has
// an odd number of digits, a JSON without a blob, key files with bad content. Each is bad input,
// exit 2 (they were 1; /dev/zero never returned), refused before a byte goes to the module.
TEST(LinkCli, FlashModelBadInputIsExitTwoAndFast) {
  test::TempDir home;
  ModuleOnPty m;
  ASSERT_EQ(run(home, "keys import 0000de70 " + dev_key_hex()).code, 0);
  const auto blob = test::make_test_blob(1);
  std::string blob_hex;
  for (uint8_t b : blob) blob_hex += fmt::format("{:02x}", b);
  std::ofstream(home.path + "/zero.json") << R"({"blob_file": "/dev/zero"})";
  std::ofstream(home.path + "/nonhex.json") << R"({"blob_hex": ")" << blob_hex.substr(0, 100) << "zz" << blob_hex.substr(102) << R"("})";
  std::ofstream(home.path + "/odd.json") << R"({"blob_hex": ")" << blob_hex.substr(1) << R"("})";
  std::ofstream(home.path + "/noblob.json") << R"({"dt_ms": 5000})";
  std::ofstream(home.path + "/ok.json") << R"({"blob_hex": ")" << blob_hex << R"("})";
  const std::string cli = std::string("timeout -s KILL 20 ") + BTSM_CLI;
  for (const char* f : {"zero.json", "nonhex.json", "odd.json", "noblob.json", "/dev/zero"}) {
    const std::string path = f[0] == '/' ? f : home.path + "/" + f;
    const Result r = run(home, "flash-model --port " + m.pty.path + " " + path, cli);
    EXPECT_EQ(r.code, 2) << f << "\n" << r.err;
  }
  EXPECT_NE(run(home, "flash-model --port " + m.pty.path + " " + home.path + "/nonhex.json", cli).err.find("'z' at character 101"),
            std::string::npos);
  // Key files with bad content, each the right name and mode.
  const std::string keydir = home.path + "/other";
  ::mkdir(keydir.c_str(), 0700);
  const std::string keyfile = keydir + "/0000de70.key";
  for (const std::string& content : {std::string("not a key\n"), dev_key_hex().substr(2) + "\n", dev_key_hex() + "00\n",
                                     dev_key_hex() + "\n" + std::string(5000, ' ')}) {
    std::ofstream(keyfile, std::ios::trunc) << content;
    ::chmod(keyfile.c_str(), 0600);
    const Result r = run(home, "flash-model --port " + m.pty.path + " --key-file " + keyfile + " " + home.path + "/ok.json", cli);
    EXPECT_EQ(r.code, 2) << content.substr(0, 20) << "\n" << r.err;
    EXPECT_NE(r.err.find(keyfile), std::string::npos) << r.err;
  }
  EXPECT_TRUE(m.module.active_model().empty());
  EXPECT_EQ(m.module.staged_bytes(), 0u);
  // The good JSON with the good key file goes through.
  std::ofstream(keyfile, std::ios::trunc) << dev_key_hex() << "\n";
  const Result ok = run(home, "flash-model --port " + m.pty.path + " --key-file " + keyfile + " " + home.path + "/ok.json", cli);
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_EQ(m.module.active_model(), blob);
}

// The link lost once MODEL_COMMIT is sent: exit 3 as for any lost link, but the message says the
// outcome is unknown and how to check it -- the module did take the model.
TEST(LinkCli, FlashModelLinkLostAtTheCommitSaysHowToCheck) {
  test::TempDir home;
  test::FakeModuleOptions o;
  o.hang_up = test::FakeModuleOptions::HangUp::kBeforeCommitAck;
  ModuleOnPty m(o);
  ASSERT_EQ(run(home, "keys import 0000de70 " + dev_key_hex()).code, 0);
  const auto blob = test::make_test_blob(2);
  std::ofstream(home.path + "/model.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(blob.data()), static_cast<std::streamsize>(blob.size()));
  const Result r = run(home, "flash-model --timeout 0.5 --port " + m.pty.path + " " + home.path + "/model.bin");
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find("unknown"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("btsm info"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(fmt::format("{:08x}", blob_stored_crc(blob.data()))), std::string::npos) << r.err;
  EXPECT_EQ(m.module.model_seq(), 1u);
}

// An image with data in Optiboot's 512 bytes (or past the 32 KiB part) was patched and handed to
// avrdude; it is refused naming the first such address, and nothing is written.
TEST(LinkCli, FlashFirmwareRefusesDataAtOrAboveTheBootloader) {
  test::TempDir home;
  for (const uint32_t at : {0x7E00u, 0x8000u}) {
    link::HexImage img;
    for (uint32_t a = 0; a < 256; ++a) img.bytes[a] = static_cast<uint8_t>(a);
    for (uint32_t a = 0; a < device_key::kRecordSize; ++a) img.bytes[device_key::kFlashAddress + a] = 0xFF;
    img.bytes[at] = 0x12;
    std::ofstream(home.path + "/fw.hex") << link::format_intel_hex(img);
    const Result r = run(home, "flash-firmware --device-id 0000de71 --new-key --hex " + home.path + "/fw.hex --out " +
                                   home.path + "/p.hex --dry-run --port /dev/ttyACM9");
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find(fmt::format("data at 0x{:04X}", at)), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("bootloader"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(home.path + "/p.hex"));
  }
}

TEST(LinkCli, FlashFirmwareDryRunPatchesTheKey) {
  test::TempDir home;
  link::HexImage img;
  for (uint32_t a = 0; a < 256; ++a) img.bytes[a] = static_cast<uint8_t>(a);
  for (uint32_t a = 0; a < device_key::kRecordSize; ++a) img.bytes[device_key::kFlashAddress + a] = 0xFF;
  std::ofstream(home.path + "/fw.hex") << link::format_intel_hex(img);
  Result r = run(home, "flash-firmware --device-id 0000de71 --hex " + home.path + "/fw.hex --out " + home.path +
                           "/p.hex --dry-run --port /dev/ttyACM9");
  EXPECT_EQ(r.code, 2);  // no key and no --new-key
  // A dry run changes nothing in the key store: --new-key says what it would do, stores no key
  // and writes no image patched with a key nobody keeps.
  r = run(home, "flash-firmware --device-id 0000de71 --new-key --hex " + home.path + "/fw.hex --out " + home.path +
                    "/p.hex --dry-run --port /dev/ttyACM9");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out, "avrdude -p atmega328p -c arduino -b 115200 -P /dev/ttyACM9 -D -U flash:w:" + home.path +
                       "/p.hex:i\n");
  EXPECT_NE(r.err.find("dry run: would generate and store a key"), std::string::npos) << r.err;
  EXPECT_EQ(run(home, "keys list").out, "");
  EXPECT_NE(run(home, "keys show 0000de71").code, 0);
  EXPECT_FALSE(std::filesystem::exists(home.path + "/p.hex"));
  // With a stored key the dry run writes the patched image (and still stores nothing new).
  r = run(home, "flash-firmware --device-id 0000de71 --new-key --hex " + home.path + "/fw.hex --out " + home.path +
                    "/p.hex --port /dev/ttyACM9 --avrdude /bin/true");
  ASSERT_EQ(r.code, 0) << r.err;  // the real run stores the key (avrdude replaced by true)
  const std::string stored = run(home, "keys show 0000de71").out;
  std::filesystem::remove(home.path + "/p.hex");
  r = run(home, "flash-firmware --device-id 0000de71 --new-key --hex " + home.path + "/fw.hex --out " + home.path +
                    "/p.hex --dry-run --port /dev/ttyACM9");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(run(home, "keys show 0000de71").out, stored);
  struct stat st {};
  ASSERT_EQ(::stat((home.path + "/p.hex").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);  // it holds the key
  const auto rec = link::read_device_key(link::read_intel_hex(home.path + "/p.hex"));
  ASSERT_TRUE(rec);
  EXPECT_EQ(rec->device_id, 0xDE71u);
  EXPECT_EQ(run(home, "keys show 0000de71").out, link::key_to_hex(rec->key) + "\n");
  r = run(home, "flash-firmware --device-id 0000de71 --dry-run --ble C8:A0:30:F1:02:03 --hex " + home.path + "/fw.hex --out " +
                    home.path + "/q.hex");
  EXPECT_EQ(r.code, 3);
  EXPECT_NE(r.err.find("USB"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(home.path + "/q.hex"));  // the keyed image was written before the refusal
  // A regular file as the port went to avrdude; an image given with --hex gets no "build it" hint.
  std::ofstream(home.path + "/not_a_tty") << "x\n";
  r = run(home, "flash-firmware --device-id 0000de71 --hex " + home.path + "/fw.hex --out " + home.path + "/q.hex --port " +
                    home.path + "/not_a_tty --avrdude /bin/true");
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find("not a serial device"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(home.path + "/q.hex"));
  r = run(home, "flash-firmware --device-id 0000de71 --hex " + home.path + "/fw.hex --out " + home.path +
                    "/q.hex --port /dev/null --avrdude /bin/true");  // a character device, but no tty
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_FALSE(std::filesystem::exists(home.path + "/q.hex"));
  std::ofstream(home.path + "/eof_data.hex") << ":0200000101FFFD\n";
  r = run(home, "flash-firmware --device-id 0000de71 --hex " + home.path + "/eof_data.hex --out " + home.path +
                    "/q.hex --dry-run");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("end-of-file record with 2 data bytes"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("build it"), std::string::npos) << r.err;
}

TEST(LinkCli, ScanSaysListeningOnlyWhenAnAdapterScans) {
  test::TempDir home;
  const Result r = run(home, "scan --seconds 0.5");
  if (r.code != 0) {
    // No adapter (or no permission): the error, and no claim to be listening before it.
    EXPECT_EQ(r.code, 3) << r.err;
    EXPECT_EQ(r.err.find("listening"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("BLE scan"), std::string::npos) << r.err;
  } else {
    EXPECT_NE(r.err.find("listening for 0.5 s on hci"), std::string::npos) << r.err;
  }
}

namespace {

// Runs the CLI on a thread; the test watches its stderr file while it runs.
struct Background {
  test::TempDir& home;
  Result result;
  std::thread thread;
  Background(test::TempDir& h, const std::string& args) : home(h) {
    thread = std::thread([this, args] { result = run(home, args); });
  }
  ~Background() {
    if (thread.joinable()) thread.join();
  }
  std::string err() const { return test::read_text(home.path + "/" + test::kCliStderr); }
  std::string out() const { return test::read_text(home.path + "/" + test::kCliStdout); }
  // Seconds until `text` appears on stderr, or a negative value after `limit_s`.
  double seconds_until(const std::string& text, double limit_s) const {
    const auto t0 = std::chrono::steady_clock::now();
    for (;;) {
      const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (err().find(text) != std::string::npos) return dt;
      if (dt > limit_s) return -1;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  Result finish() {
    thread.join();
    return result;
  }
};

bool wait_for_samples(const FakeModule& m, uint32_t n, double limit_s) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(limit_s);
  while (m.samples_sent() < n) {
    if (std::chrono::steady_clock::now() > until) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

}  // namespace

TEST(LinkCli, MonitorLinesCarryTheTimeAndALostLinkIsSaidAtOnce) {
  test::TempDir home;
  test::FakeModuleOptions o;
  o.sample_period = std::chrono::milliseconds(20);
  ModuleOnPty m(o);
  Background mon(home, "monitor --port " + m.pty.path + " --timeout 1 --reconnect 2");
  ASSERT_GT(mon.seconds_until("monitor: module", 10), -1) << mon.err();
  const uint32_t before = m.module.samples_sent();
  ASSERT_TRUE(wait_for_samples(m.module, before + 10, 5));
  m.module.replace_fd(-1);  // the module's end of the link closes (BLE drop, cable pulled)
  const double said_after = mon.seconds_until("link lost", 5);
  ASSERT_GE(said_after, 0) << mon.err();
  EXPECT_LT(said_after, 1.0) << "the lost link must be said within the reply timeout";
  EXPECT_NE(mon.err().find("reconnecting for up to 2 s"), std::string::npos) << mon.err();
  const Result r = mon.finish();
  EXPECT_EQ(r.code, 3) << r.err;  // not back within --reconnect
  // Every sample line starts with the host's time of day and the module's time.
  std::istringstream lines(r.out);
  std::string line;
  int n = 0;
  while (std::getline(lines, line)) {
    ++n;
    ASSERT_GE(line.size(), 12u);
    EXPECT_TRUE(std::isdigit(line[0]) && std::isdigit(line[1]) && line[2] == ':' && line[5] == ':' && line[8] == ' ')
        << line;
    EXPECT_EQ(line.substr(9, 2), "t=") << line;
  }
  EXPECT_GE(n, 10);
}

TEST(LinkCli, MonitorSaysWhenTheStreamGoesSilentAndWhenItIsBack) {
  test::TempDir home;
  test::FakeModuleOptions o;
  o.sample_period = std::chrono::milliseconds(20);
  ModuleOnPty m(o);
  Background mon(home, "monitor --port " + m.pty.path + " --timeout 0.5 --count 120");
  ASSERT_GT(mon.seconds_until("monitor: module", 10), -1) << mon.err();
  ASSERT_TRUE(wait_for_samples(m.module, m.module.samples_sent() + 20, 5));
  m.module.set_streaming(false);  // silent link: no disconnect, no data
  const double said_after = mon.seconds_until("no sample for", 5);
  ASSERT_GE(said_after, 0) << mon.err();
  // One configured sample period (the fake reports 1 s, the least a module may have, while it
  // streams every 20 ms), not the host's arrival rate, plus the reply timeout (and polling slack).
  EXPECT_LT(said_after, 1.0 + 0.5 + 0.5) << "one interval plus the reply timeout (and polling slack)";
  EXPECT_NE(mon.err().find("(one expected every 1 s, the module's sample period)"), std::string::npos) << mon.err();
  m.module.set_streaming(true);
  EXPECT_GE(mon.seconds_until("samples again", 5), 0) << mon.err();
  const Result r = mon.finish();
  EXPECT_EQ(r.code, 0) << r.err;
}

// A link that stays lost past --reconnect ends `record` with exit 3; the rows written stay and the
// closing summary lines follow them, with the reason. The README's `record` section said the
// summary was missing after a link loss; it must say what the file holds.
TEST(LinkCli, RecordLinkLostKeepsRowsAndSummaryAsTheReadmeSays) {
  test::TempDir home;
  test::FakeModuleOptions o;
  o.sample_period = std::chrono::milliseconds(20);
  ModuleOnPty m(o);
  const std::string csv = home.path + "/rec.csv";
  Background rec(home, "record --port " + m.pty.path + " --out " + csv + " --timeout 0.5 --reconnect 1");
  ASSERT_GT(rec.seconds_until("record: module", 10), -1) << rec.err();
  ASSERT_TRUE(wait_for_samples(m.module, m.module.samples_sent() + 20, 5));
  m.module.replace_fd(-1);  // the module's end of the link closes and stays closed
  const Result r = rec.finish();
  EXPECT_EQ(r.code, 3) << r.err;
  const thermal::Recording file = thermal::read_recording_csv(csv);
  EXPECT_GE(file.rows(), 10u);
  EXPECT_EQ(file.meta_value("stop_reason").rfind("link lost: ", 0), 0u) << file.meta_value("stop_reason");
  EXPECT_EQ(file.meta_value("samples"), std::to_string(file.rows()));
  EXPECT_FALSE(file.meta_value("lost_samples").empty());
  const std::string readme = test::read_text(BTSM_README);
  const size_t from = readme.find("\n### Record\n");
  ASSERT_NE(from, std::string::npos);
  const std::string section = readme.substr(from, readme.find("\n### ", from + 1) - from);
  EXPECT_EQ(section.find("without the closing summary"), std::string::npos) << section;
  EXPECT_NE(section.find("followed by the closing summary lines"), std::string::npos) << section;
  EXPECT_NE(section.find("`# stop_reason: link lost: …`"), std::string::npos) << section;
}

TEST(LinkCli, GetConfigReadsWhatSetConfigWroteOnTheSimulatedModule) {
  test::TempDir home;
  sim::SimModuleOptions o;
  o.pty_path = home.path + "/btsm-sim";
  o.plant.speed = sim::SpeedProfile::parse("1h@6000");
  sim::SimModule sim(o);
  sim.start();
  const std::string port = " --port " + o.pty_path;
  Result r = run(home, "get-config" + port);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("sample_period_ms       5000\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("channel_role_5         spare\n"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 12) << r.out;  // every key the protocol names
  ASSERT_EQ(run(home, "set-config" + port + " channel_role_5 shaft").code, 0);
  ASSERT_EQ(run(home, "set-config" + port + " sample_period_ms 2000").code, 0);
  r = run(home, "get-config --json" + port + " channel_role_5 sample_period_ms");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["channel_role_5"], "shaft");
  EXPECT_EQ(j["sample_period_ms"], 2000);
  EXPECT_EQ(j.size(), 2u);
  r = run(home, "get-config" + port + " no_such_key");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("no_such_key"), std::string::npos) << r.err;
  // A second ambient was acknowledged silently, and every recording after it was refused by the
  // readers: set-config warns (a swap of two probes passes through such a moment), record refuses.
  r = run(home, "set-config" + port + " channel_role_2 ambient");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("WARNING: channel 4 has the role ambient too"), std::string::npos) << r.err;
  r = run(home, "record" + port + " --out " + home.path + "/two_ambients.csv --samples 3");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("channels 2 and 4 both have the role ambient"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(home.path + "/two_ambients.csv"));
  r = run(home, "set-config" + port + " channel_role_2 housing");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err.find("WARNING"), std::string::npos) << r.err;
  sim.stop();
  EXPECT_TRUE(sim.error().empty()) << sim.error();
}
