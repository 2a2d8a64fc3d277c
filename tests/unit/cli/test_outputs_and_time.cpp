// Outputs that must never cost the user a file, and inputs whose time axis or model cannot give a
// meaningful answer: the rows of the hostile-input probe of 26 Nov that ended in exit 0 with a
// wrong result or a lost file.
#include "cli_run.hpp"
#include "refusals.hpp"
#include "model_fixture.hpp"

#include "host/io/output_file.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <stdexcept>
#include <string>

namespace btsm::test {
namespace {

bool mentions(const CliResult& r, const std::string& s) { return r.err.find(s) != std::string::npos; }

// `fit rec.csv --out rec.csv` replaced a recording by model JSON (also when the fit then failed);
// reduce and heat did the same to their model and recording. Refused before any work, with both
// names, and the input is byte for byte what it was.
TEST(Outputs, AnOutputNamingAnInputIsRefusedAndTheInputKept) {
  ScratchDir d;
  const std::string rec = recording_csv(200), model = spindle4_model_json();
  write_text(d.file("rec.csv"), rec);
  write_text(d.file("model.json"), model);
  std::filesystem::create_directory(d.file("h"));
  write_text(d.file("h/heat_sources.csv"), rec);
  struct Case {
    const char* args;
    const char* option;
    const char* input;
  } cases[] = {
      {"fit rec.csv --preset spindle4 --sum-c 20478.7 --out ./rec.csv", "--out", "rec.csv"},
      {"reduce model.json --speeds 4000,6000 --out model.json", "--out", "model.json"},
      {"reduce model.json --speeds 4000,6000 --out r.json --blob model.json", "--blob", "model.json"},
      {"heat model.json h/heat_sources.csv --out h", "--out", "h/heat_sources.csv"},
  };
  for (const auto& c : cases) {
    const CliResult r = run_btsm(d, c.args);
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.err;
    EXPECT_TRUE(mentions(r, c.option) && mentions(r, "refusing to overwrite")) << r.err;
    EXPECT_EQ(read_text(d.file("rec.csv")), rec) << c.args;
    EXPECT_EQ(read_text(d.file("model.json")), model) << c.args;
    EXPECT_EQ(read_text(d.file("h/heat_sources.csv")), rec) << c.args;
  }
}

// A blob written to a full disk was reported "wrote /dev/full (464 bytes)" with exit 0. /dev/full
// is refused as an output place now (a device, exit 2 before the work: test_output_places.cpp);
// the full disk is a file size limit here (ulimit -f 8: 4 KiB, the reduced JSON is ~11 KiB, the
// report on stdout and stderr less), with SIGXFSZ ignored so the write fails with EFBIG.
TEST(Outputs, AWriteErrorFailsTheCommand) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  const std::string limited = "sh -c 'trap \"\" XFSZ; ulimit -f 8; exec \"$0\" \"$@\"' " + btsm_cli();
  const CliResult r = run_cli(limited, d.path, "reduce model.json --speeds 4000,6000 --out r.json --blob m.bin --force", 300, d.path);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(mentions(r, "r.json: cannot write the JSON: File too large")) << r.err;
  EXPECT_FALSE(mentions(r, "wrote")) << r.err;
  EXPECT_FALSE(file_exists(d.file("r.json")) || file_exists(d.file("m.bin")));  // neither of the pair
}

// The library calls behind those: the replace is all or nothing, the same file is recognised
// under another name, and a recording's old file is kept under the first free backup name.
TEST(Outputs, WriteReplaceAndBackupPrimitives) {
  ScratchDir d;
  const std::string f = d.file("out.txt");
  io::write_output_file(f, "first\n", "test output");
  io::write_output_file(f, "second\n", "test output");
  EXPECT_EQ(read_text(f), "second\n");
  for (const auto& e : std::filesystem::directory_iterator(d.path))  // no temporary left beside it
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
  EXPECT_THROW(io::write_output_file(d.path, "x", "test output"), std::runtime_error);  // a directory
  EXPECT_THROW(io::write_output_file("/dev/full", "x", "test output"), std::runtime_error);
  EXPECT_THROW(io::write_output_file(d.file("no/such/dir/out.txt"), "x", "test output"), std::runtime_error);

  std::filesystem::create_hard_link(f, d.file("link.txt"));
  EXPECT_THROW(io::refuse_output_over_input(d.file("link.txt"), "--out", {f}), std::invalid_argument);
  EXPECT_THROW(io::refuse_output_over_input(d.path + "/./out.txt", "--out", {f}), std::invalid_argument);
  EXPECT_NO_THROW(io::refuse_output_over_input(d.file("new.txt"), "--out", {f}));

  EXPECT_EQ(io::keep_existing_as_backup(d.file("absent.csv")), "");
  write_text(d.file("rec.csv"), "old 1");
  EXPECT_EQ(io::keep_existing_as_backup(d.file("rec.csv")), d.file("rec.csv.~1~"));
  write_text(d.file("rec.csv"), "old 2");
  EXPECT_EQ(io::keep_existing_as_backup(d.file("rec.csv")), d.file("rec.csv.~2~"));
  EXPECT_EQ(read_text(d.file("rec.csv.~1~")), "old 1");
  EXPECT_EQ(read_text(d.file("rec.csv.~2~")), "old 2");
  EXPECT_FALSE(file_exists(d.file("rec.csv")));
}

// A time of 1e300 s was fitted ("converged", every parameter at a bound) and replayed by reduce's
// detector calibration for ever; rows 1e-9 s apart gave 57 kW heat sources. Refused with the place.
TEST(TimeAxis, TimesBeyondTheLimitsAreRefusedWithTheirPlace) {
  ScratchDir d;
  struct Case {
    const char* text;
    const char* says;
  } cases[] = {{"1e300", "a recording may hold"}, {"1000000001", "a recording may hold"}, {"400.000000001", "duplicated timestamp"}};
  for (const auto& c : cases) {
    write_text(d.file("rec.csv"), recording_csv(200, [&](int row, int col, const std::string& text) {
                 return row == 41 && col == 0 ? std::string(c.text) : text;
               }));
    for (const char* cmd : {"fit rec.csv --preset spindle4 --sum-c 20478.7 --out model.json", "heat spindle4 rec.csv"}) {
      const CliResult r = run_btsm(d, cmd);
      EXPECT_EQ(r.code, 2) << c.text << " " << cmd << "\n" << r.err;
      EXPECT_TRUE(mentions(r, "rec.csv:44:1") && mentions(r, c.says)) << c.text << "\n" << r.err;
    }
  }
}

// A model whose speed law makes it unstable at the recording's speeds (speed_ref_rpm 1: every
// source scaled by 6000^n) loads -- stability is checked at rest and at the reference speed --
// and its NaN rows dropped out of every metric: validate scored the stopped rows alone, heat wrote
// all -nan, residual reported "base rms 0 K". Now each names where the prediction diverges.
TEST(Models, APredictionThatDivergesIsAnErrorNotAScore) {
  ScratchDir d;
  nlohmann::json m = nlohmann::json::parse(spindle4_model_json());
  m["network"]["speed_ref_rpm"] = 1;
  write_text(d.file("model.json"), m.dump(2));
  write_text(d.file("rec.csv"), recording_csv(400));
  const CliResult v = run_btsm(d, "validate model.json rec.csv --initial-rows 20 --json");
  EXPECT_EQ(v.code, 2) << v.out << v.err;
  EXPECT_TRUE(mentions(v, "rec.csv") && mentions(v, "diverges") && mentions(v, "6000 rpm")) << v.err;
  write_text(d.file("check.csv"), recording_csv(300));
  const CliResult r = run_btsm(d, "residual --fit rec.csv --check check.csv --network model.json --use-values --threads 1");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_TRUE(mentions(r, "diverges")) << r.err;
  // heat replaces the model's friction sources by unknowns; a temperature-driven one it keeps
  // overflows outright with the speed law referred to 1e-300 rpm
  m["network"]["speed_ref_rpm"] = 1e-300;
  m["network"]["parameters"].push_back({{"name", "k"}, {"unit", "W/K"}, {"min", 0}, {"max", 10}, {"log", false}});
  m["network"]["sources"].push_back({{"name", "heat_T"}, {"node", "rear_bearing"},
                                     {"operating", {{{"driven_by", {"rear_bearing", "ambient"}}, {"power", "k"}, {"speed_exponent", 1.5}}}}});
  m["parameters"]["k"] = 0.01;
  write_text(d.file("tiny.json"), m.dump(2));
  const CliResult h = run_btsm(d, "heat tiny.json rec.csv --out h");
  EXPECT_EQ(h.code, 1) << h.err;
  EXPECT_TRUE(mentions(h, "not a number")) << h.err;
  EXPECT_FALSE(file_exists(d.file("h/heat_sources.csv"))) << h.err;
}

// A HEX file, a host binary or a directory as --elf started a simulation that ended "AVR core
// stopped (crashed)"; the heat inverse on readings that never vary said "give it explicitly"
// without the file or the option. Both now name what and where.
TEST(Inputs, AnImageThatIsNotAnAvrElfAndReadingsWithoutNoiseAreNamed) {
  ScratchDir d;
  write_text(d.file("fw.hex"), ":100000000C9434000C9446000C9446000C9446006A\n");
  const CliResult hex = run_btsm(d, "sim-module --board avr --elf fw.hex --pty p --duration 1m");
  EXPECT_EQ(hex.code, 2) << hex.err;
  EXPECT_TRUE(mentions(hex, "fw.hex") && mentions(hex, "not an ELF")) << hex.err;
  const CliResult host = run_btsm(d, "sim-module --board avr --elf /bin/ls --pty p --duration 1m");
  EXPECT_EQ(host.code, 2) << host.err;
  EXPECT_TRUE(mentions(host, "not an AVR image")) << host.err;
  write_text(d.file("flat.csv"), recording_csv(200, [](int, int col, const std::string& text) {
               return col >= 3 ? std::string("21.0000") : text;
             }));
  const CliResult h = run_btsm(d, "heat spindle4 flat.csv");
  EXPECT_EQ(h.code, 2) << h.err;
  EXPECT_TRUE(mentions(h, "flat.csv") && mentions(h, "noise level") && mentions(h, "--noise")) << h.err;
}

// Options whose value has no meaning were taken as given: heat --noise -1, residual --iterations -1
// or --check-improvement 0 (a "better" that is worse), sim-module --start-steady 1e9 (which then
// stopped at 81 million degC). The parser refuses them, naming the option, exit 2.
TEST(Inputs, OptionValuesWithoutMeaningAreRefusedByName) {
  ScratchDir d;
  write_text(d.file("rec.csv"), recording_csv(200));
  expect_refusals(d, {
      {"heat spindle4 rec.csv --noise -1", "--noise"},
      {"residual --preset spindle4 --fit rec.csv --check rec.csv --iterations -1", "--iterations"},
      {"residual --preset spindle4 --fit rec.csv --check rec.csv --check-improvement 0", "--check-improvement"},
      {"residual --preset spindle4 --fit rec.csv --check rec.csv --max-candidates 0", "--max-candidates"},
      {"sim-module --pty p --start-steady 1e9 --duration 1m", "--start-steady"},
      {"sim-module --pty p --noise -1 --duration 1m", "--noise"},
  });
}

}  // namespace
}  // namespace btsm::test
