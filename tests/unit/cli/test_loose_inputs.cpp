// What the second hostile-input probe (27 Nov) found accepted too loosely: a value or a file that
// means something other than it seems, taken with exit 0 or refused with a message no user can
// act on. Each is now refused naming the option, file or field; the honest form beside it passes.
#include "cli_run.hpp"
#include "model_fixture.hpp"
#include "refusals.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace btsm::test {
namespace {

// Options: the same node twice as two unknowns, --alpha ignored by a rule that picks its own, a
// negative BIC margin that accepts any effect, hex or a doubled comma in a number list, a seed
// beyond 64 bits saturated, an RFCOMM channel Bluetooth does not have, and CLI11's 300-digit
// "not in range 0.000000 to 1797...".
TEST(LooseInputs, OptionsOutsideTheirMeaningAreRefused) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("rec.csv"), recording_csv(200));
  write_text(d.file("check.csv"), "# source: check\n" + recording_csv(240));
  write_text(d.file("a_file"), "not a directory\n");
  expect_refusals(d, {{"heat model.json rec.csv --nodes housing,housing", "node 'housing' is listed twice"},
                      {"heat model.json rec.csv --alpha 5", "--alpha is used only with --alpha-rule fixed"},
                      {"heat model.json rec.csv --alpha-points 100000", "--alpha-points"},
                      {"heat model.json rec.csv --out a_file", "--out a_file: exists and is not a directory"},
                      {"residual --preset spindle4 --fit rec.csv --check check.csv --bic-margin -1", "--bic-margin"},
                      {"residual --preset spindle4 --fit rec.csv --check check.csv --report a_file",
                       "--report a_file: exists and is not a directory"},
                      {"fit rec.csv --preset spindle4 --out m.json --iterations 0", "not in range 1 to 1000000"},
                      {"fit rec.csv --preset spindle4 --out m.json --sum-c 0", "must be > 0, got 0"},
                      {"reduce model.json --speeds 2000,4000, --out r.json", "an empty entry"},
                      {"reduce model.json --speeds 2000,0x1000 --out r.json", "'0x1000' is not a number"},
                      {"rtd r2t 0x3e8", "'0x3e8' is not a number"},
                      {"rtd r2t inf", "'inf' is not a number"},
                      {"sim-module --no-wait --duration 1s --pty p --seed 99999999999999999999", "beyond the range of whole numbers"},
                      {"info --rfcomm 00:11:22:33:44:55 --rfcomm-channel 0", "--rfcomm-channel"},
                      {"info --port /nonexistent/tty --timeout 0", "--timeout"},
                      {"keys import 0000bee0 " + std::string(64, '0'), "all 00 bytes"},
                      {"keys import 0000bee0 " + std::string(64, 'f'), "all FF bytes"}});
  EXPECT_FALSE(file_exists(d.file("m.json")));
  EXPECT_FALSE(file_exists(d.file("r.json")));
  // What a user means by spaces is taken: a speed list with spaces, a profile with spaces at '@'.
  const CliResult spaced = run_btsm(d, "reduce model.json --speeds \" 2000 , 4000\" --force --out r.json", 300);
  EXPECT_EQ(spaced.code, 0) << spaced.err;
  const CliResult rtd = run_btsm(d, "rtd r2t \" 1000 \"");
  EXPECT_EQ(rtd.code, 0) << rtd.err;
  EXPECT_EQ(rtd.out, "0.0000\n");
  const CliResult sim = run_btsm(d, "sim-module --no-wait --duration 2s --pty p --profile \" 1s @ 6000 , 1s@0 \"");
  EXPECT_EQ(sim.code, 0) << sim.err;
}

