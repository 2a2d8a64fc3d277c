// What a model, a network or a recording says about itself, held to where it is read (hostile-input
// probe 7): a node cut off from the ambient (F7).
#include "cli_run.hpp"
#include "model_fixture.hpp"
#include "refusals.hpp"

#include <gtest/gtest.h>

#include <string>

namespace btsm::test {
namespace {

bool mentions(const std::string& text, const std::string& s) { return text.find(s) != std::string::npos; }

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

}  // namespace
}  // namespace btsm::test
