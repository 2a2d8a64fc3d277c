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

}  // namespace
}  // namespace btsm::test