// JSON: a key twice in one object (the parser kept the last silently), a "format" that is no
// string, a value for a parameter the network does not have (the one meant kept its old value).
TEST(LooseInputs, ModelFilesThatSayTwoThingsOrOtherThingsAreRefused) {
  ScratchDir d;
  write_text(d.file("rec.csv"), recording_csv(200));
  const std::string model = spindle4_model_json();
  write_text(d.file("model.json"), model);
  std::string twice = model;
  twice.insert(twice.find('{') + 1, "\"format\": \"btsm-thermal-model-1\",");
  twice.insert(twice.find('{') + 1, "\"format\": \"btsm-thermal-model-1\",");
  write_text(d.file("twice.json"), twice);
  nlohmann::json j = nlohmann::json::parse(model);
  j["format"] = 1;
  write_text(d.file("format1.json"), j.dump(2));
  j["format"] = nullptr;
  write_text(d.file("formatnull.json"), j.dump(2));
  j = nlohmann::json::parse(model);
  j["parameters"]["bogus"] = 1.0;
  write_text(d.file("bogus.json"), j.dump(2));
  nlohmann::json net = j["network"];
  net["nodes"][0]["name"] = "first";
  std::string net_twice = net.dump();
  net_twice.insert(net_twice.find("\"name\":\"first\"") + 1, "name\":\"second\",\"");
  write_text(d.file("net_twice.json"), net_twice);
  expect_refusals(d, {{"validate twice.json rec.csv", "twice.json: key \"format\" is given twice in one object"},
                      {"fit rec.csv --network net_twice.json --out m.json", "key \"nodes[].name\" is given twice"},
                      {"validate format1.json rec.csv", "\"format\" is 1, not the string 'btsm-thermal-model-1'"},
                      {"heat formatnull.json rec.csv", "\"format\" is null"},
                      {"validate bogus.json rec.csv", "parameters: \"bogus\" is no parameter of the network"}});
  EXPECT_FALSE(file_exists(d.file("m.json")));
}

// flash-model: a blob given twice (hex and file), a blob that is no string, a fitted model where
// the reduced one belongs, a scheduled_model field that is no number (the consistency check
// skipped it), all taken or misnamed before.
TEST(LooseInputs, AReducedModelFileIsReadStrictly) {
  ScratchDir d;
  const nlohmann::json reduced = reduced_spindle4_json(d);
  auto variant = [&](const std::string& name, const std::function<void(nlohmann::json&)>& edit) {
    nlohmann::json j = reduced;
    edit(j);
    write_text(d.file(name), j.dump(2));
  };
  variant("both.json", [](nlohmann::json& j) { j["blob_file"] = "m.bin"; });
  variant("number.json", [](nlohmann::json& j) { j["blob_hex"] = 123; });
  variant("dt.json", [](nlohmann::json& j) { j["scheduled_model"]["dt_ms"] = "5000"; });
  variant("fitted.json", [](nlohmann::json& j) { j["format"] = "btsm-thermal-model-1"; });
  expect_refusals(d, {{"flash-model both.json --port /nonexistent/tty", "gives the blob twice (\"blob_hex\" and \"blob_file\")"},
                      {"flash-model number.json --port /nonexistent/tty", "\"blob_hex\" is 123, not a string"},
                      {"flash-model dt.json --port /nonexistent/tty", "dt_ms is \"5000\", not a number"},
                      {"flash-model fitted.json --port /nonexistent/tty", "a fitted model from `btsm fit`: reduce it first"},
                      {"flash-model model.json --port /nonexistent/tty", "a fitted model from `btsm fit`"}});
  // The file reduce wrote goes as far as the missing port.
  const CliResult honest = run_btsm(d, "flash-model r.json --port /nonexistent/tty");
  EXPECT_EQ(honest.code, 3) << honest.err;
}

