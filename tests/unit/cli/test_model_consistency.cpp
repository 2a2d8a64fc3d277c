// What a model, a network or a recording says about itself, held to where it is read (hostile-input
// probe 7): a probe that read nothing (F5), a node cut off from the ambient (F7) and a hand-edited
// channel map with one node on two channels (F10).
#include "cli_run.hpp"
#include "model_fixture.hpp"
#include "refusals.hpp"

#include <gtest/gtest.h>

#include <string>

namespace btsm::test {
namespace {

bool mentions(const std::string& text, const std::string& s) { return text.find(s) != std::string::npos; }

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
