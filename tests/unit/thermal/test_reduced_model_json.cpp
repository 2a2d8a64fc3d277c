// The "scheduled_model" table of a reduced-model JSON against its blob: the table reduce writes
// reads back into exactly the blob, and an edit of any field the blob encodes (or of a channel's
// node, which picks the model) is named by its path. Before, only the speeds, poles, period, mask
// and ambient channel were compared: an edited gain, detector limit or node was flashed as the
// blob's old value without a word (hostile-input probe 7, F9).
#include "host/thermal/reduce.hpp"
#include "host/thermal/reduced_model_json.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace btsm::thermal {
namespace {

struct Reduced {
  nlohmann::json table;
  std::vector<uint8_t> blob;
};

// spindle4 reduced as `btsm reduce` does (channels 1-3 modelled, 4 ambient, 5 unused), its table
// passed through the JSON text as a file would be.
const Reduced& reduced() {
  static const Reduced r = [] {
    const Network net = preset_network("spindle4");
    ReduceOptions o;
    o.speeds_rpm = {4000, 6000, 8000};
    const ScheduledReduction s = build_scheduled_model(net, test::true_parameters(net), o);
    const nlohmann::json j = nlohmann::json::parse(reduction_to_json(net, s, o).dump(2));
    return Reduced{j["scheduled_model"], s.blob};
  }();
  return r;
}

std::string edited(const char* pointer, const nlohmann::json& value) {
  nlohmann::json t = reduced().table;
  t[nlohmann::json::json_pointer(pointer)] = value;
  return scheduled_model_contradiction(t, reduced().blob);
}

TEST(ReducedModelJson, TheTableReduceWritesIsItsBlob) {
  ASSERT_EQ(reduced().blob.size(), kReducedModelBlobSize);
  EXPECT_EQ(scheduled_model_contradiction(reduced().table, reduced().blob), "");
  const ReducedModelF64 m = scheduled_model_from_json(reduced().table);
  EXPECT_EQ(m.n_breakpoints, 4);
  EXPECT_EQ(m.ambient_channel, 3);
}

TEST(ReducedModelJson, AnEditedFieldIsNamedByItsPath) {
  struct Edit {
    const char* pointer;
    nlohmann::json value;
    std::string says;
  };
  const std::vector<Edit> edits = {
      {"/breakpoints/1/b_K/0", 100.0, "at breakpoints[1].b_K[0] (breakpoint 1, channel 1 heat gain: 100 K in the table"},
      {"/breakpoints/2/a/1", 0.5, "at breakpoints[2].a[1] (breakpoint 2, channel 2 pole"},
      {"/breakpoints/3/speed_rpm", 8500, "at breakpoints[3].speed_rpm"},
      {"/channels/0/detector/abs_limit_c", 500.0, "at channels[0].detector.abs_limit_c (channel 1 absolute limit: 500 degC in the table, 80 degC"},
      {"/channels/1/detector/drift_K", 0.7, "at channels[1].detector.drift_K"},
      {"/channels/2/detector/low_drift_K", 0.9, "at channels[2].detector.low_drift_K"},
      {"/channels/0/detector/warn_evidence_K_min", 3.0, "at channels[0].detector.warn_evidence_K_min"},
      {"/channels/0/detector/alarm_evidence_K_min", 8.0, "at channels[0].detector.alarm_evidence_K_min"},
      {"/channels/0/detector/low_warn_evidence_K_min", 0.0, "at channels[0].detector.low_warn_evidence_K_min"},
      {"/channels/0/detector/max_rise_K_per_min", 0.0, "at channels[0].detector.max_rise_K_per_min"},
      {"/channels/3/abs_limit_c", 60.0, "at channels[3].abs_limit_c (channel 4 absolute limit"},
      {"/channels/0/role", "motor", "at channels[0].role (channel 1 role: motor in the table, rear_bearing in the blob)"},
      {"/channels/0/node", "shaft", "at channels[0].node (channel 1 node: \"shaft\" in the table"},
      {"/channels/3/node", "housing", "at channels[3].node"},
      {"/channels/4/node", "shaft", "at channels[4].node"},
      {"/stop_phase_end_s/0", 500, "stop_phases[0].end_s is 600, but stop_phase_end_s[0] is 500"},
      {"/stop_phases/1/a/2", 0.9, "at stop_phases[1].a[2] (stop phase 2, channel 3 pole"},
      {"/breakpoints/2/b_K/4", 1.0, "at breakpoints[2].b_K[4] (1 in the table, but the blob has no model for channel 5: 0)"},
      {"/dt_ms", 2000, "at dt_ms (sample period: 2000 ms in the table, 5000 ms in the blob)"},
      {"/enabled_mask", 31, "at enabled_mask (channel mask: 31 in the table, 15 in the blob)"},
      {"/ambient_channel", nullptr, "at ambient_channel (ambient channel: none in the table, 4 in the blob)"},
      {"/breakpoints/1/b_K/0", "0.006", "breakpoints[1].b_K[0] is \"0.006\", not a number"},
      {"/breakpoints/1/speed_rpm", 4000.5, "breakpoints[1].speed_rpm is 4000.5, not a whole number 0..65535"},
      {"/channels/0/detector", nlohmann::json::object(), "channels[0].detector.drift_K is missing"},
      {"/breakpoints/1/a/0", 1.5, "the table holds a value no blob can (pole a outside [0, 1), breakpoint 1, channel 1)"},
  };
  for (const Edit& e : edits) {
    const std::string why = edited(e.pointer, e.value);
    EXPECT_NE(why.find(e.says), std::string::npos) << e.pointer << "\n" << why;
    EXPECT_NE(why.find("re-run reduce"), std::string::npos) << e.pointer << "\n" << why;
  }
}

// A channel with a carrier (reduce gives channel 1 the slower housing's model where that helps):
// its carrier and coupling are in the blob too.
TEST(ReducedModelJson, ACarrierEditIsNamed) {
  const nlohmann::json& chans = reduced().table["channels"];
  std::size_t carried = chans.size();
  for (std::size_t j = 0; j < chans.size(); ++j)
    if (chans[j].contains("carrier_channel")) carried = j;
  if (carried == chans.size()) GTEST_SKIP() << "this reduction gave no channel a carrier";
  const std::string p = "/channels/" + std::to_string(carried);
  EXPECT_NE(edited((p + "/coupling_per_step").c_str(), 0.25).find("coupling_per_step"), std::string::npos);
  nlohmann::json t = reduced().table;
  t["channels"][carried].erase("carrier_channel");
  EXPECT_NE(scheduled_model_contradiction(t, reduced().blob).find("carrier_channel (channel " + std::to_string(carried + 1) +
                                                                  " carrier: none in the table"),
            std::string::npos);
}

}  // namespace
}  // namespace btsm::thermal