// Metadata forms: "# ambient_channel:" with nothing after it dropped the ambient from the fitted
// model's channel map; "# Channel_Roles:" was an unknown key, ignored, and the error came later
// as a missing column.
TEST(LooseInputs, MetadataLinesThatWouldBeIgnoredAreRefused) {
  ScratchDir d;
  const std::string roles = "T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=shaft\n";
  write_text(d.file("empty.csv"), "# channel_roles: " + roles + "# ambient_channel:\n" + recording_csv(200));
  write_text(d.file("case.csv"), "# Channel_Roles: " + roles + recording_csv(200));
  expect_refusals(d, {{"fit empty.csv --preset spindle4 --out m.json", "'# ambient_channel': is empty"},
                      {"fit case.csv --preset spindle4 --out m.json", "keys are lower case: write '# channel_roles:'"}});
  EXPECT_FALSE(file_exists(d.file("m.json")));
}

}  // namespace
}  // namespace btsm::test

namespace btsm::test {
namespace {

// The third probe (27 Nov): files a run writes over what it reads or what was there, inputs read
// without end, arguments checked only after the work began. Each is refused first (exit 2), and
// the files named keep their bytes.
TEST(LooseInputs, TheSimulatorNeitherOverwritesItsInputsNorReadsWithoutEnd) {
  ScratchDir d;
  const std::string profile = "30s@6000\n30s@0\n";
  write_text(d.file("prof.txt"), profile);
  write_text(d.file("precious.csv"), "keep me\n");
  write_text(d.file("a_file"), "not a pty\n");
  write_text(d.file("small.eeprom"), std::string(10, '\xff'));
  // An ELF header for the AVR announcing a program header the file does not hold.
  std::string elf(60, '\0');
  elf.replace(0, 4, "\x7f" "ELF");
  elf[4] = 1, elf[5] = 1, elf[18] = 83, elf[28] = 52, elf[42] = 32, elf[44] = 1;
  write_text(d.file("cut.elf"), elf);
  const std::string sim = "sim-module --no-wait --duration 10s ";
  expect_refusals(d, {{sim + "--profile-file prof.txt --pty p --truth-out prof.txt", "--truth-out prof.txt is the input prof.txt"},
                      {sim + "--pty p --truth-out t.csv --eeprom t.csv", "--truth-out and --eeprom name the same file"},
                      {sim + "--pty p --eeprom /dev/zero", "EEPROM image"},
                      {sim + "--pty p --eeprom small.eeprom", "10 bytes, an EEPROM image has 1024"},
                      {sim + "--pty ''", "--pty: an empty value"},
                      {sim + "--pty p --time-scale fast", "--time-scale 'fast'"},
                      {sim + "--pty p --board avr --elf cut.elf", "cut short"}},
                  2, 20);
  EXPECT_EQ(read_text(d.file("prof.txt")), profile);
  // A start that fails at the pty leaves an existing truth file as it was.
  const CliResult r = run_btsm(d, sim + "--pty a_file --truth-out precious.csv", 20);
  EXPECT_NE(r.code, 0) << r.err;
  EXPECT_EQ(read_text(d.file("precious.csv")), "keep me\n");
}

// Negative counts meant "for ever"; --out at the module's port wrote the CSV into the link; a
// flashed image over its own input replaced the build's image with one module's key.
TEST(LooseInputs, LinkCommandsRefuseOutputsOverTheirInputs) {
  ScratchDir d;
  write_text(d.file("port"), "stands for a module port\n");
  write_text(d.file("fw.hex"), ":00000001FF\n");
  expect_refusals(d, {{"monitor --port /nonexistent/tty --count -1", "--count"},
                      {"record --port /nonexistent/tty --out r.csv --samples -1", "--samples"},
                      {"record --port /nonexistent/tty --out r.csv --duration -1", "--duration"},
                      {"record --port port --out port", "--out port is the input port"},
                      {"flash-firmware --device-id 0000de71 --new-key --hex fw.hex --out fw.hex --dry-run",
                       "--out fw.hex is the input fw.hex"}});
  EXPECT_EQ(read_text(d.file("port")), "stands for a module port\n");
  EXPECT_EQ(read_text(d.file("fw.hex")), ":00000001FF\n");
}

// The spindle4 model with every parameter `pick` selects at 1e300 (its bound widened to hold it, so
// the file loads): the model JSON and how many were set.
std::pair<std::string, int> spindle4_with_huge(const std::function<bool(const nlohmann::json& param)>& pick) {
  nlohmann::json m = nlohmann::json::parse(spindle4_model_json());
  int count = 0;
  for (auto& p : m["network"]["parameters"])
    if (pick(p)) {
      p["max"] = 1e300;
      m["parameters"][p["name"].get<std::string>()] = 1e300;
      ++count;
    }
  return {m.dump(2), count};
}

// Capacitances of 1e300 J/K load (finite, inside widened bounds) and leave modes of ~1e296 s:
// reduce sampled them every 10 s for hours. It names the time constant at once.
TEST(LooseInputs, ReduceNamesAModelTooSlowForAModule) {
  ScratchDir d;
  write_text(d.file("slow.json"), spindle4_with_huge([](const nlohmann::json& p) { return p["unit"] == "J/K"; }).first);
  expect_refusals(d, {{"reduce slow.json --speeds 4000,6000,8000 --out r.json", "slowest time constant"}}, 2, 60);
  EXPECT_FALSE(file_exists(d.file("r.json")));
}

// `--truth-out ''` wrote nothing and `flash-firmware --out ''` took the default name, silently;
// record found a directory or a missing folder as its --out only after connecting.
TEST(LooseInputs, EmptyValuesAndOutputsThatCannotBeMadeAreRefusedFirst) {
  ScratchDir d;
  expect_refusals(d, {{"sim-module --pty p --profile 1m@6000 --truth-out ''", "--truth-out: an empty value"},
                      {"flash-firmware --device-id 0000de71 --out '' --dry-run", "--out: an empty value"},
                      {"fit '' --preset spindle4 --out m.json", "File does not exist"},
                      {"record --port /nonexistent/tty --out " + d.path + " --samples 2", "a directory, not a file to write the recording to"},
                      {"record --port /nonexistent/tty --out nodir/x.csv --samples 2", "its directory nodir does not exist"},
                      {"effect-suite --list --timeout 0", "--timeout"},
                      {"record --port /nonexistent/tty --out r.csv --samples ''", "--samples: an empty value"},
                      {"sim-module --pty p --profile 1m@0 --ambient 20,1h@500", "target outside -40..85 degC"}});
}

// --score-only --reuse ran nothing and so checked nothing of the truth: a run file "/etc/passwd" or
// a kind "bogus" was scored. Held to what a run checks now.
TEST(LooseInputs, AReusedAnswerIsHeldToTheTruthChecksOfARun) {
  ScratchDir d;
  const CliResult gen = run_btsm(d, "effect-suite --set reduced --only clean_r --generate-only --out s", 120);
  ASSERT_EQ(gen.code, 0) << gen.err;
  const std::string truth_path = d.file("s/cases/clean_r/truth.json");
  const nlohmann::json truth = nlohmann::json::parse(read_text(truth_path));
  const std::string answer = R"({"verdict":"none","effect":"none","nodes":[],"rmse_before_K":0.003,"rmse_after_K":0.003})";
  for (const auto& [edit, says] : std::vector<std::pair<std::function<void(nlohmann::json&)>, std::string>>{
           {[](nlohmann::json& t) { t["runs"][0]["file"] = "/etc/passwd"; }, "not a file name in the case's folder"},
           {[](nlohmann::json& t) { t["kind"] = "bogus"; }, "kind 'bogus'"}}) {
    nlohmann::json t = truth;
    edit(t);
    write_text(truth_path, t.dump(1));
    write_text(d.file("s/cases/clean_r/residual.json"), answer);  // newer than the truth: reused
    const CliResult r = run_btsm(d, "effect-suite --set reduced --only clean_r --score-only --reuse --out s --btsm /bin/false");
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find(says), std::string::npos) << r.err;
  }
}

// The fifth probe (27 Nov): a hand-edited answer with an effect no residual run gives was scored,
// a truth id other than its folder named the row, a comma in a field shifted results.csv's columns,
// and a symlinked results.json was written through to its target.
TEST(LooseInputs, FifthProbeSuiteAnswersAndOutputs) {
  ScratchDir d;
  const CliResult gen = run_btsm(d, "effect-suite --set reduced --only clean_r --generate-only --out s", 120);
  ASSERT_EQ(gen.code, 0) << gen.err;
  const std::string truth_path = d.file("s/cases/clean_r/truth.json"), answer_path = d.file("s/cases/clean_r/residual.json");
  const std::string truth = read_text(truth_path);
  const std::string cmd = "effect-suite --set reduced --only clean_r --score-only --reuse --out s --btsm /bin/false";
  write_text(answer_path, R"({"verdict":"effect","effect":"latent_mass\n| fake | row |","nodes":[]})");
  CliResult r = run_btsm(d, cmd);
  EXPECT_NE(r.err.find("not a family the residual loop names"), std::string::npos) << r.err;
  nlohmann::json t = nlohmann::json::parse(truth);
  t["id"] = "clean_r,\"x\"";
  write_text(truth_path, t.dump(1));
  write_text(answer_path, R"({"verdict":"none","effect":"none","nodes":[],"rmse_before_K":0.003,"rmse_after_K":0.003})");
  r = run_btsm(d, cmd);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("is not the case's folder 'clean_r'"), std::string::npos) << r.err;
  write_text(truth_path, truth);
  write_text(answer_path, R"({"verdict":"none","effect":"none","nodes":[],"rmse_before_K":0.003,"rmse_after_K":0.003})");
  write_text(d.file("precious.txt"), "keep me");
  std::filesystem::remove(d.file("s/results.json"));
  std::filesystem::create_symlink(d.file("precious.txt"), d.file("s/results.json"));
  r = run_btsm(d, cmd);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(read_text(d.file("precious.txt")), "keep me");  // the link is replaced, not written through
  EXPECT_FALSE(std::filesystem::is_symlink(d.file("s/results.json")));
  std::filesystem::remove(d.file("s/results.csv"));
  std::filesystem::create_directory(d.file("s/results.csv"));
  std::filesystem::remove(d.file("s/results.json"));
  std::filesystem::remove(d.file("s/table.md"));
  r = run_btsm(d, cmd);
  EXPECT_EQ(r.code, 1) << r.err;  // was "written", exit 0
  EXPECT_NE(r.err.find("results.csv"), std::string::npos) << r.err;
  EXPECT_TRUE(file_exists(d.file("s/results.json"))) << "one output in the way cost the others";
  EXPECT_TRUE(file_exists(d.file("s/table.md")));
}

