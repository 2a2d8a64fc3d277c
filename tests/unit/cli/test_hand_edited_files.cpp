// Files of our own (reduced.json, an effect suite's truth.json and residual.json, recordings)
// edited by hand, as the seventh hostile-input probe did: what was taken silently or shown raw.
// Each is now refused (exit 2) naming the file and the field, or shown escaped; the file the tool
// wrote itself still passes.
#include "cli_run.hpp"
#include "model_fixture.hpp"
#include "refusals.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <functional>
#include <string>
#include <vector>

namespace btsm::test {
namespace {

bool mentions(const CliResult& r, const std::string& s) { return r.err.find(s) != std::string::npos; }

// F9: flash-model compared only the poles, speeds, period, mask and ambient of scheduled_model
// with blob_hex. A raised limit, an edited gain or another node passed, and the module got the
// blob's old values.
TEST(HandEditedFiles, AReducedModelTableEditedAnywhereIsNotFlashed) {
  ScratchDir d;
  const nlohmann::json reduced = reduced_spindle4_json(d);
  auto variant = [&](const std::string& name, const char* pointer, const nlohmann::json& value) {
    nlohmann::json j = reduced;
    j["scheduled_model"][nlohmann::json::json_pointer(pointer)] = value;
    write_text(d.file(name), j.dump(2));
  };
  variant("gain.json", "/breakpoints/1/b_K/0", 100.0);
  variant("limit.json", "/channels/0/detector/abs_limit_c", 500.0);
  variant("node.json", "/channels/0/node", "shaft");
  variant("rise.json", "/channels/2/detector/max_rise_K_per_min", 9.0);
  expect_refusals(d, {{"flash-model gain.json --port /nonexistent/tty", "at breakpoints[1].b_K[0] (breakpoint 1, channel 1 heat gain: 100 K"},
                      {"flash-model limit.json --port /nonexistent/tty",
                       "\"blob_hex\" contradicts \"scheduled_model\" at channels[0].detector.abs_limit_c (channel 1 absolute limit: "
                       "500 degC in the table, 80 degC in the blob)"},
                      {"flash-model node.json --port /nonexistent/tty", "at channels[0].node (channel 1 node: \"shaft\" in the table"},
                      {"flash-model rise.json --port /nonexistent/tty", "at channels[2].detector.max_rise_K_per_min"}});
  const CliResult r = run_btsm(d, "flash-model limit.json --port /nonexistent/tty");
  EXPECT_TRUE(mentions(r, "limit.json: ") && mentions(r, "re-run reduce")) << r.err;
  // The file reduce wrote goes as far as the missing port (exit 3).
  const CliResult honest = run_btsm(d, "flash-model r.json --port /nonexistent/tty");
  EXPECT_EQ(honest.code, 3) << honest.err;
}

// F6 and P3-i: effect-suite --score-only --reuse printed a residual.json's node names and a
// truth.json's family raw (ESC [ 2 J cleared the screen, a newline forged a progress line and a
// table row), scored a negative RMSE, goal_factor -1 and accepted_names of another family, and
// ran a residual.json with a key twice again, overwriting it. Each is refused now (exit 2),
// naming the file and the key, and shown escaped.
TEST(HandEditedFiles, SuiteFilesTheScoringCannotTakeAreRefused) {
  ScratchDir d;
  const std::string id = "temperature_dependent_heat_rising_r";
  const CliResult gen = run_btsm(d, "effect-suite --set reduced --only " + id + " --generate-only --out s", 120);
  ASSERT_EQ(gen.code, 0) << gen.err;
  const std::string truth_path = d.file("s/cases/" + id + "/truth.json"), answer_path = d.file("s/cases/" + id + "/residual.json");
  const nlohmann::json truth = nlohmann::json::parse(read_text(truth_path));
  const std::string node = truth["nodes"][0].get<std::string>();
  const nlohmann::json good = {{"verdict", "effect"}, {"effect", "temperature_dependent_heat"}, {"nodes", truth["nodes"]},
                               {"rmse_before_K", 1.0}, {"rmse_after_K", 0.1}, {"seconds", 3}};
  const std::string cmd = "effect-suite --set reduced --only " + id + " --score-only --reuse --out s --btsm /bin/false";
  // the truth first (the answer is written after it: newer, so reused)
  const auto run = [&](const std::function<void(nlohmann::json&)>& edit_truth, const std::string& answer) {
    nlohmann::json t = truth;
    if (edit_truth) edit_truth(t);
    write_text(truth_path, t.dump(1));
    write_text(answer_path, answer);
    return run_btsm(d, cmd);
  };
  struct Case {
    std::function<void(nlohmann::json&)> truth;
    std::string answer, says;
  };
  nlohmann::json esc_nodes = good, negative = good;
  esc_nodes["nodes"].push_back("\u001b[2J\u001b[31mFAKE\nfake line");
  negative["rmse_before_K"] = -1.0;
  negative["rmse_after_K"] = -5.0;
  const std::vector<Case> cases = {
      {{}, esc_nodes.dump(), "residual.json: 'nodes' holds \"\\u001b[2J\\u001b[31mFAKE\\nfake line\", not a node name"},
      {[](nlohmann::json& t) { t["family"] = "temperature_dependent_heat\u001b[2J"; },
       good.dump(), "truth.json: family 'temperature_dependent_heat\\x1b[2J' is not the case's family 'temperature_dependent_heat'"},
      {{}, negative.dump(), "residual.json: 'rmse_before_K' is -1.0, not an RMSE"},
      {[](nlohmann::json& t) { t["goal_factor"] = -1; }, good.dump(), "truth.json: 'goal_factor' is -1, not a cut of the check RMSE"},
      {[](nlohmann::json& t) { t["accepted_names"] = {"sensor_lag"}; }, good.dump(),
       "truth.json: 'accepted_names' holds \"sensor_lag\", not a name of family 'temperature_dependent_heat'"},
      {{}, R"({"verdict":"none","verdict":"effect","effect":"temperature_dependent_heat","nodes":[")" + node + R"("]})",
       "residual.json: key \"verdict\" is given twice"},
      {{}, good.dump().substr(0, 40), "residual.json: not valid JSON"}};
  for (const Case& c : cases) {
    const CliResult r = run(c.truth, c.answer);
    EXPECT_EQ(r.code, 2) << c.says << "\n" << r.err;
    EXPECT_TRUE(mentions(r, c.says)) << r.err;
    EXPECT_EQ(r.err.find('\x1b'), std::string::npos) << r.err;
    EXPECT_EQ(r.out.find('\x1b'), std::string::npos) << r.out;
  }
  // the cut-short answer (the last one) is named, not run again and overwritten (the --btsm here fails)
  EXPECT_NE(read_text(answer_path), "") << "the cut-short answer was replaced";
  EXPECT_EQ(read_text(answer_path), good.dump().substr(0, 40));
  // the files the suite wrote, with an honest answer, are scored
  const CliResult honest = run({}, good.dump());
  EXPECT_EQ(honest.code, 0) << honest.err;
  EXPECT_TRUE(mentions(honest, ", named")) << honest.err;
}

}  // namespace
}  // namespace btsm::test
