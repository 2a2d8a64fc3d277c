// Network and model JSON readers against hostile input (probe 7, P3-h, P3-n, P3-o): names given
// twice, a node named like a reserved link end, a parameter used in two units, a number beyond
// double range, an unknown top-level key in a model, and absurd values that were called "not
// stable" of a stable network.
#include "host/io/input_error.hpp"
#include "host/io/json_input.hpp"
#include "host/thermal/network.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace btsm::thermal {
namespace {

using nlohmann::json;

// Nodes heater and air, heater - air - ambient, a heat source at the heater: the probe's
// incubator network in small.
json incubator() {
  return json::parse(R"({
    "name": "inc", "speed_ref_rpm": 1.0,
    "parameters": [
      {"name": "C_heater", "unit": "J/K", "nominal": 300},
      {"name": "C_air", "unit": "J/K", "nominal": 200},
      {"name": "R_heater_air", "unit": "K/W", "nominal": 1},
      {"name": "R_box", "unit": "K/W", "nominal": 2},
      {"name": "q_heater", "unit": "W", "nominal": 1, "min": 0, "max": 10, "log": false}],
    "nodes": [{"name": "heater", "capacitance": "C_heater"}, {"name": "air", "capacitance": "C_air"}],
    "links": [
      {"name": "R_heater_air", "between": ["heater", "air"], "both": [{"resistance": "R_heater_air"}]},
      {"name": "R_box", "between": ["air", "ambient"], "both": [{"resistance": "R_box"}]}],
    "sources": [{"name": "Q_heater", "node": "heater", "operating": [{"power": "q_heater", "speed_exponent": 1}]}],
    "measurements": [{"column": "box_avg", "node": "air"}]
  })");
}

std::string network_error(const json& j) {
  try {
    network_from_json(j, "net.json");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(HostileNetworkJson, TheFixtureReads) { EXPECT_EQ(network_error(incubator()), ""); }

// A second link of one name was accepted (dup_link.json); a second node of one name surfaced as
// "link 'R_heater_air': unknown node 'air'" (dup_node_name.json). Both entries are named now.
TEST(HostileNetworkJson, NamesGivenTwiceAreRefusedNamingBothEntries) {
  json dup_link = incubator();
  dup_link["links"].push_back(dup_link["links"][0]);
  const std::string link = network_error(dup_link);
  EXPECT_TRUE(has(link, "net.json: ") && has(link, "two links are named 'R_heater_air' (links[0] and links[2])")) << link;

  json dup_node = incubator();
  dup_node["nodes"][1]["name"] = "heater";
  const std::string node = network_error(dup_node);
  EXPECT_TRUE(has(node, "net.json: nodes: two nodes are named 'heater' (nodes[0] and nodes[1])")) << node;
  EXPECT_FALSE(has(node, "unknown node")) << node;

  json dup_param = incubator();
  dup_param["parameters"][1]["name"] = "C_heater";
  const std::string param = network_error(dup_param);
  EXPECT_TRUE(has(param, "two parameters are named 'C_heater' (parameters[0] and parameters[1])")) << param;

  json dup_source = incubator();
  dup_source["sources"].push_back(dup_source["sources"][0]);
  const std::string source = network_error(dup_source);
  EXPECT_TRUE(has(source, "two sources are named 'Q_heater' (sources[0] and sources[1])")) << source;
}

// A node renamed 'ambient' surfaced as "unknown node 'heater'"; one named like a declared boundary
// column could never be reached by a link (the name means the column).
TEST(HostileNetworkJson, ANodeNamedLikeAReservedLinkEndIsRefusedAsSuch) {
  json amb = incubator();
  amb["nodes"][0]["name"] = "ambient";
  const std::string a = network_error(amb);
  EXPECT_TRUE(has(a, "net.json: nodes[0]: 'ambient' is reserved")) << a;
  EXPECT_FALSE(has(a, "unknown node")) << a;

  json bnd = incubator();
  bnd["boundaries"] = {"coolant_c"};
  bnd["nodes"][0]["name"] = "coolant_c";
  const std::string b = network_error(bnd);
  EXPECT_TRUE(has(b, "nodes[0]: 'coolant_c' is a declared boundary column")) << b;
}

// A capacitance naming a resistance parameter was "parameter 'R_box' enters non-linearly; give it
// an initial value", from the fit. The same parameter in two terms of one unit stays allowed.
TEST(HostileNetworkJson, AParameterUsedInTwoUnitsIsRefusedWhenRead) {
  json cap = incubator();
  cap["nodes"][1]["capacitance"] = "R_box";
  const std::string c = network_error(cap);
  EXPECT_TRUE(has(c, "parameter 'R_box': used as the capacitance of node 'air' (J/K) and as a resistance in link 'R_box' (K/W)"))
      << c;

  json power = incubator();
  power["sources"][0]["operating"][0]["power"] = "R_box";
  const std::string p = network_error(power);
  EXPECT_TRUE(has(p, "parameter 'R_box': used as a resistance in link 'R_box' (K/W) and as a heat in source 'Q_heater' (W)")) << p;

  json shared = incubator();
  shared["links"][0]["both"][0]["resistance"] = "R_box";  // two resistances of one value: a choice
  shared["nodes"][1]["capacitance"] = "C_heater";
  EXPECT_EQ(network_error(shared), "");
}

// The JSON library's message for 1e400 named the number only.
TEST(HostileNetworkJson, ANumberBeyondDoubleRangeIsPlacedByLineColumnAndKey) {
  const std::string text = "{\n  \"parameters\": [\n    {\"name\": \"R\", \"max\": 1e400}\n  ]\n}\n";
  try {
    io::parse_json_text(text, "net.json");
    FAIL() << "1e400 accepted";
  } catch (const io::InputError& e) {
    const std::string m = e.what();
    EXPECT_TRUE(has(m, "net.json: not valid JSON: at line 3, column 26 (parameters[].max): number '1e400' is beyond the range")) << m;
    EXPECT_FALSE(has(m, "json.exception")) << m;
  }
  try {
    io::parse_json_text("[1, -2e999]", "x.json");
    FAIL() << "-2e999 accepted";
  } catch (const io::InputError& e) {
    EXPECT_TRUE(has(e.what(), "at line 1, column 5 ([]): number '-2e999'")) << e.what();
  }
}

}  // namespace
}  // namespace btsm::thermal