// The fifth probe: outputs named twice or unwritable only at the end, and plots written over each other.
TEST(LooseInputs, FifthProbeOutputsAreDistinctAndCheckedFirst) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("rec.csv"), recording_csv(200));
  std::filesystem::create_directories(d.file("out"));
  expect_refusals(d, {{"reduce model.json --speeds 4000,6000 --force --out out/r.json --blob ./out/../out/r.json",
                       "--blob and --out name the same file"},
                      {"sim-module --pty p --no-wait --profile 1m@0 --eeprom nodir/e.bin", "--eeprom nodir/e.bin: its directory nodir does not exist"}});
  EXPECT_FALSE(file_exists(d.file("out/r.json")));
  std::filesystem::create_directories(d.file("A"));
  std::filesystem::create_directories(d.file("B"));
  write_text(d.file("A/check.csv"), recording_csv(200));
  write_text(d.file("B/check.csv"), recording_csv(180));
  const CliResult v = run_btsm(d, "validate model.json A/check.csv B/check.csv --plots plots", 120);
  ASSERT_EQ(v.code, 0) << v.err;
  EXPECT_TRUE(file_exists(d.file("plots/validate_check.png")));
  EXPECT_TRUE(file_exists(d.file("plots/validate_check_2.png")));  // B's plot was written over A's
  // A 200 kB metadata line drawn as a panel label: the label was cut one character at a time,
  // measuring the rest each time (minutes; killed at 60 s here). Now cut before it is measured.
  write_text(d.file("long.csv"), "# speed_rpm_quantity: " + std::string(200000, 'x') + "\n" + recording_csv(200));
  const CliResult l = run_btsm(d, "validate model.json long.csv --plots plots", 60);
  EXPECT_EQ(l.code, 0) << l.err;
  EXPECT_TRUE(file_exists(d.file("plots/validate_long.png")));
}

