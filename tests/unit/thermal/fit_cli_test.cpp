// `btsm fit` through its CLI registration: --iterations sets the final stage's budget and a fit
// that runs out of it fails naming the limit and the option.
#include "host/cli/cli_support.hpp"
#include "host/cli/commands.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

namespace {

void run(std::vector<std::string> args) {
  CLI::App app{"btsm"};
  app.require_subcommand(1);
  btsm::cli::register_sysid_commands(app);
  std::vector<std::string> argv_s = {"btsm"};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& s : argv_s) argv.push_back(s.data());
  std::stringstream out, err;
  auto* old_out = std::cout.rdbuf(out.rdbuf());
  auto* old_err = std::cerr.rdbuf(err.rdbuf());
  struct Restore {
    std::streambuf *o, *e;
    ~Restore() {
      std::cout.rdbuf(o);
      std::cerr.rdbuf(e);
    }
  } restore{old_out, old_err};
  app.parse(static_cast<int>(argv.size()), argv.data());
}

std::vector<std::string> demo_fit_args(const std::string& out) {
  const std::string d = std::string(BTSM_TEST_DATA_DIR) + "/demo-warmups/";
  return {"fit", d + "warmup_4000rpm.csv", d + "warmup_6000rpm.csv", d + "warmup_8000rpm.csv", "--preset", "spindle4",
          "--sum-c", "20478.7", "--column", "shaft=T5", "--out", out};
}

TEST(FitCli, IterationsLimitTheFinalStageAndAreNamedWhenTheyRunOut) {
  const std::string out = ::testing::TempDir() + "/fit_cli_model.json";
  auto args = demo_fit_args(out);
  args.insert(args.end(), {"--iterations", "15"});
  try {
    run(args);
    FAIL() << "a 15-iteration fit of the demo recordings converged";
  } catch (const btsm::cli::CommandError& e) {
    EXPECT_EQ(e.code, btsm::cli::kExitFailure);
    EXPECT_NE(std::string(e.what()).find("within 15 iterations"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--iterations"), std::string::npos) << e.what();
  }
  std::ifstream f(out);
  const auto j = nlohmann::json::parse(f);
  EXPECT_EQ(j["fit"]["stages"].back()["iterations"], 15);
  EXPECT_FALSE(j["fit"]["converged"].get<bool>());
}

TEST(FitCli, DefaultIterationsConvergeOnTheDemoRecordings) {
  const std::string out = ::testing::TempDir() + "/fit_cli_model_default.json";
  EXPECT_NO_THROW(run(demo_fit_args(out)));
  std::ifstream f(out);
  const auto j = nlohmann::json::parse(f);
  EXPECT_TRUE(j["fit"]["converged"].get<bool>());
}

// Warm-ups far apart in speed (8250, 4750, 7250 rpm, recorded from the simulated module with
// noise seed 10) need 371 final-stage iterations: the default budget must cover them, not stop a
// user's fit 0.16 % above its minimum with "did not converge" as 300 did.
TEST(FitCli, DefaultIterationsConvergeOnWarmupsFarApartInSpeed) {
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir()) / "fit_cli_far_apart";
  const std::string cmd = "bash '" + std::string(BTSM_TEST_DATA_DIR) + "/module-warmups/make_module_warmups.sh' '" +
                          std::string(BTSM_BIN_DIR) + "/btsm' '" + dir.string() + "' 10 8250,4750,7250 > /dev/null 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  const std::string out = (dir / "model.json").string();
  EXPECT_NO_THROW(run({"fit", (dir / "warmup_8250rpm.csv").string(), (dir / "warmup_4750rpm.csv").string(),
                       (dir / "warmup_7250rpm.csv").string(), "--preset", "spindle4", "--column", "shaft=T5", "--out",
                       out}));
  std::ifstream f(out);
  const auto j = nlohmann::json::parse(f);
  EXPECT_TRUE(j["fit"]["converged"].get<bool>());
  // The pty recording is not bit-reproducible (the host's timing moves it by a few samples), so the
  // final stage's count varies between runs (measured 274-371); it stays above every clean
  // demo-speed experiment's (<= 160), so the case still exercises a long final stage.
  const int iterations = j["fit"]["stages"].back()["iterations"].get<int>();
  std::cout << "final stage: " << iterations << " iterations\n";
  EXPECT_GT(iterations, 160) << "the case no longer tests a long final stage";
  std::filesystem::remove_all(dir);
}

}  // namespace
