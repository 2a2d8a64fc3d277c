// README's exit codes: 0 ok, 1 the operation ran and failed, 2 bad arguments or unreadable input,
// 3 no device / link lost. The argument parser's own codes (105 missing required option, 106
// file does not exist, 114 value out of range, ...) used to leak through; every floating-point
// option refuses nan and inf; nothing is written before the inputs are checked.
#include "cli_run.hpp"
#include "model_fixture.hpp"

#include <gtest/gtest.h>

namespace btsm::test {
namespace {

TEST(CliExitCodes, ParserErrorsAreTwo) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  struct Case {
    const char* what;
    std::string args;
  } cases[] = {
      {"missing input file", "fit missing.csv --preset spindle4 --out m.json"},
      {"missing required option", "fit --preset spindle4"},
      {"value out of range", "reduce model.json --speeds 6000 --out r.json --dt 100"},
      {"option without a value", "reduce model.json --speeds 6000 --out r.json --dt"},
      {"unknown option", "reduce model.json --speeds 6000 --out r.json --no-such-option"},
      {"no command", ""},
      {"unknown command", "no-such-command"},
      {"not a number", "reduce model.json --speeds 6000 --out r.json --dt fast"},
  };
  for (const auto& c : cases) {
    const CliResult r = run_btsm(d, c.args);
    EXPECT_EQ(r.code, 2) << c.what << ": btsm " << c.args << "\n" << r.err;
    EXPECT_FALSE(r.err.empty()) << c.what;
  }
  EXPECT_FALSE(file_exists(d.file("r.json")));
  EXPECT_FALSE(file_exists(d.file("m.json")));
  EXPECT_EQ(run_btsm(d, "--help").code, 0);
  EXPECT_EQ(run_btsm(d, "--version").code, 0);
  EXPECT_EQ(run_btsm(d, "reduce --help").code, 0);
}

// A malformed link address is a bad argument (2), not a missing device (3): it is checked before
// anything is opened; so are reduce's --speeds (before the channel map is printed) and
// flash-model's --key-file name (before connecting).
TEST(CliExitCodes, MalformedAddressesAndSpeedsAreTwo) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  for (const char* args : {"info --ble nonsense", "info --ble AA:BB:CC:DD:EE:FF/sideways", "info --usb zz",
                           "info --rfcomm 12:34", "monitor --usb 2341", "record --ble x --out r.csv",
                           // flash-firmware said "bad --usb" with exit 3, a missing device (probe 4)
                           "flash-firmware --device-id 0000de70 --dry-run --usb xyz",
                           "flash-firmware --device-id 0000de70 --dry-run --usb 0x2341:0x0043"}) {
    const CliResult r = run_btsm(d, args);
    EXPECT_EQ(r.code, 2) << args << "\n" << r.err;
    EXPECT_NE(r.err.find("bad"), std::string::npos) << args << "\n" << r.err;
  }
  EXPECT_FALSE(file_exists(d.file("btsm-fw-0000de70.hex")));
  const CliResult sp = run_btsm(d, "reduce model.json --speeds 6000,4000 --out r.json");
  EXPECT_EQ(sp.code, 2) << sp.err;
  EXPECT_NE(sp.err.find("--speeds: '6000,4000': each in 1..65534 rpm, strictly ascending"), std::string::npos) << sp.err;
  EXPECT_EQ(sp.err.find("channel map"), std::string::npos) << sp.err;
  write_text(d.file("model.bin"), std::string(464, '\0'));
  const CliResult kf = run_btsm(d, "flash-model --port /nonexistent/tty --key-file mykey.key model.bin");
  EXPECT_EQ(kf.code, 2) << kf.err;
  EXPECT_NE(kf.err.find("--key-file must be named"), std::string::npos) << kf.err;
}

