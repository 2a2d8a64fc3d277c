// A network's structure is checked where it is read: a node that no chain of conducting links
// joins to the ambient (or a boundary) was found only after a whole fit, as "not stable in cooling
// mode" naming no node, or as a start value "its nodes are not measured" (hostile-input probe 7, F7).
#include "host/thermal/model_file.hpp"
#include "host/thermal/network.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace btsm::thermal {
namespace {

using nlohmann::json;

// Nodes a and b of one capacitance C, joined by `links` (terms of one resistance R).
json two_nodes(const std::vector<json>& links, double operating_above_rpm = 0.0) {
  return {{"name", "two"},
          {"operating_above_rpm", operating_above_rpm},
          {"boundaries", {"coolant_c"}},
          {"parameters", {{{"name", "C"}, {"unit", "J/K"}, {"nominal", 100.0}}, {{"name", "R"}, {"unit", "K/W"}, {"nominal", 1.0}}}},
          {"nodes", {{{"name", "a"}, {"capacitance", "C"}}, {{"name", "b"}, {"capacitance", "C"}}}},
          {"links", links}};
}

json link(const std::string& a, const std::string& b, const std::string& mode, double speed_exponent = 0.0) {
  json term = {{"resistance", "R"}};
  if (speed_exponent != 0.0) term["speed_exponent"] = speed_exponent;
  return {{"name", a + "_" + b}, {"between", {a, b}}, {mode, {term}}};
}

std::string read_error(const json& j) {
  try {
    network_from_json(j, "net.json");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(NetworkStructure, ANodeWithoutAPathToAmbientIsNamedWhenRead) {
  const std::string none = read_error(two_nodes({link("a", "ambient", "both")}));
  EXPECT_NE(none.find("net.json: network 'two': links: node 'b' has no link at all"), std::string::npos) << none;
  EXPECT_EQ(none.find("node 'a'"), std::string::npos) << none;
  const std::string island = read_error(two_nodes({link("a", "b", "both")}));
  EXPECT_NE(island.find("node 'a' has no path of links to the ambient or a boundary; node 'b' has no path"), std::string::npos)
      << island;
}

// At standstill only terms without a speed law conduct: an operating-only link, or a cooling term
// with a speed_exponent (0 at 0 rpm), leaves the node to heat for ever once the spindle stops.
TEST(NetworkStructure, APathThatConductsOnlyWhileRunningIsNamed) {
  const std::string running = read_error(two_nodes({link("a", "b", "both"), link("b", "ambient", "operating")}));
  EXPECT_NE(running.find("node 'a' reaches the ambient only while running"), std::string::npos) << running;
  EXPECT_NE(running.find("node 'b' reaches the ambient only while running"), std::string::npos) << running;
  const std::string speed_law =
      read_error(two_nodes({link("a", "b", "both"), link("b", "ambient", "both", 0.5)}, 100.0));
  EXPECT_NE(speed_law.find("node 'b' reaches the ambient only while running"), std::string::npos) << speed_law;
  const std::string stopped = read_error(two_nodes({link("a", "b", "both"), link("b", "ambient", "cooling")}));
  EXPECT_NE(stopped.find("node 'a' reaches the ambient only at standstill"), std::string::npos) << stopped;
}

// A boundary is as good as the ambient, a path through other nodes as good as a direct link.
TEST(NetworkStructure, PathsThroughNodesAndToABoundaryAreAccepted) {
  EXPECT_EQ(read_error(two_nodes({link("a", "b", "both"), link("b", "ambient", "both")})), "");
  EXPECT_EQ(read_error(two_nodes({link("a", "b", "both"), link("b", "coolant_c", "both")})), "");
  EXPECT_EQ(read_error(two_nodes({link("a", "b", "both"), link("b", "ambient", "operating"), link("a", "ambient", "cooling")})), "");
}

// The preset and every network and fitted model the tests and the README use still read.
TEST(NetworkStructure, EveryShippedNetworkAndModelIsRead) {
  EXPECT_NO_THROW(preset_network("spindle4"));
  int read = 0;
  for (const auto& e : std::filesystem::recursive_directory_iterator(BTSM_TEST_DATA_DIR)) {
    if (e.path().extension() != ".json") continue;
    json j;
    try {
      j = json::parse(std::ifstream(e.path()));
    } catch (const json::exception&) {
      continue;  // not JSON this test reads
    }
    if (!j.is_object()) continue;
    const std::string path = e.path().string();
    if (j.contains("links")) {
      EXPECT_NO_THROW(load_network(path)) << path;
      ++read;
    } else if (j.contains("network") && j.contains("parameters")) {
      EXPECT_NO_THROW(load_model(path)) << path;
      ++read;
    }
  }
  EXPECT_GE(read, 8);  // 6 networks, 2 fitted models in tests/data when this was written
}

}  // namespace
}  // namespace btsm::thermal
