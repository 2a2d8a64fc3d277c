// The seventh hostile-input probe's P3 findings on input files and options: what named a
// symptom (or the wrong cause, or nothing) now names the cause, the file, the line or the option,
// and an option's error comes before any work (exit 2).
#include "cli_run.hpp"
#include "model_fixture.hpp"
#include "refusals.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace btsm::test {
namespace {

std::string key_hex() { return std::string(63, '0') + "5\n"; }

// P3-k: the key was read after connecting, so a bad --key-file with no module there was exit 3
// (link) instead of 2. Now it is read and checked first.
TEST(Probe7P3, ABadKeyFileIsExitTwoBeforeAnyModuleIsAsked) {
  ScratchDir d;
  (void)reduced_spindle4_json(d);  // m.bin: a valid blob, so the key file is what is refused
  write_text(d.file("0000de70.key"), "not hex at all\n");
  ::chmod(d.file("0000de70.key").c_str(), 0600);
  write_text(d.file("0000de71.key"), key_hex());
  ::chmod(d.file("0000de71.key").c_str(), 0644);
  write_text(d.file("0000de72.key"), std::string(20, 'a') + "\n");
  ::chmod(d.file("0000de72.key").c_str(), 0600);
  expect_refusals(d, {{"flash-model m.bin --port /nonexistent/tty --key-file 0000de70.key", "0000de70.key"},
                      {"flash-model m.bin --port /nonexistent/tty --key-file 0000de71.key", "has permissions 0644"},
                      {"flash-model m.bin --port /nonexistent/tty --key-file 0000de72.key", "expected 32"},
                      {"flash-model m.bin --port /nonexistent/tty --key-file 0000de73.key", "no key for device 0000de73"}});
  // A good key file gets as far as the link: the missing port is exit 3, as before.
  write_text(d.file("0000de74.key"), key_hex());
  ::chmod(d.file("0000de74.key").c_str(), 0600);
  const CliResult good = run_btsm(d, "flash-model m.bin --port /nonexistent/tty --key-file 0000de74.key");
  EXPECT_EQ(good.code, 3) << good.err;
}

std::string replaced(std::string text, char from, char to) {
  for (char& c : text)
    if (c == from) c = to;
  return text;
}

// P3-h: lines ending in a bare CR (classic Mac) read as one line, "no header line found"; part of
// a file converted that way ran two rows into one, "expected 7 cells, found 13".
TEST(Probe7P3, LinesEndingInABareCarriageReturnAreNamedWithTheConversion) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("mac.csv"), replaced(recording_csv(200), '\n', '\r'));
  std::string part = recording_csv(200);
  part[part.find("\n100,")] = '\r';  // the row at t = 90 s runs into the one at 100 s
  write_text(d.file("part.csv"), part);
  expect_refusals(d, {{"validate model.json mac.csv", "mac.csv:1: the lines end in a bare CR"},
                      {"validate model.json mac.csv", "tr '\\r' '\\n' < mac.csv"},
                      {"validate model.json part.csv", "part.csv:12:8: expected 7 cells, found 13 (it holds a bare CR"}});
  write_text(d.file("crlf.csv"), [] {
    std::string s;
    for (char c : recording_csv(200)) s += c == '\n' ? std::string("\r\n") : std::string(1, c);
    return s;
  }());
  EXPECT_EQ(run_btsm(d, "validate model.json crlf.csv").code, 0);
}

// P3-h: two recordings joined into one file (cat a.csv b.csv) said "bad number 'time_s'".
TEST(Probe7P3, ASecondHeaderMidFileIsNamedAsTwoRecordingsJoined) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  const std::string one = recording_csv(200);  // line 1 "# source", line 2 header, rows 3..202
  write_text(d.file("joined.csv"), one + one);
  std::string repeated = one;
  repeated.insert(repeated.find("\n100,") + 1, "time_s,speed_rpm,ambient_c,T1,T2,T3,T4\n");
  write_text(d.file("repeated.csv"), repeated);
  expect_refusals(d, {{"validate model.json joined.csv",
                       "joined.csv:204: a second header line (the first is line 2), after a metadata comment block that "
                       "starts again at line 203: two recordings joined into one file?"},
                      {"validate model.json repeated.csv", "repeated.csv:13: a second header line (the first is line 2): two"}});
}

