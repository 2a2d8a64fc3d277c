// Network and model JSON readers against hostile input (probe 7, P3-h, P3-n, P3-o): names given
// twice, a node named like a reserved link end, a parameter used in two units, a number beyond
// double range, an unknown top-level key in a model, and absurd values that were called "not
// stable" of a stable network.
#include "host/io/input_error.hpp"
#include "host/io/json_input.hpp"
#include "host/thermal/model_file.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/validate.hpp"
#include "test_support.hpp"

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

// --- model JSON ---------------------------------------------------------------------------------

json spindle4_model() {
  const Network net = preset_network("spindle4");
  const Eigen::VectorXd p = default_parameters(net);
  json j;
  j["format"] = kFittedModelFormat;
  j["network"] = network_to_json(net);
  for (int i = 0; i < net.param_count(); ++i) j["parameters"][net.params[static_cast<std::size_t>(i)].name] = p[i];
  return j;
}

std::string model_error(const json& j) {
  try {
    model_from_json(j, "model.json");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

// What `fit` writes (model_to_json, every key it emits) and the models shipped in tests/data read.
TEST(HostileModelJson, ModelsTheToolWritesStillRead) {
  const Network net = preset_network("spindle4");
  FitResult fit;
  fit.params = default_parameters(net);
  for (int i = 0; i < net.param_count(); ++i) {
    const Parameter& p = net.params[static_cast<std::size_t>(i)];
    fit.estimates.push_back({p.name, p.unit, fit.params[i], 0.0, Identifiability::Good, false, "note"});
  }
  fit.stages.push_back({});
  fit.warnings = {"a warning"};
  const std::vector<Recording> recs{read_recording_csv(test::ref_dir() + "/" + test::warmup_files()[0])};
  const json written = model_to_json(net, fit, recs);
  for (const char* key : {"format", "network", "parameters", "sigma", "sigma_note", "units", "identifiability", "notes", "gauge",
                          "fit", "recordings", "warnings", "channel_map"})
    EXPECT_TRUE(written.contains(key)) << key;
  EXPECT_EQ(model_error(written), "");
  for (const char* file : {"/incubator-dt/result/lid2021_events/model_lid.json", "/incubator-dt/result/lid2021_events/model_base.json"})
    EXPECT_NO_THROW(load_model(std::string(BTSM_TEST_DATA_DIR) + file)) << file;
}

// "paramters" was ignored without a word.
TEST(HostileModelJson, AnUnknownTopLevelKeyIsRefusedWithTheNearestKnownOne) {
  json typo = spindle4_model();
  typo["paramters"] = json::object();
  const std::string t = model_error(typo);
  EXPECT_TRUE(has(t, "model.json: unknown top-level key \"paramters\" (did you mean 'parameters'?)")) << t;

  json other = spindle4_model();
  other["zzz_custom"] = 1;
  const std::string o = model_error(other);
  EXPECT_TRUE(has(o, "unknown top-level key \"zzz_custom\"")) << o;
  EXPECT_FALSE(has(o, "did you mean")) << o;

  // the typo of a required key is named, not just "needs 'parameters'"
  json missing = spindle4_model();
  missing["paramters"] = missing["parameters"];
  missing.erase("parameters");
  EXPECT_TRUE(has(model_error(missing), "did you mean 'parameters'?")) << model_error(missing);
  // informative blocks stay open: what is inside "notes" or "fit" is not checked
  json open = spindle4_model();
  open["notes"] = {{"anything", "free text"}};
  open["fit"] = {{"extra", 1}};
  EXPECT_EQ(model_error(open), "");
}

// A capacitance of 1e300 J/K (or 1e-300) was "not stable ... heat that grows with temperature
// faster than it flows away" of a stable network: its time constants are beyond resolution.
TEST(HostileModelJson, AbsurdCapacitancesAreNamedAsTimeConstantsNotAsInstability) {
  for (const double c : {1e300, 1e-300}) {
    json m = spindle4_model();
    for (auto& p : m["network"]["parameters"])
      if (p["name"] == "C1") p["min"] = 1e-300, p["max"] = 1e300;
    m["parameters"]["C1"] = c;
    const std::string e = model_error(m);
    EXPECT_TRUE(has(e, "time constants too far apart to simulate at 0 rpm: ")) << e;
    EXPECT_TRUE(has(e, "node 'rear_bearing'") && has(e, "C1 = ")) << e;
    EXPECT_FALSE(has(e, "not stable")) << e;
  }
}

// A 5 MW heat source made validate say the prediction diverges because "the network is not
// stable"; it is stable, its steady rise is 1.6e6 K.
TEST(HostileModelJson, AnAbsurdHeatSourceIsNamedAsSuchNotAsInstability) {
  json m = spindle4_model();
  for (auto& p : m["network"]["parameters"])
    if (p["name"] == "qf1") p["max"] = 1e7;
  m["parameters"]["qf1"] = 5e6;
  const std::string e = model_error(m);
  EXPECT_TRUE(has(e, "at 5000 rpm its heat would settle node 'rear_bearing' ")) << e;
  EXPECT_TRUE(has(e, "K above ambient, more than the 10000 K a recording can hold (the network is stable there")) << e;
  EXPECT_TRUE(has(e, "its largest heat source is 'Qf1' = 5e+06 W")) << e;
  EXPECT_FALSE(has(e, "not stable")) << e;
}

// Heat that grows with the node's own rise faster than its links carry it away: still "not
// stable", at a read and where validate's prediction leaves the range at a faster speed.
TEST(HostileModelJson, AGenuinelyUnstableNetworkIsStillReportedAsNotStable) {
  json net = incubator();
  net["parameters"].push_back({{"name", "k"}, {"unit", "W/K"}, {"nominal", 5.0}, {"min", -100}, {"max", 100}, {"log", false}});
  net["sources"].push_back({{"name", "runaway"}, {"node", "heater"},
                            {"operating", {{{"power", "k"}, {"speed_exponent", 1}, {"driven_by", {"heater", "ambient"}}}}}});
  json m = {{"network", net}, {"parameters", {{"C_heater", 300}, {"C_air", 200}, {"R_heater_air", 1}, {"R_box", 2}, {"q_heater", 1}, {"k", 5}}}};
  const std::string at_read = model_error(m);
  EXPECT_TRUE(has(at_read, "not stable in operating mode at 1 rpm")) << at_read;

  // stable at the reference speed (k = 0.1 W/K against 1/3 W/K to ambient), not at 10x it
  m["parameters"]["k"] = 0.1;
  const FittedModel fm = model_from_json(m, "model.json");
  Recording rec;
  rec.source = "rec.csv";
  rec.time_s = {0, 1000};
  rec.speed_rpm = {10, 10};
  rec.ambient_c = {20, 20};
  Eigen::MatrixXd predicted(2, 2);
  predicted << 20, 20, 1e5, 50;
  const std::string diverges = prediction_problem(fm.network, fm.params, predicted, rec);
  EXPECT_TRUE(has(diverges, "the model's prediction diverges: node 'heater' at t = 1000 s (10 rpm) is 1e+05 degC: not stable in "
                            "operating mode at 10 rpm"))
      << diverges;

  // stable at every speed but absurdly hot at this one: said so
  m["parameters"]["k"] = 0.0;
  m["parameters"]["q_heater"] = 10.0;
  const FittedModel hot = model_from_json(m, "model.json");
  rec.speed_rpm = {5000, 5000};
  const std::string too_hot = prediction_problem(hot.network, hot.params, predicted, rec);
  EXPECT_TRUE(has(too_hot, "at 5000 rpm its heat would settle node 'heater' ") && has(too_hot, "the network is stable there")) << too_hot;
  EXPECT_FALSE(has(too_hot, "not stable")) << too_hot;
}

}  // namespace
}  // namespace btsm::thermal
