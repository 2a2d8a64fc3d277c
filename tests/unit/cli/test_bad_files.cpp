// Bad files a user may hand the tool, each a row of the hardening issue: they fail with exit code
// 2 (unreadable or unusable input) or 1 (the operation failed), fast, with a message naming what
// and where, and no output file -- never a crash, a hang or a "converged" with rms inf.
#include "cli_run.hpp"
#include "model_fixture.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <string>

namespace btsm::test {
namespace {

bool mentions(const CliResult& r, const std::string& s) { return r.err.find(s) != std::string::npos; }

// Row 1: a model whose heat sources are all 0 W used to crash `reduce` (SIGSEGV on an empty
// matrix: every Hankel singular value 0). Now: exit 1, the reason, no output file.
TEST(BadFiles, ReduceOfAModelWithoutHeatFailsWithTheReason) {
  ScratchDir d;
  write_text(d.file("zero.json"), spindle4_model_json([](nlohmann::json& p) {
    for (const char* q : {"qf1", "qf2", "qf3", "qf4"}) p[q] = 0.0;
  }));
  const CliResult r = run_btsm(d, "reduce zero.json --speeds 4000,6000 --out r.json --blob m.bin");
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(mentions(r, "Hankel singular value")) << r.err;
  EXPECT_FALSE(file_exists(d.file("r.json")));
  EXPECT_FALSE(file_exists(d.file("m.bin")));
}

// Row 2: one cell of 1e300 rpm or 1e155 degC made the fit print "converged" with rms inf and
// write a model with every heat source 0. The reader refuses values no spindle reaches, naming
// file, line and column, before anything is fitted.
TEST(BadFiles, RecordingValuesBeyondPhysicalBoundsAreRefusedWithTheirPlace) {
  ScratchDir d;
  struct Case {
    int row, col;
    const char* text;
    const char* says;
  } cases[] = {
      {40, 1, "1e300", "rpm"},           // speed
      {40, 3, "1e155", "degC"},          // temperature
      {40, 4, "-300", "absolute zero"},  // below -273.15 degC
      {40, 2, "1e200", "degC"},          // ambient
  };
  for (const auto& c : cases) {
    write_text(d.file("rec.csv"), recording_csv(200, [&](int row, int col, const std::string& text) {
                 return row == c.row && col == c.col ? std::string(c.text) : text;
               }));
    const CliResult r = run_btsm(d, "fit rec.csv --preset spindle4 --sum-c 20478.7 --out model.json");
    EXPECT_EQ(r.code, 2) << c.text << "\n" << r.err;
    // line = 2 header lines + row + 1, column 1-based
    const std::string where = "rec.csv:" + std::to_string(c.row + 3) + ":" + std::to_string(c.col + 1);
    EXPECT_TRUE(mentions(r, where)) << where << "\n" << r.err;
    EXPECT_TRUE(mentions(r, c.says)) << r.err;
    EXPECT_FALSE(file_exists(d.file("model.json"))) << c.text;
  }
}

// Row 2, the fit's own final check: a network free to heat (its source's power not fixed) fitted
// to a recording in which nothing heats -- temperatures decay while the spindle runs -- ends with
// every heat source at 0 W. Such a model predicts nothing and leaves reduce nothing to reduce:
// exit 1 with the reason, no model written (the fit used to write it and exit 0).
TEST(BadFiles, FitThatEndsDegenerateWritesNoModel) {
  ScratchDir d;
  write_text(d.file("net.json"), R"({"name": "two nodes", "speed_ref_rpm": 5000, "sum_capacitance_J_per_K": 3000,
    "parameters": [{"name": "C1", "unit": "J/K", "min": 1, "max": 1e6}, {"name": "C2", "unit": "J/K", "min": 1, "max": 1e6},
      {"name": "Ra", "unit": "K/W", "min": 1e-3, "max": 1e3}, {"name": "Rab", "unit": "K/W", "min": 1e-3, "max": 1e3},
      {"name": "Rb", "unit": "K/W", "min": 1e-3, "max": 1e3}, {"name": "q", "unit": "W", "min": 0, "max": 100, "log": false}],
    "nodes": [{"name": "a", "capacitance": "C1"}, {"name": "b", "capacitance": "C2"}],
    "links": [{"name": "a0", "between": ["a", "ambient"], "both": [{"resistance": "Ra"}]},
              {"name": "ab", "between": ["a", "b"], "both": [{"resistance": "Rab"}]},
              {"name": "b0", "between": ["b", "ambient"], "both": [{"resistance": "Rb"}]}],
    "sources": [{"name": "heat", "node": "a", "operating": [{"power": "q", "speed_exponent": 1}]}],
    "measurements": [{"column": "T1", "node": "a"}, {"column": "T2", "node": "b"}]})");
  // C1 1000 J/K, C2 2000 J/K, Ra 2, Rab 1, Rb 4 K/W; 20 / 15 K above ambient, no heat at all.
  std::string rec = "time_s,speed_rpm,ambient_c,T1,T2\n";
  double x1 = 20, x2 = 15;
  for (int k = 0; k < 1500; ++k) {
    char line[96];
    std::snprintf(line, sizeof line, "%d,%d,20.000,%.4f,%.4f\n", 10 * k, k < 750 ? 6000 : 0, 20 + x1, 20 + x2);
    rec += line;
    for (int i = 0; i < 20; ++i) {  // Euler, 0.5 s steps
      const double d1 = (-x1 / 2.0 - (x1 - x2) / 1.0) / 1000.0, d2 = (-(x2 - x1) / 1.0 - x2 / 4.0) / 2000.0;
      x1 += 0.5 * d1;
      x2 += 0.5 * d2;
    }
  }
  write_text(d.file("decay.csv"), rec);
  const CliResult r = run_btsm(d, "fit decay.csv --network net.json --out model.json", 300);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(mentions(r, "degenerate: every heat source is (near) 0 W")) << r.err;
  EXPECT_FALSE(file_exists(d.file("model.json")));
}

// Row 3: /dev/zero as any input file never returned (memory grew by 1.6 GB in 10 s). Every reader
// reads through a size cap and refuses a text file's first NUL byte.
TEST(BadFiles, DevZeroFailsFastAsEveryInput) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("rec.csv"), recording_csv(50));
  const char* commands[] = {
      "fit /dev/zero --preset spindle4 --out m.json",
      "fit rec.csv --network /dev/zero --out m.json",
      "validate /dev/zero rec.csv",
      "validate model.json /dev/zero",
      "reduce /dev/zero --speeds 6000 --out r.json",
      "heat /dev/zero rec.csv --out heat",
      "flash-model /dev/zero --port /dev/null",
      "flash-firmware --device-id 0000de71 --new-key --hex /dev/zero --dry-run --out fw.hex",
      "sim-module --pty sim.pty --profile-file /dev/zero",  // grew one endless line, never started
  };
  for (const char* c : commands) {
    const auto t0 = std::chrono::steady_clock::now();
    const CliResult r = run_btsm(d, c, 20);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_EQ(r.code, 2) << c << "\n" << r.err;
    EXPECT_LT(s, 10.0) << c;
    EXPECT_TRUE(mentions(r, "/dev/zero")) << c << "\n" << r.err;
  }
  EXPECT_FALSE(file_exists(d.file("m.json")));
  EXPECT_FALSE(file_exists(d.file("r.json")));
  EXPECT_FALSE(file_exists(d.file("fw.hex")));
}