// P3-h, P3-l: a symbolic-link loop given as an input was "File does not exist"; a link to nothing
// too; a symlinked key file was "Too many levels of symbolic links" (O_NOFOLLOW's errno).
TEST(Probe7P3, AnInputThatCannotBeOpenedIsNamedWithTheCause) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("rec.csv"), recording_csv(200));
  ASSERT_EQ(::symlink("loop_b.csv", d.file("loop_a.csv").c_str()), 0);
  ASSERT_EQ(::symlink("loop_a.csv", d.file("loop_b.csv").c_str()), 0);
  ASSERT_EQ(::symlink("gone.csv", d.file("dangling.csv").c_str()), 0);
  ASSERT_EQ(::symlink("loop_a.csv", d.file("loop.json").c_str()), 0);
  expect_refusals(d, {{"validate model.json loop_a.csv", "loop_a.csv: a symbolic-link loop (ELOOP"},
                      {"validate loop.json rec.csv", "loop.json: a symbolic-link loop (ELOOP"},
                      {"validate model.json dangling.csv", "dangling.csv: a symbolic link to 'gone.csv', which does not exist"},
                      {"heat loop.json rec.csv", "loop.json: cannot open model or network JSON: a symbolic-link loop (ELOOP"},
                      {"flash-firmware --device-id 0000de70 --dry-run --hex loop_a.csv", "a symbolic-link loop (ELOOP"},
                      {"validate model.json nosuch.csv", "File does not exist: nosuch.csv"}});
  // A key in the key store that is a symbolic link (to a good key).
  const std::string keys = d.path + "/.config/btsm/keys";
  ASSERT_EQ(::system(("mkdir -p " + keys).c_str()), 0);
  write_text(d.file("real.key"), key_hex());
  ::chmod(d.file("real.key").c_str(), 0600);
  ASSERT_EQ(::symlink(d.file("real.key").c_str(), (keys + "/0000de70.key").c_str()), 0);
  const CliResult list = run_btsm(d, "keys list");
  EXPECT_EQ(list.code, 0) << list.err;
  EXPECT_NE(list.out.find("UNUSABLE: key file " + keys + "/0000de70.key is a symbolic link (key files must be regular files)"),
            std::string::npos)
      << list.out;
}

// P3-a: --alpha-range 1 1e-3 was blamed on the recording after the run started ("rec.csv: heat
// inverse: bad alpha grid"); --alpha 1e300 failed with exit 1 after the work. Both are refused as
// they are parsed, naming the option and its range.
TEST(Probe7P3, HeatAlphaOptionsOutsideTheirRangeAreRefusedAsTheyAreParsed) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("rec.csv"), recording_csv(200));
  expect_refusals(d, {{"heat model.json rec.csv --alpha-range 1 1e-3", "--alpha-range: MIN 1 is not below MAX 1e-3"},
                      {"heat model.json rec.csv --alpha-range 1 1", "--alpha-range: MIN 1 is not below MAX 1"},
                      {"heat model.json rec.csv --alpha-range -1 1", "--alpha-range: MIN -1 is outside 1e-15..1e9 K^2/W^2"},
                      {"heat model.json rec.csv --alpha-range 1e-3 1e12", "--alpha-range: MAX 1e12 is outside 1e-15..1e9"},
                      {"heat model.json rec.csv --alpha-range x 1", "--alpha-range: MIN 'x' is not a number"},
                      {"heat model.json rec.csv --alpha-rule fixed --alpha 1e300", "--alpha: 1e300 is outside 1e-15..1e9 K^2/W^2"},
                      {"heat model.json rec.csv --alpha-rule fixed --alpha 0", "--alpha: 0 is outside 1e-15..1e9"}});
  for (const CliResult& r : {run_btsm(d, "heat model.json rec.csv --alpha-range 1 1e-3"),
                             run_btsm(d, "heat model.json rec.csv --alpha-rule fixed --alpha 1e300")})
    EXPECT_EQ(r.err.find("heat: 200 samples"), std::string::npos) << r.err;  // before any work
  const CliResult ok = run_btsm(d, "heat model.json rec.csv --alpha-range 1e-12 1e2");
  EXPECT_EQ(ok.code, 0) << ok.err;
}

