// Output places, from hostile-input probe 7: named pipes in the key store and as outputs hung
// `keys`, `record`, `sim-module --truth-out`, `flash-firmware --out` and the plot writers for ever
// (F1); outputs that cannot be written were found after the whole run, with exit 1 (F3); a failed
// `reduce --blob` had already replaced the `--out` JSON (F4). Every child runs under a time limit,
// and the library checks of a writer run in a child killed by alarm(): a writer that waits on a
// named pipe again fails its test instead of hanging the suite.
#include "cli_run.hpp"
#include "model_fixture.hpp"
#include "refusals.hpp"

#include "host/io/output_file.hpp"
#include "host/thermal/recording.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>

namespace btsm::test {
namespace {

namespace fs = std::filesystem;

bool mentions(const CliResult& r, const std::string& s) { return r.err.find(s) != std::string::npos; }

void make_fifo(const std::string& path) { ASSERT_EQ(::mkfifo(path.c_str(), 0600), 0) << path; }

bool is_fifo(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && S_ISFIFO(st.st_mode);
}

// No temporary file of the beside-and-rename writer is left in `dir`.
void expect_no_temporaries(const std::string& dir) {
  for (const auto& e : fs::recursive_directory_iterator(dir))
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
}

// The spindle4 model and a 200-row recording in `d`, as model.json, rec.csv and check.csv.
void write_model_and_recordings(const ScratchDir& d) {
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("rec.csv"), recording_csv(200));
  write_text(d.file("check.csv"), recording_csv(150));
}

// A named pipe in the key store (probe 7 F1): `keys list` printed nothing and waited for ever in
// open(), `keys show` and `keys generate --force` too. Now the pipe is listed as UNUSABLE with the
// reason, next to the good key, and show / generate refuse it at once.
TEST(OutputPlaces, ANamedPipeInTheKeyStoreIsListedUnusableNotWaitedOn) {
  ScratchDir d;
  ASSERT_EQ(run_btsm(d, "keys generate 0000abcd", 20).code, 0);
  const std::string pipe = d.file(".config/btsm/keys/0000eeee.key");
  make_fifo(pipe);

  const CliResult list = run_btsm(d, "keys list", 20);
  ASSERT_EQ(list.code, 0) << list.err;
  EXPECT_NE(list.out.find("0000abcd  " + d.file(".config/btsm/keys/0000abcd.key") + "\n"), std::string::npos) << list.out;
  EXPECT_NE(list.out.find("0000eeee  " + pipe + "  UNUSABLE: key file " + pipe + " is a named pipe, not a regular file"),
            std::string::npos)
      << list.out;

  const CliResult json = run_btsm(d, "keys list --json", 20);
  ASSERT_EQ(json.code, 0) << json.err;
  const nlohmann::json keys = nlohmann::json::parse(json.out);
  ASSERT_EQ(keys.size(), 2u) << json.out;
  EXPECT_TRUE(keys[0]["usable"].get<bool>());
  EXPECT_FALSE(keys[1]["usable"].get<bool>());
  EXPECT_NE(keys[1]["problem"].get<std::string>().find("named pipe"), std::string::npos) << json.out;

  expect_refusals(d, {{"keys show 0000eeee", "key file " + pipe + " is a named pipe, not a regular file"},
                      {"keys generate 0000eeee --force", "key file " + pipe + " is a named pipe, not a file to write the key to"}},
                  2, 20);
  EXPECT_TRUE(is_fifo(pipe));
}

// Every output a command writes, given as a named pipe no program reads (probe 7 F1): record
// connected and then blocked holding the module's link, sim-module and flash-firmware blocked
// silently, validate and heat blocked on a plot after writing the CSVs. Each is refused before
// any work (nothing read, no port opened), naming the pipe and what would have gone into it;
// the pipe stays.
TEST(OutputPlaces, AnOutputThatIsANamedPipeIsRefusedBeforeTheWork) {
  ScratchDir d;
  write_model_and_recordings(d);
  for (const char* name : {"fifo.csv", "fifo.json", "fifo.bin"}) make_fifo(d.file(name));
  fs::create_directories(d.file("plots"));
  make_fifo(d.file("plots/validate_rec.svg"));
  fs::create_directories(d.file("h"));
  make_fifo(d.file("h/heat_sources.png"));
  fs::create_directories(d.file("rep"));
  make_fifo(d.file("rep/residual_model.svg"));

  expect_refusals(
      d,
      {{"record --port /nonexistent/tty --out fifo.csv --samples 3", "--out fifo.csv: a named pipe, not a file to write the recording to"},
       {"sim-module --no-wait --duration 10s --pty p --truth-out fifo.csv", "--truth-out fifo.csv: a named pipe, not a file to write the truth CSV to"},
       {"flash-firmware --device-id 0000de71 --new-key --dry-run --out fifo.csv",
        "--out fifo.csv: a named pipe, not a file to write the patched firmware image to"},
       {"fit rec.csv --preset spindle4 --sum-c 20478.7 --out fifo.json", "--out fifo.json: a named pipe, not a file to write the model JSON to"},
       {"reduce model.json --speeds 4000,6000 --force --out r.json --blob fifo.bin",
        "--blob fifo.bin: a named pipe, not a file to write the model blob to"},
       {"validate model.json rec.csv --plots plots", "--plots plots: plots/validate_rec.svg is a named pipe, not a file to write the plot to"},
       {"heat model.json rec.csv --out h", "--out h: h/heat_sources.png is a named pipe, not a file to write the plot to"},
       {"residual --preset spindle4 --fit rec.csv --check check.csv --report rep",
        "--report rep: rep/residual_model.svg is a named pipe, not a file to write the plot to"}},
      2, 30);
  for (const char* name : {"fifo.csv", "fifo.json", "fifo.bin", "plots/validate_rec.svg", "h/heat_sources.png", "rep/residual_model.svg"})
    EXPECT_TRUE(is_fifo(d.file(name))) << name;
  EXPECT_FALSE(file_exists(d.file("r.json")));  // reduce wrote neither output
  EXPECT_FALSE(file_exists(d.file("h/heat_sources.csv")));  // heat wrote nothing before the plot
}

// Outputs that cannot be written (probe 7 F3): fit and reduce ran to the end (minutes on real
// data) and then failed with exit 1 ("No such file or directory" for /proc/version); validate
// --plots FILE and effect-suite --out FILE gave a raw std::filesystem error; heat, validate and
// residual into a place that takes no file failed after their work. Each is exit 2 before the work
// (no recording read), naming the option, the path and why. As root, /proc stands for the
// unwritable directory: root passes every permission bit.
TEST(OutputPlaces, AnOutputPlaceThatCannotBeWrittenIsRefusedBeforeTheWork) {
  ScratchDir d;
  write_model_and_recordings(d);
  fs::create_directories(d.file("adir"));
  const std::string fit = "fit rec.csv --preset spindle4 --sum-c 20478.7 ";
  const std::string reduce = "reduce model.json --speeds 4000,6000 --force ";
  const Refusal cases[] = {
      {fit + "--out nodir/sub/o.json", "--out nodir/sub/o.json: its directory nodir/sub does not exist"},
      {fit + "--out /proc/version", "--out /proc/version: no file can be created in its directory /proc"},
      {fit + "--out adir", "--out adir: a directory, not a file to write the model JSON to"},
      {fit + "--out rec.csv/o.json", "--out rec.csv/o.json: rec.csv is not a directory"},
      {fit + "--out /dev/null", "--out /dev/null: a character device, not a file to write the model JSON to"},
      {fit + "--out -", "--out -: stdout is no output file here"},
      {fit + "--out /dev/stdout", "--out /dev/stdout: stdout is no output file here"},
      {reduce + "--out nodir/x.json", "--out nodir/x.json: its directory nodir does not exist"},
      {reduce + "--out r.json --blob /dev/full", "--blob /dev/full: a character device, not a file to write the model blob to"},
      {"validate model.json rec.csv --plots model.json", "--plots model.json: exists and is not a directory"},
      {"validate model.json rec.csv --plots model.json/sub", "--plots model.json/sub: model.json is not a directory"},
      {"validate model.json rec.csv --plots /proc/plots", "--plots /proc/plots: it cannot be made in /proc"},
      {"heat model.json rec.csv --out /proc/h/sub", "--out /proc/h/sub: it cannot be made in /proc"},
      {"residual --preset spindle4 --fit rec.csv --check check.csv --report /proc/r", "--report /proc/r: it cannot be made in /proc"},
      {"effect-suite --set reduced --only temperature_dependent --score-only --out model.json",
       "--out model.json: exists and is not a directory"},
  };
  for (const auto& c : cases) {
    const CliResult r = run_btsm(d, c.args, 30);
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.err;
    EXPECT_TRUE(mentions(r, c.says)) << c.args << "\n" << r.err;
    EXPECT_FALSE(mentions(r, "reading ") || mentions(r, "filesystem error")) << c.args << "\n" << r.err;  // before the work
  }
  EXPECT_TRUE(fs::is_empty(d.file("adir")));
  EXPECT_FALSE(file_exists(d.file("r.json")));
  expect_no_temporaries(d.path);
}

// A reduce whose --blob cannot be written replaced the reduced JSON of the pair first, then failed
// with exit 1 (probe 7 F4): the pair on disk no longer belonged together. Now both places are
// checked before the reduction and the pair is written both or neither; the old pair is kept byte
// for byte.
TEST(OutputPlaces, ReduceWritesItsJsonAndBlobBothOrNeither) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  fs::create_directories(d.file("pair/blobdir"));
  ASSERT_EQ(run_btsm(d, "reduce model.json --speeds 4000,6000 --force --out pair/r.json --blob pair/m.bin", 300).code, 0);
  const std::string json = read_text(d.file("pair/r.json")), blob = read_text(d.file("pair/m.bin"));
  ASSERT_FALSE(json.empty());
  expect_refusals(d,
                  {{"reduce model.json --speeds 3000,6000 --force --out pair/r.json --blob pair/blobdir",
                    "--blob pair/blobdir: a directory, not a file to write the model blob to"},
                   {"reduce model.json --speeds 3000,6000 --force --out pair/r.json --blob nodir/m.bin",
                    "--blob nodir/m.bin: its directory nodir does not exist"}},
                  2, 300);
  EXPECT_EQ(read_text(d.file("pair/r.json")), json);
  EXPECT_EQ(read_text(d.file("pair/m.bin")), blob);
  expect_no_temporaries(d.path);
}