// What to build 3: every file is read through a size cap, and the refusal states the cap. Sparse
// files just over each limit: a regular file is refused from its size, before a byte is read.
TEST(BadFiles, FilesBeyondTheirLimitAreRefusedWithTheLimitNamed) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("rec.csv"), recording_csv(50));
  const auto sparse = [&](const char* name, std::uintmax_t bytes) {
    write_text(d.file(name), "");
    std::filesystem::resize_file(d.file(name), bytes);
  };
  constexpr std::uintmax_t kMiB = 1024 * 1024;
  sparse("big.csv", 256 * kMiB + 1);
  sparse("big.json", 16 * kMiB + 1);
  sparse("big_blob.bin", 64 * 1024 + 1);
  write_text(d.file("names_big_blob.json"), R"({"blob_file": "big_blob.bin"})");
  struct Case {
    std::string args, limit;
  } cases[] = {
      {"fit big.csv --preset spindle4 --out m.json", "larger than 256 MiB"},
      {"validate model.json big.csv", "larger than 256 MiB"},
      {"fit rec.csv --network big.json --out m.json", "larger than 16 MiB"},
      {"validate big.json rec.csv", "larger than 16 MiB"},
      {"reduce big.json --speeds 6000 --out r.json", "larger than 16 MiB"},
      {"flash-model big.json --port /dev/null", "larger than 16 MiB"},
      {"flash-model names_big_blob.json --port /dev/null", "larger than 64 KiB"},
      {"heat big.json rec.csv --out heat", "larger than 16 MiB"},
  };
  for (const auto& c : cases) {
    const CliResult r = run_btsm(d, c.args, 20);
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.err;
    EXPECT_TRUE(mentions(r, c.limit)) << c.args << "\n" << r.err;
  }
  EXPECT_FALSE(file_exists(d.file("m.json")));
  EXPECT_FALSE(file_exists(d.file("r.json")));
}

