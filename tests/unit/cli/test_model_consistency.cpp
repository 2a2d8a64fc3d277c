// What a model, a network or a recording says about itself, held to where it is read (hostile-input
// probe 7): the fit's own column mapping (F2), a probe that read nothing (F5), a node cut off from
// the ambient (F7) and a hand-edited channel map with one node on two channels (F10).
#include "cli_run.hpp"
#include "model_fixture.hpp"
#include "refusals.hpp"

#include <gtest/gtest.h>

#include <string>

namespace btsm::test {
namespace {

bool mentions(const std::string& text, const std::string& s) { return text.find(s) != std::string::npos; }

// A module recording as `btsm record` writes it: `roles` from the module, ch4 the ambient (recorded
// as ambient_c), the fifth probe as T5 (recording_csv's fourth temperature column).
std::string module_recording(const std::string& roles, int rows, const std::string& source = "test") {
  std::string s = recording_csv(rows);
  const std::string header = "time_s,speed_rpm,ambient_c,T1,T2,T3,T4";
  s.replace(s.find(header), header.size(), "time_s,speed_rpm,ambient_c,T1,T2,T3,T5");
  s.replace(0, s.find('\n'), "# source: " + source);
  return "# channel_roles: " + roles + "\n# ambient_channel: T4\n" + s;
}

// The module's default roles: the fifth probe is spare, and the README maps it with --column shaft=T5.
const std::string kDefaultRoles = "T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=spare";

// The spindle4 model with its nominal values as `fit --column shaft=T5` writes it from recordings
// with the default roles: the shaft measured by T5, and the channel map saying T5 was spare then.
std::string shaft_on_spare_t5_model() {
  nlohmann::json m = nlohmann::json::parse(spindle4_model_json());
  for (auto& meas : m["network"]["measurements"])
    if (meas["node"] == "shaft") meas["column"] = "T5";
  m["channel_map"][3] = {{"channel", 4}, {"column", "ambient_c"}, {"module_role", "ambient"}, {"node", "ambient"}};
  m["channel_map"][4] = {{"channel", 5}, {"column", "T5"}, {"module_role", "spare"}, {"node", "shaft"}};
  return m.dump(2);
}

// F2: the README's workflow. validate and heat refused the fit's own recordings ("the probes are
// not where the model says; refit the model with this recording"), and the refit gave the same model.
TEST(FittedChannelMap, TheModelOfFitColumnShaftT5IsScoredOnItsOwnRecordings) {
  ScratchDir d;
  write_text(d.file("rec.csv"), module_recording(kDefaultRoles, 800));
  const CliResult fit = run_btsm(d, "fit rec.csv --preset spindle4 --sum-c 20478.7 --column shaft=T5 --out m.json", 300);
  ASSERT_TRUE(file_exists(d.file("m.json"))) << fit.err;
  const auto map = nlohmann::json::parse(read_text(d.file("m.json")))["channel_map"];
  EXPECT_EQ(map[4]["module_role"], "spare");
  EXPECT_EQ(map[4]["node"], "shaft");
  for (const char* cmd : {"validate m.json rec.csv", "heat m.json rec.csv"}) {
    const CliResult r = run_btsm(d, cmd, 120);
    EXPECT_EQ(r.code, 0) << cmd << "\n" << r.err;
    EXPECT_FALSE(mentions(r.err, "not where the model says")) << cmd << "\n" << r.err;
  }
}

TEST(FittedChannelMap, ReduceAndResidualTakeItTooAndAMovedProbeIsStillRefused) {
  ScratchDir d;
  write_text(d.file("model.json"), shaft_on_spare_t5_model());
  write_text(d.file("rec.csv"), module_recording(kDefaultRoles, 800));
  write_text(d.file("check.csv"), module_recording(kDefaultRoles, 240, "check"));
  const CliResult reduce = run_btsm(d, "reduce model.json --speeds 4000,6000 --calibrate-bands rec.csv --force --out r.json", 300);
  EXPECT_EQ(reduce.code, 0) << reduce.err;
  const CliResult residual = run_btsm(d, "residual --network model.json --use-values --fit rec.csv --check check.csv "
                                         "--effects sensor_lag --threads 1", 300);
  EXPECT_EQ(residual.code, 0) << residual.err;
  EXPECT_TRUE(mentions(residual.err, "shaft=T5")) << residual.err;
  // Channel 5 disabled since the fit: whatever T5 holds now is not the probe the model was fitted on.
  write_text(d.file("moved.csv"), module_recording("T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=disabled", 800));
  const std::string moved = "moved.csv: its channel_roles put node 'shaft' on no channel, but the model measures it with T5 (T5 is disabled there)";
  expect_refusals(d, {{"validate model.json moved.csv", moved},
                      {"heat model.json moved.csv", moved},
                      {"reduce model.json --speeds 4000,6000 --calibrate-bands moved.csv --force --out r2.json", moved},
                      {"residual --network model.json --use-values --fit moved.csv --check check.csv", moved}});
  EXPECT_FALSE(file_exists(d.file("r2.json")));
}

// F5: a probe open for a whole recording. validate showed its row as "--" without a word, heat
// printed "residual rms T1: nan K" and fit said "converged" on a node it never saw.
TEST(UnsampledColumns, ValidateAndHeatSayWhichColumnAndFitRefuses) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("rec.csv"), recording_csv(400, [](int, int col, const std::string& text) { return col == 3 ? "" : text; }));
  const std::string said = "rec.csv: column 'T1' (node 'rear_bearing') has no value in any row";
  const CliResult v = run_btsm(d, "validate model.json rec.csv");
  EXPECT_EQ(v.code, 0) << v.err;
  EXPECT_TRUE(mentions(v.err, "validate: WARNING: " + std::string(said) + ": its node is not scored")) << v.err;
  const CliResult h = run_btsm(d, "heat model.json rec.csv", 120);
  EXPECT_EQ(h.code, 0) << h.err;
  EXPECT_TRUE(mentions(h.err, "heat: WARNING: " + std::string(said) + ": the heat is estimated without that probe")) << h.err;
  EXPECT_TRUE(mentions(h.out, "residual rms       T1: -- (no value in any row)")) << h.out;
  EXPECT_FALSE(mentions(h.out, "nan")) << h.out;
  write_text(d.file("rec2.csv"), "# source: second\n" + recording_csv(300, [](int, int col, const std::string& text) { return col == 3 ? "" : text; }));
  expect_refusals(d, {{"fit rec.csv rec2.csv --preset spindle4 --sum-c 20478.7 --out m.json",
                       "column 'T1' (measures node 'rear_bearing') has no value in any row of rec.csv, rec2.csv"}});
  EXPECT_FALSE(file_exists(d.file("m.json")));
}