// The same at the write itself, for a failure no check before the work can see: the second file
// of the pair cannot be created. Neither destination changes and no temporary file is left.
TEST(OutputPlaces, WriteOutputFilesIsAllOrNothing) {
  ScratchDir d;
  write_text(d.file("a.json"), "old a\n");
  EXPECT_THROW(io::write_output_files({{d.file("a.json"), "new a\n", "JSON"}, {d.file("gone/b.bin"), "new b", "blob"}}),
               std::runtime_error);
  EXPECT_EQ(read_text(d.file("a.json")), "old a\n");
  EXPECT_FALSE(file_exists(d.file("gone")));
  expect_no_temporaries(d.path);
  io::write_output_files({{d.file("a.json"), "new a\n", "JSON"}, {d.file("b.bin"), "new b", "blob"}});
  EXPECT_EQ(read_text(d.file("a.json")), "new a\n");
  EXPECT_EQ(read_text(d.file("b.bin")), "new b");
}

// Runs `body` in a child that alarm() stops after 5 s: it must throw std::runtime_error at once.
// A writer that waits on a named pipe again ends in SIGALRM, a failed test, not a hung suite.
template <class Body>
void expect_prompt_runtime_error(Body body) {
  EXPECT_EXIT(
      {
        ::alarm(5);
        try {
          body();
        } catch (const std::runtime_error&) {
          std::_Exit(0);
        }
        std::_Exit(1);
      },
      ::testing::ExitedWithCode(0), "");
}

// The writers themselves, for a place that became a named pipe after the checks before the
// work: never opened for writing (which waits for a reader), always an error at once.
TEST(OutputPlaces, WritersRefuseANamedPipeAtOnce) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  ScratchDir d;
  const std::string pipe = d.file("fifo");
  make_fifo(pipe);
  expect_prompt_runtime_error([&] { io::write_output_file(pipe, "x", "test output"); });
  expect_prompt_runtime_error([&] { (void)io::open_output_stream(pipe, "test output"); });
  expect_prompt_runtime_error([&] { (void)io::open_output_stream(pipe, "test output", true); });
  expect_prompt_runtime_error([&] {
    thermal::RecordingWriter w;
    w.open(pipe, {"T1"});
  });
  EXPECT_TRUE(is_fifo(pipe));
  EXPECT_EQ(io::special_file_kind(pipe), "a named pipe");
  EXPECT_EQ(io::special_file_kind(d.path), "a directory");
  EXPECT_EQ(io::special_file_kind("/dev/null"), "a character device");
  EXPECT_EQ(io::special_file_kind(d.file("absent")), "");
}

}  // namespace
}  // namespace btsm::test
