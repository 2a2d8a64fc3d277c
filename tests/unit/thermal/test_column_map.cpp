// `--column NODE=COLUMN`: moving, dropping and refusing measurement mappings; the same taken from
// a module recording's channel roles.
#include "host/thermal/fit.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"
#include "host/thermal/recording_metadata.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace th = btsm::thermal;

namespace {

std::string column_of(const th::Network& net, const std::string& node) {
  const int k = net.node_index(node);
  for (const auto& m : net.measurements)
    if (m.node == k) return m.column;
  return "";
}

TEST(ColumnMap, MovesTheShaftToTheFifthProbe) {
  th::Network net = th::preset_network("spindle4");
  ASSERT_EQ(column_of(net, "shaft"), "T4");
  th::remap_measurements(net, {"shaft=T5"});
  EXPECT_EQ(column_of(net, "shaft"), "T5");
  EXPECT_EQ(column_of(net, "rear_bearing"), "T1");
  EXPECT_EQ(net.measurements.size(), 4u);
}

TEST(ColumnMap, EmptyColumnDropsTheMeasurement) {
  th::Network net = th::preset_network("spindle4");
  th::remap_measurements(net, {"shaft="});
  EXPECT_EQ(column_of(net, "shaft"), "");
  EXPECT_EQ(net.measurements.size(), 3u);
}

TEST(ColumnMap, BadSpecsNameWhatIsWrong) {
  th::Network net = th::preset_network("spindle4");
  auto message = [&](const std::string& spec) {
    try {
      th::Network n = net;
      th::remap_measurements(n, {spec});
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("shaftT5").find("expected NODE=COLUMN"), std::string::npos);
  EXPECT_NE(message("spindle=T5").find("no node 'spindle'"), std::string::npos);
  EXPECT_NE(message("shaft=T1").find("already measures node 'rear_bearing'"), std::string::npos);
}

// The specs apply as a whole: two probes swapped on the machine are said with one spec each (one
// at a time, the first collided with the other's old column).
TEST(ColumnMap, TwoProbesSwapPlaces) {
  th::Network net = th::preset_network("spindle4");
  th::remap_measurements(net, {"rear_bearing=T3", "front_bearing=T1"});
  EXPECT_EQ(column_of(net, "rear_bearing"), "T3");
  EXPECT_EQ(column_of(net, "front_bearing"), "T1");
  EXPECT_EQ(net.measurements.size(), 4u);
  th::Network n2 = th::preset_network("spindle4");
  EXPECT_THROW(th::remap_measurements(n2, {"rear_bearing=T3"}), std::invalid_argument);  // T3 still the front bearing's
}

// A recording as `btsm record` writes it: ambient channel T4 is ambient_c, not a T column.
th::Recording module_recording(const std::string& roles, const std::string& source = "rec.csv") {
  std::string text = "# channel_roles: " + roles + "\n# ambient_channel: T4\n"
                     "time_s,speed_rpm,ambient_c,T1,T2,T3,T5\n0,6000,20,21,22,23,24\n5,6000,20,21,22,23,24\n";
  return th::parse_recording_csv(text, source);
}

TEST(ColumnMap, ChannelRolesOfAModuleRecordingPlaceTheProbes) {
  th::Network net = th::preset_network("spindle4");
  const auto rec = module_recording("T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=shaft");
  const std::string said = th::map_measurements(net, {rec}, {});
  EXPECT_EQ(column_of(net, "shaft"), "T5");
  EXPECT_EQ(column_of(net, "housing"), "T2");
  EXPECT_NE(said.find("shaft=T5"), std::string::npos) << said;
  EXPECT_NO_THROW(th::measurement_columns(net, rec));
}

// The recordings' roles say rear=T1, front=T3; the user knows the probes were swapped and says
// both (`fit ... --column rear_bearing=T3 --column front_bearing=T1` exited 2: "column 'T3'
// already measures node 'front_bearing'").
TEST(ColumnMap, ColumnOverridesSwapTheRolesProbes) {
  th::Network net = th::preset_network("spindle4");
  const auto rec = module_recording("T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=shaft");
  th::map_measurements(net, {rec}, {"rear_bearing=T3", "front_bearing=T1"});
  EXPECT_EQ(column_of(net, "rear_bearing"), "T3");
  EXPECT_EQ(column_of(net, "front_bearing"), "T1");
  EXPECT_EQ(column_of(net, "shaft"), "T5");
}

TEST(ColumnMap, ASpareFifthProbeLeavesTheShaftUnmeasuredAndSaysSo) {
  th::Network net = th::preset_network("spindle4");
  const auto rec = module_recording("T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=spare");
  const std::string said = th::map_measurements(net, {rec}, {});
  EXPECT_EQ(column_of(net, "shaft"), "");
  EXPECT_EQ(net.measurements.size(), 3u);
  EXPECT_NE(said.find("shaft=(none)"), std::string::npos) << said;
  // --column wins over the roles.
  th::Network explicit_net = th::preset_network("spindle4");
  th::map_measurements(explicit_net, {rec}, {"shaft=T5"});
  EXPECT_EQ(column_of(explicit_net, "shaft"), "T5");
}

TEST(ColumnMap, SwappedProbesAreFollowedWithoutACollision) {
  th::Network net = th::preset_network("spindle4");
  const auto rec = module_recording("T1=rear_bearing,T2=front_bearing,T3=housing,T4=ambient,T5=shaft");
  th::map_measurements(net, {rec}, {});
  EXPECT_EQ(column_of(net, "front_bearing"), "T2");
  EXPECT_EQ(column_of(net, "housing"), "T3");
}

TEST(ColumnMap, RolesThatAreOnlyDefaultsOrAbsentChangeNothing) {
  const th::Network preset = th::preset_network("spindle4");
  th::Network net = preset;
  const auto defaults = module_recording(
      "T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=shaft (firmware defaults, not read from the module)");
  EXPECT_EQ(th::map_measurements(net, {defaults}, {}), "");
  EXPECT_EQ(column_of(net, "shaft"), "T4");
  const auto plain = th::parse_recording_csv("time_s,speed_rpm,ambient_c,T1,T2,T3,T4\n0,0,20,20,20,20,20\n", "plain.csv");
  EXPECT_EQ(th::map_measurements(net, {plain}, {}), "");
  EXPECT_EQ(net.measurements.size(), preset.measurements.size());
}

TEST(ColumnMap, RecordingsThatDisagreeAreRefusedNamingBoth) {
  th::Network net = th::preset_network("spindle4");
  const auto a = module_recording("T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=shaft", "a.csv");
  const auto b = module_recording("T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=spare", "b.csv");
  try {
    th::map_measurements(net, {a, b}, {});
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("'shaft'"), std::string::npos) << m;
    EXPECT_NE(m.find("a.csv"), std::string::npos) << m;
    EXPECT_NE(m.find("b.csv"), std::string::npos) << m;
    EXPECT_NE(m.find("--column shaft="), std::string::npos) << m;
  }
  EXPECT_NO_THROW(th::map_measurements(net, {a, b}, {"shaft=T5"}));  // told explicitly: fine
}

// The channel map `fit --column shaft=T5` writes from recordings with the default roles (ch5 spare,
// ch4 the ambient, recorded as ambient_c).
const char* kDefaultRoles = "T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=spare";
std::vector<th::FittedChannel> shaft_fitted_on_spare_t5() {
  return {{"T1", "rear_bearing", "rear_bearing"}, {"T2", "housing", "housing"}, {"T3", "front_bearing", "front_bearing"},
          {"ambient_c", "ambient", "ambient"},    {"T5", "spare", "shaft"}};
}

th::Network shaft_on_t5() {
  th::Network net = th::preset_network("spindle4");
  th::remap_measurements(net, {"shaft=T5"});
  return net;
}

std::string mapping_error(const std::vector<th::FittedChannel>& fitted, const std::string& roles) {
  try {
    th::check_mapping_agrees_with_roles(shaft_on_t5(), fitted, {module_recording(roles)}, {}, "ADVICE");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

// Probe 7 (F2): the README's model (fit --column shaft=T5 on module recordings, T5 spare) was refused
// by validate, heat, reduce --calibrate-bands and residual --use-values on its own fit recordings:
// "the probes are not where the model says; refit" -- and the refit gave the same model. The fit's
// channel map says it mapped the spare channel on purpose; recordings laid out as then are scored.
TEST(ColumnMap, AMappingTheFitMadeAgainstTheRolesHoldsOnRecordingsWithThoseRoles) {
  EXPECT_EQ(mapping_error(shaft_fitted_on_spare_t5(), kDefaultRoles), "");
  // The module now naming the shaft probe agrees with the model as well.
  EXPECT_EQ(mapping_error(shaft_fitted_on_spare_t5(), "T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=shaft"), "");
  // Without a map (a model fitted before btsm kept one) the roles are all there is to go by.
  EXPECT_NE(mapping_error({}, kDefaultRoles).find("put node 'shaft' on no channel, but the model measures it with T5 (T5 is spare there)"),
            std::string::npos);
  // A map that does not say the fit measured the shaft with T5 excuses nothing.
  auto unmapped = shaft_fitted_on_spare_t5();
  unmapped.back().node = "";
  EXPECT_NE(mapping_error(unmapped, kDefaultRoles).find("node 'shaft'"), std::string::npos);
}

TEST(ColumnMap, AProbeMovedSinceTheFitIsStillRefused) {
  const auto fitted = shaft_fitted_on_spare_t5();
  EXPECT_NE(mapping_error(fitted, "T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=disabled")
                .find("put node 'shaft' on no channel, but the model measures it with T5 (T5 is disabled there): the probes are not "
                      "where the model says; ADVICE"),
            std::string::npos);
  EXPECT_NE(mapping_error(fitted, "T1=housing,T2=rear_bearing,T3=front_bearing,T4=ambient,T5=spare")
                .find("put node 'housing' on T1, but the model measures it with T2 (T2 is rear_bearing there)"),
            std::string::npos);
  // The roles now put the shaft on a channel of its own: not where the fit had it.
  EXPECT_NE(mapping_error(fitted, "T1=rear_bearing,T2=housing,T3=shaft,T4=ambient,T5=front_bearing").find("rec.csv: its channel_roles"),
            std::string::npos);
}

// Probe 7 (F5): T5 empty in every row of every recording, mapped by --column shaft=T5, and the fit
// said "converged" with a channel map that has T5 measure the shaft.
TEST(ColumnMap, AMeasuredColumnWithNoValueInAnyRecordingIsRefusedByTheFit) {
  auto rec = [](const std::string& source, const std::string& t5) {
    return th::parse_recording_csv("time_s,speed_rpm,ambient_c,T1,T2,T3,T5\n0,6000,20,21,22,23,\n5,6000,20,21,22,23," + t5 + "\n", source);
  };
  const th::Network net = shaft_on_t5();
  ASSERT_EQ(th::unsampled_measurements(net, rec("a.csv", "")).size(), 1u);
  try {
    th::fit_network(net, {rec("a.csv", ""), rec("b.csv", "")});
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("column 'T5' (measures node 'shaft') has no value in any row of a.csv, b.csv"), std::string::npos)
        << e.what();
  }
  // One value in one recording is a probe that reads (gaps are the fit's to bridge).
  EXPECT_NO_THROW(th::refuse_unsampled_measurements(net, {rec("a.csv", ""), rec("b.csv", "24")}));
  EXPECT_TRUE(th::unsampled_measurements(net, rec("b.csv", "24")).empty());
  const auto said = th::unsampled_measurement_warnings(net, rec("a.csv", ""), "WHAT NOW");
  ASSERT_EQ(said.size(), 1u);
  EXPECT_EQ(said[0], "a.csv: column 'T5' (node 'shaft') has no value in any row: WHAT NOW");
}

// What a reader refuses in the metadata, before any command maps a probe: the entry is named.
TEST(ColumnMap, ContradictoryRoleMetadataIsRefusedWhenRead) {
  auto read = [](const std::string& meta) {
    return th::parse_recording_csv(meta + "time_s,speed_rpm,ambient_c,T1,T2,T3,T5\n0,6000,20,21,22,23,24\n", "m.csv");
  };
  auto message = [&](const std::string& meta) {
    try {
      read(meta);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  EXPECT_NE(message("# channel_roles: T1=rear_bearing,T2=housing,T3=housing,T4=ambient\n").find("'housing' is on two channels, T2 and T3"),
            std::string::npos);
  EXPECT_NE(message("# channel_roles: T1=ambient,T4=ambient\n").find("'ambient' is on two channels"), std::string::npos);
  EXPECT_NE(message("# channel_roles: T1\n").find("not COLUMN=ROLE"), std::string::npos);
  EXPECT_NE(message("# channel_roles: T1=bearing\n").find("unknown role 'bearing'"), std::string::npos);
  EXPECT_NE(message("# ambient_channel: ambient\n").find("not a module channel"), std::string::npos);
  EXPECT_NE(message("# channel_roles: T1=rear_bearing,T4=ambient\n# ambient_channel: T5\n").find("where T4 is the ambient"),
            std::string::npos);
  // Spare, disabled and unknown channels may repeat; defaults are not read as roles at all.
  EXPECT_NO_THROW(read("# channel_roles: T1=rear_bearing,T2=spare,T3=spare,T4=ambient,T5=disabled\n# ambient_channel: T4\n"));
  EXPECT_NO_THROW(read("# channel_roles: T1=unknown,T2=unknown,T4=ambient\n"));
  EXPECT_NO_THROW(read("# channel_roles: T1=housing,T2=housing (firmware defaults, not read from the module)\n"));
  // A role on a channel the module does not have was ignored, while "# ambient_channel: T9" was
  // refused (probe 7, P3-g): refused alike.
  EXPECT_NE(message("# channel_roles: T1=rear_bearing,T4=ambient,T9=shaft\n").find("entry 'T9=shaft': 'T9' is not a module channel (T1..T5)"),
            std::string::npos);
}

// "# channel_roles = ...", "## channel_roles: ..." and "# channel-roles: ..." were read as other
// keys and ignored without a word, so swapped probes in them were scored (probe 7, P3-f). A '#'
// line may be a comment, so they are not refused: each is warned about, quoting the line.
TEST(ColumnMap, MetadataLinesThatLookLikeAKeyAreWarnedAbout) {
  auto warnings = [](const std::string& meta) {
    return th::metadata_warnings(th::parse_recording_csv(meta + "time_s,speed_rpm,ambient_c,T1,T2\n0,6000,20,21,22\n", "m.csv"));
  };
  const std::string roles = "T1=housing,T2=rear_bearing";
  for (const std::string& line : std::vector<std::string>{"# channel_roles = " + roles, "## channel_roles: " + roles, "# channel-roles: " + roles,
                                  "# Channel roles: " + roles, "#  ambient channel: T4"}) {
    const auto w = warnings(line + "\n");
    ASSERT_EQ(w.size(), 1u) << line;
    EXPECT_NE(w[0].find("m.csv: the line '"), std::string::npos) << w[0];
    EXPECT_NE(w[0].find("what it says is ignored"), std::string::npos) << w[0];
  }
  EXPECT_NE(warnings("## channel_roles: " + roles + "\n")[0].find("'## channel_roles: T1=housing,T2=rear_bearing' is not read as '# channel_roles:'"),
            std::string::npos);
  // the keys themselves, with or without blanks, and comments that only mention them, say nothing
  for (const std::string& line : std::vector<std::string>{"# channel_roles: " + roles, "#channel_roles:" + roles, "# channel roles were swapped on 3 Nov",
                                  "# source: btsm record", "# note: channel_roles checked"})
    EXPECT_TRUE(warnings(line + "\n").empty()) << line;
}

}  // namespace