// One Intel HEX record (":LLAAAATT<data>CC").
std::string hex_record(unsigned address, unsigned type, const std::vector<uint8_t>& data) {
  unsigned sum = static_cast<unsigned>(data.size()) + (address >> 8) + (address & 0xFF) + type;
  char buf[16];
  std::snprintf(buf, sizeof buf, ":%02X%04X%02X", static_cast<unsigned>(data.size()), address, type);
  std::string line = buf;
  for (uint8_t b : data) {
    std::snprintf(buf, sizeof buf, "%02X", b);
    line += buf;
    sum += b;
  }
  std::snprintf(buf, sizeof buf, "%02X\n", (0x100 - (sum & 0xFF)) & 0xFF);
  return line + buf;
}

// P3-m: data at or past the bootloader (0x7E00) or beyond 32 KiB was refused naming the address
// only; the README promises the line too.
TEST(Probe7P3, FirmwareDataOverTheBootloaderNamesItsHexLine) {
  ScratchDir d;
  const std::vector<uint8_t> sixteen(16, 0xAA);
  const std::string start = hex_record(0x0000, 0x00, sixteen) + hex_record(0x0010, 0x00, sixteen);
  const std::string eof = hex_record(0, 0x01, {});
  write_text(d.file("boot.hex"), start + hex_record(0x7E00, 0x00, sixteen) + eof);
  write_text(d.file("high.hex"), start + hex_record(0, 0x04, {0x00, 0x01}) + hex_record(0x0000, 0x00, sixteen) + eof);
  write_text(d.file("seg.hex"), start + "\n" + hex_record(0, 0x02, {0x10, 0x00}) + hex_record(0x0000, 0x00, sixteen) + eof);
  expect_refusals(d, {{"flash-firmware --device-id 0000de70 --dry-run --hex boot.hex", "boot.hex:3: data at 0x7E00: an application"},
                      {"flash-firmware --device-id 0000de70 --dry-run --hex high.hex", "high.hex:4: data at 0x10000"},
                      {"flash-firmware --device-id 0000de70 --dry-run --hex seg.hex", "seg.hex:5: data at 0x10000"}});
}

// P3-j: '# sensor_fault:' lines were read by no reader: channel T9, code 'melted', a range run
// backwards or 'nan-inf' passed without a word. They are informative comments (README), so each
// is a warning naming its line; the recording is still read.
TEST(Probe7P3, AMalformedSensorFaultLineIsAWarningNamingItsLine) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  const std::string rows = recording_csv(200);  // 202 lines
  write_text(d.file("faults.csv"), rows + "# sensor_fault: T9 open 10.000-20.000\n# sensor_fault: T2 melted 10-20\n"
                                          "# sensor_fault: T2 open 50-10\n# sensor_fault: T2 open nan-inf\n"
                                          "# sensor_fault: T2 open+adc 10.000-20.000\n# sensor_fault: T3 fault 0-1990\n");
  const CliResult r = run_btsm(d, "validate model.json faults.csv");
  EXPECT_EQ(r.code, 0) << r.err;
  for (const char* says : {"faults.csv:203: '# sensor_fault: T9 open 10.000-20.000': 'T9' is not a module channel (T1..T5)",
                           "faults.csv:204: '# sensor_fault: T2 melted 10-20': unknown fault code 'melted'",
                           "faults.csv:205: '# sensor_fault: T2 open 50-10': the range runs backwards",
                           "faults.csv:206: '# sensor_fault: T2 open nan-inf': FROM is not a finite number",
                           "the line is informative only (why a cell is empty) and is ignored"})
    EXPECT_NE(r.err.find(says), std::string::npos) << says << "\n" << r.err;
  EXPECT_EQ(r.err.find(":207:"), std::string::npos) << r.err;  // well-formed lines say nothing
  EXPECT_EQ(r.err.find(":208:"), std::string::npos) << r.err;
}

