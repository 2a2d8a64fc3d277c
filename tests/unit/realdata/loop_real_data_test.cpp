// What the residual loop does with a real recording's declared boundary column (the verdicts on
// every real recording are pinned in tests/unit/residual/residual_real_data_test.cpp). What the
// column can explain is measured without the loop in declared_columns_real_data_test.cpp.
#include "host/residual/residual_loop.hpp"
#include "host/residual/residual_report.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

namespace btsm::residual {
namespace {

const std::string kData = BTSM_TEST_DATA_DIR;

bool has(const std::vector<std::string>& v, const std::string& x) { return std::find(v.begin(), v.end(), x) != v.end(); }

LoopResult run(const std::string& dir, const std::string& network, const std::string& fit, const std::string& check) {
  const thermal::Network net = thermal::load_network(kData + dir + network);
  return run_residual_loop(net, Eigen::VectorXd(), {thermal::read_recording_csv(kData + dir + fit)},
                           {thermal::read_recording_csv(kData + dir + check)}, {});
}

const CandidateResult* candidate(const LoopResult& r, const std::string& family) {
  for (const auto& c : r.candidates)
    if (c.effect == family && c.status != "not fitted") return &c;
  return nullptr;
}

// SJTU spindle with the cooling water declared as a boundary column: the loop proposes it as a
// second boundary, but it explains little of the plateau error (by hand 1.09 -> 1.04 K), so the
// verdict stays `unexplained`, and it names where the residual is.
TEST(ResidualLoopRealDataDeclared, SjtuCoolingWaterIsTriedAndDoesNotExplainThePlateau) {
  const LoopResult r = run("/spindle-sjtu-elongation/", "sjtu4_network.json", "sjtu_fit_0-24h.csv", "sjtu_check_24-78h.csv");
  EXPECT_EQ(r.verdict, "unexplained") << format_table(r);
  EXPECT_GT(r.before_check.rmse_k, 0.7);
  EXPECT_TRUE(has(r.nodes, "rear"));
  const CandidateResult* water = candidate(r, "second_boundary");
  ASSERT_NE(water, nullptr) << "the declared coolant_c column was not proposed";
  EXPECT_LT(water->check_factor, 1.25);
}

}  // namespace
}  // namespace btsm::residual