// A probe drift in a model (README: "a measurement ... drift ... d_T1 K/h") was left out of
// validate's scores while heat and residual applied it (probe 5): a 5 K/h drift on a recording
// without one scored like none. Now the same model scores the same way everywhere.
TEST(LooseInputs, ValidateScoresAProbeDriftLikeFitAndResidual) {
  ScratchDir d;
  nlohmann::json m = nlohmann::json::parse(spindle4_model_json());
  for (auto& meas : m["network"]["measurements"])
    if (meas["column"] == "T1") meas["drift"] = "d_T1";
  m["network"]["parameters"].push_back({{"name", "d_T1"}, {"unit", "K/h"}, {"nominal", 0}, {"initial", 0}, {"min", -10},
                                         {"max", 10}, {"fixed", false}, {"log", false}});
  m["parameters"]["d_T1"] = 0.0;
  write_text(d.file("still.json"), m.dump(1));
  m["parameters"]["d_T1"] = 5.0;
  write_text(d.file("drift.json"), m.dump(1));
  write_text(d.file("rec.csv"), recording_csv(400));
  // the same recording with T1 drifting 5 K/h (rows every 10 s)
  write_text(d.file("drifted.csv"), recording_csv(400, [](int row, int col, const std::string& text) {
               if (col != 3) return text;
               char buf[32];
               std::snprintf(buf, sizeof buf, "%.4f", std::stod(text) + 5.0 * 10.0 * row / 3600.0);
               return std::string(buf);
             }));
  const auto t1_rmse = [&](const char* model, const char* rec) {
    const CliResult r = run_btsm(d, std::string("validate ") + model + " " + rec + " --json", 60);
    EXPECT_EQ(r.code, 0) << r.err;
    return nlohmann::json::parse(r.out)["recordings"][0]["nodes"]["T1"]["all"]["rmse_K"].get<double>();
  };
  const double plain = t1_rmse("still.json", "rec.csv");
  EXPECT_NEAR(t1_rmse("drift.json", "drifted.csv"), plain, 1e-3) << "the drift the model holds is part of its prediction";
  EXPECT_GT(t1_rmse("still.json", "drifted.csv"), plain + 0.1);
  // heat applies the same drift; one far beyond the recording (1e10 K/h, bounds widened) gave
  // 6.7e9 K residuals and heat in 1e10 W with exit 0. Now refused, nothing written.
  EXPECT_EQ(run_btsm(d, "heat drift.json drifted.csv --step 600 --out h5", 120).code, 0);
  m["network"]["parameters"].back()["min"] = -1e12;
  m["network"]["parameters"].back()["max"] = 1e12;
  m["parameters"]["d_T1"] = 1e10;
  write_text(d.file("absurd.json"), m.dump(1));
  const CliResult h = run_btsm(d, "heat absurd.json drifted.csv --step 600 --out habs", 120);
  EXPECT_EQ(h.code, 1) << h.err;
  EXPECT_NE(h.err.find("does not describe it"), std::string::npos) << h.err;
  EXPECT_FALSE(file_exists(d.file("habs/heat_sources.csv")));
}