// An output directory given with a trailing slash printed "heat//heat_sources.csv".
TEST(CliPaths, TrailingSlashOfAnOutputDirectoryIsDropped) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("rec.csv"), recording_csv(200));
  const CliResult r = run_btsm(d, "heat model.json rec.csv --out heat/");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("written: heat/heat_sources.csv"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("//"), std::string::npos) << r.out;
}

// validate estimates the initial state from the first --initial-rows rows; a recording no longer
// than that scored NMSE 0.99997 on the rows its start was fitted to (exit 0). The NMSE printed is
// the paper's A7 index (1 = perfect), the opposite of the usual meaning: the output says so.
TEST(CliValidate, ARecordingNoLongerThanTheInitialRowsIsRefusedAndNmseIsExplained) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("tiny.csv"), recording_csv(100));
  write_text(d.file("short.csv"), recording_csv(200));
  const CliResult tiny = run_btsm(d, "validate model.json tiny.csv");
  EXPECT_EQ(tiny.code, 2) << tiny.err;
  EXPECT_NE(tiny.err.find("tiny.csv: 100 rows, not more than --initial-rows 120"), std::string::npos) << tiny.err;
  const CliResult shorter = run_btsm(d, "validate model.json short.csv --initial-rows 20");
  EXPECT_EQ(shorter.code, 0) << shorter.err;
  EXPECT_NE(shorter.out.find("1 = perfect, 0 = no better than the mean"), std::string::npos) << shorter.out;
  EXPECT_EQ(shorter.out.find("nan"), std::string::npos) << shorter.out;
  // the recording's warm-up is far shorter than 5 slowest time constants: no MAPE, and the reason
  EXPECT_NE(shorter.out.find("steady state: -- (the longest run at one speed before a stop"), std::string::npos) << shorter.out;
  EXPECT_NE(shorter.out.find("rear_bearing"), std::string::npos) << shorter.out;  // rows name their node
  const CliResult warned = run_btsm(d, "validate model.json short.csv");
  EXPECT_EQ(warned.code, 0) << warned.err;
  EXPECT_NE(warned.err.find("the initial state comes from 120 of its 200 rows"), std::string::npos) << warned.err;
}

// `--dt nan` passed the range check (every comparison with NaN is false), wrote reduced.json and
// then failed; now every FLOAT option of every command refuses nan and inf up front.
TEST(CliExitCodes, NonFiniteNumbersAreRefusedBeforeAnythingIsWritten) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  for (const char* bad : {"nan", "NaN", "inf", "-inf", "1e999"}) {
    const CliResult r = run_btsm(d, std::string("reduce model.json --speeds 6000 --out r.json --blob m.bin --dt ") + bad);
    EXPECT_EQ(r.code, 2) << bad << "\n" << r.err;
    EXPECT_NE(r.err.find("--dt"), std::string::npos) << r.err;  // inf may meet the range check first
    EXPECT_FALSE(file_exists(d.file("r.json"))) << bad;
    EXPECT_FALSE(file_exists(d.file("m.bin"))) << bad;
  }
  const CliResult warn = run_btsm(d, "reduce model.json --speeds 6000 --out r.json --warn-evidence nan");
  EXPECT_EQ(warn.code, 2);
  EXPECT_NE(warn.err.find("'nan' is not a finite number"), std::string::npos) << warn.err;
  EXPECT_EQ(run_btsm(d, "fit x.csv --preset spindle4 --out m.json --sum-c inf").code, 2);
  EXPECT_EQ(run_btsm(d, "rtd r2t nan").code, 2);
  EXPECT_FALSE(file_exists(d.file("r.json")));
  // The same command with a finite period works (--force: one breakpoint leaves the model off at
  // lower speeds, test_reduce_speed_range.cpp).
  const CliResult ok = run_btsm(d, "reduce model.json --speeds 6000 --out r.json --blob m.bin --dt 5 --force");
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_TRUE(file_exists(d.file("r.json")));
  EXPECT_TRUE(file_exists(d.file("m.bin")));
}

}  // namespace
}  // namespace btsm::test
