// `btsm residual` judges every candidate against its base fit, so the base fit's warnings (the
// stage-1 fallback starts, weakly or not identifiable parameters) must reach the user as `btsm fit`
// prints them: on stderr and in the JSON (`base_fit_warnings`). They were computed and dropped.
// tests/data/drift-cooling: a drifting rear-bearing probe leaves stage 1 unsettled (C1 started
// from the gauge's share), see its README.
#include "cli_run.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <string>

namespace btsm::test {
namespace {

TEST(ResidualBaseFitWarnings, AreOnStderrAndInTheJsonNextToEveryFormerKey) {
  ScratchDir d;
  const std::string data = std::string(BTSM_TEST_DATA_DIR) + "/drift-cooling/";
  // The check: the first hours of the 8002 rpm run read 20 mK warmer (residual refuses a check
  // that is a fit recording, or repeats its samples; the warnings come from the base fit,
  // whatever the check).
  const std::string run = read_text(data + "warmup_8002rpm.csv");
  std::string check;
  std::size_t at = 0;
  for (int lines = 0; lines < 1500; ++lines) {
    const std::size_t end = run.find('\n', at);
    ASSERT_NE(end, std::string::npos);
    std::string line = run.substr(at, end - at);
    at = end + 1;
    if (!line.empty() && line[0] >= '0' && line[0] <= '9') {  // time,speed,ambient,T1,T2,T3,T5
      std::string out;
      std::size_t from = 0;
      for (int col = 0; from <= line.size(); ++col) {
        const std::size_t comma = std::min(line.find(',', from), line.size());
        std::string cell = line.substr(from, comma - from);
        if (col >= 3 && !cell.empty()) cell = std::to_string(std::stod(cell) + 0.02);
        out += (col ? "," : "") + cell;
        from = comma + 1;
      }
      line = out;
    }
    check += line + "\n";
  }
  write_text(d.file("check.csv"), check);
  const CliResult r = run_btsm(d,
                               "residual --preset spindle4 --fit " + data + "warmup_4038rpm.csv --fit " + data +
                                   "warmup_8002rpm.csv --check check.csv --effects sensor_drift --max-candidates 1 --json",
                               240);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("residual: base fit warning: 'C1' could not be started from the data"), std::string::npos) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const auto& w = j.at("base_fit_warnings");
  ASSERT_TRUE(w.is_array());
  bool c1 = false;
  for (const auto& s : w) {
    const std::string text = s.get<std::string>();
    c1 = c1 || (text.find("'C1'") != std::string::npos && text.find("unsettled") != std::string::npos);
    // every JSON warning is on stderr too
    EXPECT_NE(r.err.find("residual: base fit warning: " + text), std::string::npos) << text;
  }
  EXPECT_TRUE(c1) << w.dump();
  for (const char* key : {"effect", "nodes", "rmse_before_K", "rmse_after_K", "verdict", "candidates", "base_fit"})
    EXPECT_TRUE(j.contains(key)) << key;
}

}  // namespace
}  // namespace btsm::test