// The fourth probe (27 Nov): a run a hair above a whole board step spun for ever; --channels with
// two entries left three channels unmodelled; a negative --initial-rows wrapped to 2^64 - 1.
TEST(LooseInputs, FourthProbeRunsEndAndChannelMapsAreWhole) {
  ScratchDir d;
  const CliResult run = run_btsm(d, "sim-module --pty p --no-wait --profile 1m@0 --duration 100.0000003", 30);
  EXPECT_EQ(run.code, 0) << run.err;  // 137: killed at the time limit, the old endless loop
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("rec.csv"), recording_csv(200));
  expect_refusals(d, {{"reduce model.json --speeds 4000,6000 --channels rear_bearing,housing --out r.json", "give all five channels"},
                      {"reduce model.json --speeds 4000,6000 --channels rear_bearing,rear_bearing,none,ambient,none --out r.json",
                       "one probe per node"},
                      {"validate model.json rec.csv --initial-rows -1", "--initial-rows"},
                      {"reduce model.json --speeds 4000,6000 --margin 2 --out r.json", "--margin requires --calibrate-bands"},
                      {"reduce model.json --speeds 4000,6000 --calibrate-bands rec.csv --margin 0.5 --out r.json", "--margin"},
                      // the blob refused these after the reduction (exit 1); the parser names the option
                      {"reduce model.json --speeds 4000,6000 --force --abs-limit 900 --out r.json", "--abs-limit"},
                      {"reduce model.json --speeds 4000,6000 --force --abs-limit -300 --out r.json", "--abs-limit"},
                      {"reduce model.json --speeds 4000,6000 --force --drift 1e9 --out r.json", "--drift"},
                      {"reduce model.json --speeds 4000,6000 --force --low-drift -0.1 --out r.json", "--low-drift"},
                      {"reduce model.json --speeds 4000,6000 --max-rise -1 --out r.json", "--max-rise"},
                      // probe 5 (P1): a model without an ambient channel predicted nothing on the module
                      {"reduce model.json --speeds 4000,6000 --channels rear_bearing,housing,front_bearing,none,shaft --out r.json",
                       "no channel is the ambient (--channels"}});
  EXPECT_FALSE(file_exists(d.file("r.json")));
}

