// Files of our own (reduced.json, an effect suite's truth.json and residual.json, recordings)
// edited by hand, as the seventh hostile-input probe did: what was taken silently or shown raw.
// Each is now refused (exit 2) naming the file and the field, or shown escaped; the file the tool
// wrote itself still passes.
#include "cli_run.hpp"
#include "model_fixture.hpp"
#include "refusals.hpp"

#include "host/io/json_input.hpp"
#include "host/io/utf8_text.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <functional>
#include <string>
#include <utility>
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

// P3-b: characters a terminal shows as nothing or as a space reached the messages unchanged: a BOM
// inside a row was "bad number '8000'" (it looked like a good one), a no-break space "bad number '
// 20.0'", a header "T1" + zero-width space "no column 'T1' ... columns: T1 T2" (the same name,
// seen). They are shown as \u{...} now, in every message (io::printable).
TEST(HandEditedFiles, InvisibleCharactersAreShownInMessages) {
  EXPECT_EQ(io::printable("a\xEF\xBB\xBF" "b\xC2\xA0" "c\xE2\x80\x8B" "d\xE2\x80\xAE" "e\xE2\x80\xA8" "f\xF3\xA0\x80\x81"),
            "a\\u{feff}b\\u{00a0}c\\u{200b}d\\u{202e}e\\u{2028}f\\u{e0001}");
  // visible text, a plain space and non-ASCII letters and signs stay as they are
  EXPECT_EQ(io::printable("20 \xC2\xB0" "C \xC3\xA4 \xE2\x80\x93 \xE2\x82\xAC"), "20 \xC2\xB0" "C \xC3\xA4 \xE2\x80\x93 \xE2\x82\xAC");
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  auto cell = [](int row, int col, const char* text) {
    return [=](int r, int c, const std::string& t) { return r == row && c == col ? std::string(text) : t; };
  };
  write_text(d.file("bom.csv"), recording_csv(200, cell(50, 1, "\xEF\xBB\xBF" "6000")));
  write_text(d.file("nbsp.csv"), recording_csv(200, cell(50, 3, "\xC2\xA0" "20.0")));
  std::string zwsp = recording_csv(200);
  zwsp.replace(zwsp.find(",T1,"), 4, ",T1\xE2\x80\x8B,");
  write_text(d.file("zwsp.csv"), zwsp);
  expect_refusals(d, {{"validate model.json bom.csv", "column 'speed_rpm': bad number '\\u{feff}6000'"},
                      {"validate model.json nbsp.csv", "column 'T1': bad number '\\u{00a0}20.0'"},
                      {"validate model.json zwsp.csv", "columns: T1\\u{200b} T2"}});
}

// P3-h: the JSON library's ids ("[json.exception.parse_error.101]", "[json.exception.type_error.302]")
// stood in front of the human part of messages. They are left out now; the text after them stays.
TEST(HandEditedFiles, MessagesCarryNoJsonLibraryIds) {
  EXPECT_EQ(io::without_json_exception_ids("m.json: not valid JSON: [json.exception.parse_error.101] parse error at line 1"),
            "m.json: not valid JSON: parse error at line 1");
  EXPECT_EQ(io::without_json_exception_ids("a ([json.exception.type_error.302] type must be string, but is number)"),
            "a (type must be string, but is number)");
  EXPECT_EQ(io::without_json_exception_ids("[json.exception.x] [no id] [json.exception"), "[no id] [json.exception");
  ScratchDir d;
  write_text(d.file("rec.csv"), recording_csv(200));
  write_text(d.file("cut.json"), spindle4_model_json().substr(0, 300));
  nlohmann::json m = nlohmann::json::parse(spindle4_model_json());
  m["channel_map"][0]["channel"] = "1";
  write_text(d.file("shape.json"), m.dump(2));
  for (const auto& [args, says] : std::vector<std::pair<std::string, std::string>>{
           {"validate cut.json rec.csv", "cut.json: not valid JSON: parse error at line"},
           {"reduce shape.json --speeds 4000,6000 --out r.json", "and a string 'node' (type must be number, but is string)"}}) {
    const CliResult r = run_btsm(d, args, 120);
    EXPECT_EQ(r.code, 2) << args << "\n" << r.err;
    EXPECT_TRUE(mentions(r, says)) << args << "\n" << r.err;
    EXPECT_FALSE(mentions(r, "json.exception")) << args << "\n" << r.err;
  }
}

// P3-f/g: a roles line written "# channel_roles = ...", "## channel_roles:" or "# channel-roles:"
// was ignored without a word (swapped probes in it were scored as they were not); a role on T9 was
// ignored while "# ambient_channel: T9" was refused. The first are warned about by every command
// that reads recordings, the second is refused alike.
TEST(HandEditedFiles, MetadataNearMissesAreWarnedAboutAndAnUnknownChannelIsRefused) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  const std::string swapped = "T1=front_bearing,T2=housing,T3=rear_bearing,T4=ambient,T5=shaft\n";
  write_text(d.file("hash.csv"), "## channel_roles: " + swapped + recording_csv(200));
  write_text(d.file("dash.csv"), "# channel-roles: " + swapped + recording_csv(200));
  for (const std::string args : {"validate model.json hash.csv", "heat model.json dash.csv --out h"}) {
    const CliResult r = run_btsm(d, args, 120);
    EXPECT_EQ(r.code, 0) << args << "\n" << r.err;
    EXPECT_TRUE(mentions(r, "WARNING: ") && mentions(r, "is not read as '# channel_roles:'") && mentions(r, "what it says is ignored"))
        << args << "\n" << r.err;
  }
  write_text(d.file("t9.csv"), "# channel_roles: T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T9=shaft\n" + recording_csv(200));
  expect_refusals(d, {{"validate model.json t9.csv", "t9.csv: metadata '# channel_roles': entry 'T9=shaft': 'T9' is not a module channel (T1..T5)"}});
}

}  // namespace
}  // namespace btsm::test
