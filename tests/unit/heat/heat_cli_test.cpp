// `btsm heat` through its CLI registration: options, outputs and error messages.
#include "host/cli/cli_support.hpp"
#include "host/cli/commands.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>

namespace {

const std::string kStepwise = std::string(BTSM_TEST_DATA_DIR) + "/tnm-reference/stepwise_3001_5018_7028.csv";

std::string run(std::vector<std::string> args) {
  CLI::App app{"btsm"};
  app.require_subcommand(1);
  btsm::cli::register_heat_commands(app);
  std::vector<std::string> argv_s = {"btsm"};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& s : argv_s) argv.push_back(s.data());
  std::stringstream out;
  auto* old = std::cout.rdbuf(out.rdbuf());
  try {
    app.parse(static_cast<int>(argv.size()), argv.data());
  } catch (...) {
    std::cout.rdbuf(old);
    throw;
  }
  std::cout.rdbuf(old);
  return out.str();
}

TEST(HeatCli, JsonOutputFilesAndPlot) {
  const std::string dir = ::testing::TempDir() + "/heat_cli";
  std::filesystem::remove_all(dir);
  const std::string out = run({"heat", "spindle4", kStepwise, "--step", "120", "--json", "--out", dir});
  const auto j = nlohmann::json::parse(out);
  EXPECT_EQ(j["alpha_rule"], "gcv");
  EXPECT_EQ(j["method"], "tikhonov1");
  EXPECT_GT(j["alpha_K2_per_W2"].get<double>(), 0.0);
  ASSERT_EQ(j["sources"].size(), 2u);
  EXPECT_EQ(j["sources"][0]["node"], "rear_bearing");
  EXPECT_EQ(j["sources"][0]["heat_W"].size(), 6480u * 5 / 120);
  EXPECT_LT(j["residual_rms_K"].get<double>(), 0.006);
  EXPECT_TRUE(std::filesystem::exists(dir + "/heat_sources.csv"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/heat_alpha_scan.csv"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/heat_sources.png"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/heat_sources.svg"));
  std::ifstream f(dir + "/heat_sources.csv");
  std::string line;
  while (std::getline(f, line) && line[0] == '#') {}
  EXPECT_EQ(line, "step_start_s,step_end_s,rear_bearing_W,rear_bearing_sigma_W,front_bearing_W,front_bearing_sigma_W");
}

TEST(HeatCli, TableOutputAndFixedAlpha) {
  const std::string out = run({"heat", "spindle4", kStepwise, "--alpha-rule", "fixed", "--alpha", "1e-5", "--scheme", "exact"});
  EXPECT_NE(out.find("alpha = 1e-05 K^2/W^2 chosen by fixed"), std::string::npos) << out;
  EXPECT_NE(out.find("rear_bearing"), std::string::npos);
}

TEST(HeatCli, BadArgumentsNameTheProblem) {
  auto expect_error = [](std::vector<std::string> args, const std::string& needle) {
    try {
      run(args);
      ADD_FAILURE() << "no error for " << needle;
    } catch (const btsm::cli::CommandError& e) {
      EXPECT_EQ(e.code, btsm::cli::kExitUsage);
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error({"heat", "spindle4", kStepwise, "--method", "tikhonov3"}, "tikhonov3");
  expect_error({"heat", "spindle4", kStepwise, "--alpha-rule", "magic"}, "magic");
  expect_error({"heat", "spindle4", kStepwise, "--alpha-rule", "fixed"}, "--alpha");
  expect_error({"heat", "spindle4", kStepwise, "--nodes", "spindle_nose"}, "spindle_nose");
  expect_error({"heat", "no_such_model", kStepwise}, "no_such_model");
  expect_error({"heat", "spindle4", kStepwise, "--step", "0"}, "--step");
}

}  // namespace