// A heat source of 1e300 W (finite, inside widened bounds) overflowed the balanced analysis to
// singular values of 0 and reduce asked "are all heat sources 0 W?". It names the rise and the source.
TEST(LooseInputs, ReduceNamesAHeatSourceFarOutOfRange) {
  ScratchDir d;
  const auto [hot, count] = spindle4_with_huge([](const nlohmann::json& p) { return p["name"] == "qf1"; });
  ASSERT_EQ(count, 1) << "spindle4 has no parameter qf1";
  write_text(d.file("hot.json"), hot);
  // refused where the model is read (probe 7, P3-n), before reduce's own check at its speeds
  expect_refusals(d, {{"reduce hot.json --speeds 4000,6000,8000 --out r.json", "more than the 10000 K a recording can hold"}}, 2, 60);
  const CliResult run = run_btsm(d, "reduce hot.json --speeds 4000,6000,8000 --out r.json");
  EXPECT_NE(run.err.find("heat source is 'Qf1' = "), std::string::npos) << run.err;
  EXPECT_EQ(run.err.find("0 W?"), std::string::npos) << run.err;
  EXPECT_FALSE(file_exists(d.file("r.json")));
}

// The demo checked --effect, --elf and --out only after it had made the report folder and a key;
// effect-suite took two contradicting modes and a hand-edited answer with a key twice.
TEST(LooseInputs, DemoAndSuiteCheckTheirArgumentsFirst) {
  ScratchDir d;
  write_text(d.file("a_file"), "x\n");
  expect_refusals(d, {{"demo --out rep --effect nosuch:1", "nosuch"},
                      {"demo --out rep --board avr --elf a_file", "not an ELF file"},
                      {"demo --out a_file --board native", "--out a_file: exists and is not a directory"},
                      {"effect-suite --out s --generate-only --score-only", "excludes"}});
  EXPECT_FALSE(file_exists(d.file("rep")));
}

}  // namespace
}  // namespace btsm::test
