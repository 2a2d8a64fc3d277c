// Runs the BUILT tool, `btsm rtd r2t --r0 100 <every resistance of the ITS-90/EN 60751 table>`,
// and checks every printed temperature against the table within the table's rounding
// (0.005 ohm / dR/dt: 0.0128 degC at 0 degC ... 0.017 degC at 840 degC); then the error paths.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

struct CmdResult {
  int exit_code;
  std::string out;
};

// stdout (and stderr when merge_stderr) of a shell command plus its exit code.
CmdResult run_cmd(const std::string& cmd, bool merge_stderr) {
  const std::string full = cmd + (merge_stderr ? " 2>&1" : " 2>/dev/null");
  FILE* p = popen(full.c_str(), "r");
  EXPECT_NE(p, nullptr) << full;
  CmdResult r{-1, {}};
  if (p == nullptr) return r;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string btsm() { return std::string(BTSM_BIN_DIR) + "/btsm"; }

double pt100_slope(double t) {
  double s = 3.9083e-3 + 2 * -5.775e-7 * t;
  if (t < 0) s += -4.183e-12 * t * t * (4 * t - 300);
  return 100.0 * s;
}

TEST(RtdCli, R2tMatchesEveryEntryOfTheItsEn60751Table) {
  std::ifstream in(std::string(BTSM_TEST_DATA_DIR) + "/rtd-iec60751/pt100_its90_en60751_m200_p840.csv");
  ASSERT_TRUE(in.good());
  std::vector<double> t_table;
  std::vector<std::string> r_text;
  std::string line;
  while (std::getline(in, line)) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();  // CRLF file
    if (line.empty()) continue;
    const size_t comma = line.find(',');
    ASSERT_NE(comma, std::string::npos) << line;
    t_table.push_back(std::stod(line.substr(0, comma)));
    r_text.push_back(line.substr(comma + 1));  // passed exactly as printed in the table
  }
  ASSERT_EQ(t_table.size(), 1041u);
  std::string cmd = btsm() + " rtd r2t --r0 100";
  for (const auto& r : r_text) cmd += " " + r;
  const CmdResult res = run_cmd(cmd, false);
  ASSERT_EQ(res.exit_code, 0) << "is " << btsm() << " built?";
  std::istringstream lines(res.out);
  double worst = 0;
  size_t i = 0;
  for (; std::getline(lines, line); ++i) {
    ASSERT_LT(i, t_table.size()) << "more output lines than inputs";
    const double t = std::stod(line);
    const double err = std::fabs(t - t_table[i]);
    worst = std::max(worst, err);
    // + 0.00005: the tool prints 4 decimals
    EXPECT_LE(err, 0.005 / pt100_slope(t_table[i]) + 0.00005) << "R = " << r_text[i] << " t = " << t_table[i];
  }
  EXPECT_EQ(i, t_table.size()) << "one result per line expected";
  std::printf("[rtd cli] btsm rtd r2t --r0 100 over 1041 table entries: worst |dT| %.4f degC\n", worst);
}

TEST(RtdCli, T2rDefaultsToPt1000) {
  const CmdResult res = run_cmd(btsm() + " rtd t2r 0 100 -200", false);
  ASSERT_EQ(res.exit_code, 0);
  EXPECT_EQ(res.out, "1000.0000\n1385.0550\n185.2008\n");
}

TEST(RtdCli, OutOfRangeAndNonNumericInputNameTheValue) {
  CmdResult res = run_cmd(btsm() + " rtd r2t --r0 100 138.5 12.0", true);
  EXPECT_EQ(res.exit_code, 2);
  EXPECT_NE(res.out.find("'12.0'"), std::string::npos) << res.out;
  EXPECT_NE(res.out.find("below"), std::string::npos) << res.out;
  EXPECT_EQ(res.out.find("138.5"), std::string::npos) << "no partial output on error: " << res.out;
  // The range a refusal prints is the one checked: 3904.82 ohm (0.009 above R(850 degC)) is read
  // as 850.003 degC, so the message says how far beyond the table values are still read (probe 5).
  res = run_cmd(btsm() + " rtd r2t 3904.9", true);
  EXPECT_NE(res.out.find("read up to 0.02 K beyond"), std::string::npos) << res.out;
  res = run_cmd(btsm() + " rtd t2r 20 twenty 900", true);
  EXPECT_EQ(res.exit_code, 2);
  EXPECT_NE(res.out.find("'twenty' is not a number"), std::string::npos) << res.out;
  EXPECT_NE(res.out.find("'900'"), std::string::npos) << res.out;
  res = run_cmd(btsm() + " rtd r2t --r0 0 100", true);
  EXPECT_EQ(res.exit_code, 2);
  EXPECT_NE(res.out.find("--r0"), std::string::npos) << res.out;
  res = run_cmd(btsm() + " rtd r2t nan", true);
  EXPECT_EQ(res.exit_code, 2);
  EXPECT_NE(res.out.find("'nan'"), std::string::npos) << res.out;
}

}  // namespace
