// `reduce` knows the network at every speed, the module only its breakpoints (interpolated
// linearly, 0 rpm = the stop). A model reduced at 4000, 6000 and 8000 rpm predicted a spindle
// running at 3000 rpm ~2 K too warm and a healthy spindle WARNed for hours (README workflow,
// walked): now reduce prints the speed range where the module's steady prediction is within its
// bands and refuses (exit 1, nothing written) a model that is off at a speed up to its top
// breakpoint, naming the channel and the speeds, unless --force; the JSON keeps the range.
#include "cli_run.hpp"
#include "model_fixture.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace btsm::test {
namespace {

TEST(ReduceSpeedRange, AModelOffBelowItsFirstBreakpointIsRefusedWithTheRange) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  const CliResult refused = run_btsm(d, "reduce model.json --speeds 4000,6000,8000 --drift 2 --low-drift 2 --out r.json --blob m.bin");
  EXPECT_EQ(refused.code, 1) << refused.err;
  EXPECT_NE(refused.err.find("does not hold at speeds the spindle may run"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find(" rpm: a healthy spindle settles up to"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("valid (steady error within 0.5 x the drift) for "), std::string::npos) << refused.err;
  EXPECT_FALSE(file_exists(d.file("r.json")));
  EXPECT_FALSE(file_exists(d.file("m.bin")));

  const CliResult forced = run_btsm(d, "reduce model.json --speeds 4000,6000,8000 --drift 2 --low-drift 2 --force --out r.json --blob m.bin");
  ASSERT_EQ(forced.code, 0) << forced.err;
  EXPECT_NE(forced.err.find("WARNING (forced)"), std::string::npos) << forced.err;
  const auto j = nlohmann::json::parse(read_text(d.file("r.json")));
  const auto& cov = j.at("speed_coverage");
  EXPECT_FALSE(cov.at("covers_all_checked_speeds").get<bool>());
  ASSERT_FALSE(cov.at("gaps").empty());
  const auto& gap = cov.at("gaps").at(0);
  EXPECT_LT(gap.at("from_rpm").get<double>(), 500.0);   // from (nearly) standstill ...
  EXPECT_GT(gap.at("to_rpm").get<double>(), 1000.0);    // ... into the speeds a spindle runs
  EXPECT_LT(gap.at("to_rpm").get<double>(), 4000.0);    // and not at the breakpoint itself
  const double from = cov.at("valid_speed_range_rpm").at(0), to = cov.at("valid_speed_range_rpm").at(1);
  EXPECT_GT(from, gap.at("to_rpm").get<double>());
  EXPECT_EQ(to, 8000.0);
}

TEST(ReduceSpeedRange, BreakpointsDownToLowSpeedCoverEverySpeedUpToTheTop) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  const CliResult r =
      run_btsm(d, "reduce model.json --speeds 500,2000,4000,6000,8000 --drift 2 --low-drift 2 --out r.json --blob m.bin");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("for 0-8000 rpm"), std::string::npos) << r.err;
  const auto j = nlohmann::json::parse(read_text(d.file("r.json")));
  EXPECT_TRUE(j.at("speed_coverage").at("covers_all_checked_speeds").get<bool>());
}

// Hand-set bands the model's own error reaches: the operation failed (exit 1), it was not a bad
// argument (exit 2, as before, while the user had given none: the defaults themselves).
TEST(ReduceSpeedRange, BandsTheModelsOwnErrorReachesFailWithOne) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  const CliResult r = run_btsm(d, "reduce model.json --speeds 500,2000,4000,6000,8000 --drift 0.01 --low-drift 0.01 --out r.json");
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("a healthy spindle would WARN"), std::string::npos) << r.err;
  EXPECT_FALSE(file_exists(d.file("r.json")));
}

}  // namespace
}  // namespace btsm::test