// Row 4: a network of ~70,000 nested '[' crashed `fit` (stack overflow building the error).
// JSON nested deeper than 64 levels is refused before a value is built, in every JSON reader.
TEST(BadFiles, DeeplyNestedJsonIsRefusedNotACrash) {
  ScratchDir d;
  write_text(d.file("rec.csv"), recording_csv(50));
  const std::string deep = std::string(70000, '[') + std::string(70000, ']');
  write_text(d.file("deep.json"), deep);
  write_text(d.file("deep_open.json"), std::string(70000, '['));
  write_text(d.file("deep_field.json"), "{\"name\": " + deep + "}");
  for (const char* f : {"deep.json", "deep_open.json", "deep_field.json"}) {
    for (const std::string& c : {std::string("fit rec.csv --out m.json --network ") + f, std::string("validate ") + f + " rec.csv",
                                std::string("reduce ") + f + " --speeds 6000 --out r.json",
                                std::string("flash-model ") + f + " --port /dev/null",
                                // heat and residual --network read a model or a network: they
                                // parsed with an unguarded reader and overflowed the stack (SIGSEGV)
                                std::string("heat ") + f + " rec.csv --out heat",
                                std::string("residual --network ") + f + " --fit rec.csv --check rec.csv"}) {
      const CliResult r = run_btsm(d, c);
      EXPECT_EQ(r.code, 2) << c << "\n" << r.err;
      EXPECT_TRUE(mentions(r, "nested deeper than 64")) << c << "\n" << r.err;
    }
  }
}

// Row 7: negative resistances passed `validate` (exit 0) and `reduce` made a blob with a 105-day
// time constant. Every model is checked on load against the network's bounds and for stability.
TEST(BadFiles, ModelValuesOutsideTheNetworkBoundsAreRefusedOnLoad) {
  ScratchDir d;
  write_text(d.file("rec.csv"), recording_csv(200));
  write_text(d.file("neg.json"), spindle4_model_json([](nlohmann::json& p) {
    p["R12"] = -0.5;
    p["Ra1"] = -3.0;
  }));
  write_text(d.file("huge.json"), spindle4_model_json([](nlohmann::json& p) { p["C1"] = 1e12; }));
  for (const char* m : {"neg.json", "huge.json"}) {
    for (const std::string& c : {std::string("validate ") + m + " rec.csv", std::string("reduce ") + m + " --speeds 6000 --out r.json --blob m.bin",
                                std::string("heat ") + m + " rec.csv --out heat"}) {
      const CliResult r = run_btsm(d, c);
      EXPECT_EQ(r.code, 2) << c << "\n" << r.err;
      EXPECT_TRUE(mentions(r, "outside the network's bounds")) << c << "\n" << r.err;
    }
  }
  EXPECT_TRUE(mentions(run_btsm(d, "validate neg.json rec.csv"), "'R12' = -0.5"));
  EXPECT_FALSE(file_exists(d.file("r.json")));
  EXPECT_FALSE(file_exists(d.file("m.bin")));
  // The preset's own values pass.
  write_text(d.file("good.json"), spindle4_model_json());
  const CliResult ok = run_btsm(d, "validate good.json rec.csv");
  EXPECT_EQ(ok.code, 0) << ok.err;
}

// The reduced model (btsm reduce --out) handed where the fitted model belongs is named for what it
// is, in every command that takes a fitted model; it used to read "needs 'network'" in validate and
// "unknown field 'blob_hex'" in heat. Another format name is refused as such.
TEST(BadFiles, AReducedModelWhereTheFittedModelBelongsIsNamed) {
  ScratchDir d;
  write_text(d.file("rec.csv"), recording_csv(200));
  write_text(d.file("reduced.json"), R"({"format": "btsm-reduced-model-2", "blob_hex": "00", "channels": []})");
  nlohmann::json other = nlohmann::json::parse(spindle4_model_json());
  other["format"] = "btsm-thermal-model-9";
  write_text(d.file("other.json"), other.dump());
  for (const std::string& c : {std::string("validate reduced.json rec.csv"), std::string("reduce reduced.json --speeds 6000 --out r.json"),
                              std::string("heat reduced.json rec.csv --out heat")}) {
    const CliResult r = run_btsm(d, c);
    EXPECT_EQ(r.code, 2) << c << "\n" << r.err;
    EXPECT_TRUE(mentions(r, "a reduced model ('btsm-reduced-model-2'")) << c << "\n" << r.err;
    EXPECT_TRUE(mentions(r, "btsm fit --out")) << c << "\n" << r.err;
  }
  const CliResult r = run_btsm(d, "validate other.json rec.csv");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_TRUE(mentions(r, "format 'btsm-thermal-model-9' is not a fitted model")) << r.err;
  EXPECT_FALSE(file_exists(d.file("r.json")));
}

// Row 9: `validate` on a recording of one row, or with every temperature empty, printed nan and
// exited 0. Nothing to validate against is bad input.
TEST(BadFiles, ValidateWithNothingToCompareIsRefused) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("one_row.csv"), recording_csv(1));
  write_text(d.file("empty_temps.csv"), recording_csv(100, [](int, int col, const std::string& text) {
               return col >= 3 ? std::string() : text;
             }));
  for (const char* f : {"one_row.csv", "empty_temps.csv"}) {
    const CliResult r = run_btsm(d, std::string("validate model.json ") + f + " --json");
    EXPECT_EQ(r.code, 2) << f << "\n" << r.err;
    EXPECT_TRUE(mentions(r, f)) << r.err;
    EXPECT_EQ(r.out.find("nan"), std::string::npos) << r.out;
  }
}

}  // namespace
}  // namespace btsm::test