// F7: a node without a path to the ambient was found after the whole fit ("not stable in cooling
// mode", no node named). Now the network is refused where it is read, before any stage runs.
TEST(NetworkPaths, ACutOffNodeIsNamedBeforeTheFit) {
  ScratchDir d;
  write_text(d.file("rec.csv"), recording_csv(200));
  nlohmann::json net = nlohmann::json::parse(spindle4_model_json())["network"];
  net["nodes"].push_back({{"name", "x"}, {"capacitance", "C1"}});
  write_text(d.file("isolated.json"), net.dump(2));
  const CliResult r = run_btsm(d, "fit rec.csv --network isolated.json --sum-c 20478.7 --out m.json");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_TRUE(mentions(r.err, "isolated.json: network '") && mentions(r.err, "node 'x' has no link at all")) << r.err;
  EXPECT_FALSE(mentions(r.err, "stage")) << "refused before the fit started\n" << r.err;
  EXPECT_FALSE(file_exists(d.file("m.json")));
}

// F10: a hand-edited channel map with the rear bearing on ch1 and ch5: reduce wrote a blob that
// checks probe 5 against the rear bearing's model, while --channels refuses the same map.
TEST(ChannelMapEdits, OneNodeOnTwoChannelsIsRefusedAsChannelsRefusesIt) {
  ScratchDir d;
  nlohmann::json m = nlohmann::json::parse(spindle4_model_json());
  m["channel_map"][4]["node"] = "rear_bearing";
  write_text(d.file("twice.json"), m.dump(2));
  expect_refusals(d, {{"reduce twice.json --speeds 4000,6000 --force --out r.json --blob m.bin",
                       "channel_map puts node 'rear_bearing' on channel 1 and channel 5: one probe per node"},
                      {"reduce twice.json --speeds 4000,6000 --force --out r.json --channels rear_bearing,housing,front_bearing,ambient,"
                       "rear_bearing",
                       "node 'rear_bearing' on channel 1 and channel 5: one probe per node"}});
  EXPECT_FALSE(file_exists(d.file("r.json")));
  EXPECT_FALSE(file_exists(d.file("m.bin")));
}

}  // namespace
}  // namespace btsm::test