// The lines [from, to) of `text` (0-based), header and comment lines included.
std::string lines_of(const std::string& text, int from, int to) {
  std::string out;
  int line = 0;
  for (std::size_t at = 0, end; (end = text.find('\n', at)) != std::string::npos; at = end + 1, ++line)
    if (line >= from && line < to) out += text.substr(at, end - at + 1);
  return out;
}

// P3-e: the first half of the fit recording given as the check was described as "1 of every 2
// rows" (a thinning); a contiguous part now says which rows of the fit recording it holds.
TEST(Probe7P3, APartOfTheFitRecordingAsTheCheckIsNamedAsThatPart) {
  ScratchDir d;
  const std::string all = recording_csv(200);  // line 0 "# source", line 1 header, rows on lines 2..201
  write_text(d.file("a.csv"), all);
  write_text(d.file("first_half.csv"), lines_of(all, 0, 102));
  write_text(d.file("middle.csv"), lines_of(all, 0, 2) + lines_of(all, 52, 152));
  write_text(d.file("thinned.csv"), [&] {
    std::string t = lines_of(all, 0, 2);
    for (int k = 2; k < 202; k += 2) t += lines_of(all, k, k + 1);
    return t;
  }());
  expect_refusals(d, {{"residual --preset spindle4 --fit a.csv --check first_half.csv",
                       "(its rows 1-100 are rows 1-100 of a.csv, equal to within 0.5 mK)"},
                      {"residual --preset spindle4 --fit a.csv --check middle.csv", "(its rows 1-100 are rows 51-150 of a.csv, equal"},
                      {"residual --preset spindle4 --fit a.csv --check thinned.csv", "(1 of every 2 rows, 100 of its 100 rows"}});
  const CliResult half = run_btsm(d, "residual --preset spindle4 --fit a.csv --check first_half.csv");
  EXPECT_EQ(half.err.find("of every"), std::string::npos) << half.err;
}

// P3-c: `rtd r2t 1e-400` was "not a number" while a recording reads 1e-400 as 0, and `rtd --r0
// 1e-300` was taken and printed 0.0000. Values read as a recording's cells do; --r0 has a range.
TEST(Probe7P3, RtdReadsNumbersAsRecordingsDoAndRefusesAnImplausibleR0) {
  ScratchDir d;
  expect_refusals(d, {{"rtd r2t 1e-400", "value #1 '1e-400' ohm: below the IEC 60751 range"},
                      {"rtd r2t 1e400", "value #1 '1e400' is beyond the range of a number"},
                      {"rtd t2r --r0 1e-300 0", "--r0 must be a resistance in ohm in 10...1e6"},
                      {"rtd t2r --r0 1e-400 0", "--r0 must be a resistance in ohm in 10...1e6 (Pt10 to beyond Pt10000; 100 = "
                                                "Pt100, 1000 = Pt1000), got 1e-400"},
                      {"rtd t2r --r0 5 0", "got 5"},
                      {"rtd t2r --r0 2e6 0", "got 2e6"},
                      {"rtd t2r --r0 0x64 0", "--r0: '0x64' is not a number"}});
  const CliResult tiny = run_btsm(d, "rtd t2r --r0 100 1e-320");
  EXPECT_EQ(tiny.code, 0) << tiny.err;
  EXPECT_EQ(tiny.out, "100.0000\n");
  const CliResult pt10 = run_btsm(d, "rtd t2r --r0 10 0");
  EXPECT_EQ(pt10.code, 0) << pt10.err;
  EXPECT_EQ(pt10.out, "10.0000\n");
}

}  // namespace
}  // namespace btsm::test
