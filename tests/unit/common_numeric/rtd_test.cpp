// Callendar–Van Dusen against two independently published tables (tests/data/rtd-iec60751), exact
// round trips, range/NaN/coefficient errors, and the float (MCU) path measured against double.
#include "common/rtd.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace btsm {
namespace {

struct TableRow {
  double t_c;
  double r_ohm;
};

std::vector<TableRow> load_table(const std::string& name, bool has_header) {
  const std::string path = std::string(BTSM_TEST_DATA_DIR) + "/rtd-iec60751/" + name;
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << "cannot open " << path;
  std::vector<TableRow> rows;
  std::string line;
  if (has_header) std::getline(in, line);
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::istringstream ss(line);
    TableRow r{};
    char comma = 0;
    ss >> r.t_c >> comma >> r.r_ohm;
    EXPECT_FALSE(ss.fail()) << path << ": bad line '" << line << "'";
    rows.push_back(r);
  }
  return rows;
}

// dR/dt of a Pt100 (ohm/degC), to turn the table's 0.005 ohm rounding into degC.
double pt100_slope(double t) {
  const RtdCoefficients<double> k = iec60751<double>(100.0);
  double s = k.a + 2 * k.b * t;
  if (t < 0) s += k.c * t * t * (4 * t - 300);
  return k.r0_ohm * s;
}

TEST(RtdTable, ForwardMatchesItsEn60751TableWithinRounding) {
  const auto rows = load_table("pt100_its90_en60751_m200_p840.csv", false);
  ASSERT_EQ(rows.size(), 1041u);
  const auto k = iec60751<double>(100.0);
  double worst = 0;
  for (const auto& row : rows) {
    const auto r = rtd_resistance(k, row.t_c);
    ASSERT_TRUE(r.ok()) << row.t_c;
    worst = std::max(worst, std::fabs(r.value - row.r_ohm));
    EXPECT_LE(std::fabs(r.value - row.r_ohm), 0.005) << "t = " << row.t_c;
  }
  std::printf("[rtd] forward vs ITS-90 table: worst |dR| %.6f ohm (table rounded to 0.01)\n", worst);
}

// Every entry: T(R) must return the tabulated temperature within the table's own rounding,
// 0.005 ohm / (dR/dt) = 0.0128 degC at 0 degC ... 0.017 degC at 840 degC.
TEST(RtdTable, InverseMatchesEveryItsEn60751EntryWithinRounding) {
  const auto rows = load_table("pt100_its90_en60751_m200_p840.csv", false);
  ASSERT_EQ(rows.size(), 1041u);
  const auto k = iec60751<double>(100.0);
  double worst = 0, worst_at = 0;
  int beyond_0013 = 0;
  for (const auto& row : rows) {
    const auto t = rtd_temperature(k, row.r_ohm);
    ASSERT_TRUE(t.ok()) << "R = " << row.r_ohm << ": " << rtd_status_name(t.status);
    const double err = std::fabs(t.value - row.t_c);
    const double bound = 0.005 / pt100_slope(row.t_c);
    EXPECT_LE(err, bound) << "R = " << row.r_ohm << " t = " << row.t_c;
    if (err > 0.013) ++beyond_0013;
    if (err > worst) worst = err, worst_at = row.t_c;
  }
  std::printf("[rtd] inverse vs ITS-90 table (1041 entries): worst |dT| %.5f degC at %.0f degC; "
              "%d entries above 0.013 degC (all above 100 degC, where dR/dt < 0.385 ohm/degC)\n",
              worst, worst_at, beyond_0013);
  // Up to 100 degC the slope is >= 0.385 ohm/degC, so the flat 0.013 degC holds for every entry.
  for (const auto& row : rows) {
    if (row.t_c > 100) break;
    EXPECT_LE(std::fabs(rtd_temperature(k, row.r_ohm).value - row.t_c), 0.013) << row.t_c;
  }
}

TEST(RtdTable, Pt1000IsTenTimesTheTable) {
  const auto rows = load_table("pt100_its90_en60751_m200_p840.csv", false);
  const auto k = iec60751<double>(1000.0);
  for (const auto& row : rows) {
    const auto t = rtd_temperature(k, 10.0 * row.r_ohm);
    ASSERT_TRUE(t.ok());
    EXPECT_LE(std::fabs(t.value - row.t_c), 0.05 / (10.0 * pt100_slope(row.t_c)) * 1.0001) << row.t_c;
  }
}

TEST(RtdTable, OlderDinTableCoversTheFullRangeToCoarseTolerance) {
  const auto rows = load_table("pt100_din43760_drhaney_m200_p850.csv", true);
  ASSERT_EQ(rows.size(), 1051u);
  const auto k = iec60751<double>(100.0);
  for (const auto& row : rows) {
    const auto r = rtd_resistance(k, row.t_c);
    ASSERT_TRUE(r.ok());
    EXPECT_LE(std::fabs(r.value - row.r_ohm), 0.015) << row.t_c;  // README: max 0.0146 ohm
    const auto t = rtd_temperature(k, row.r_ohm);
    ASSERT_TRUE(t.ok());
    EXPECT_LE(std::fabs(t.value - row.t_c), 0.015 / pt100_slope(row.t_c)) << row.t_c;
  }
}

TEST(Rtd, SpotValuesFromPublishedPt1000Table) {
  const auto k = iec60751<double>(1000.0);
  EXPECT_NEAR(rtd_resistance(k, 20.0).value, 1077.935, 0.0005);
  EXPECT_NEAR(rtd_resistance(k, 30.0).value, 1116.729, 0.0005);
  EXPECT_NEAR(rtd_resistance(k, -200.0).value, 185.2008, 0.0001);
  EXPECT_NEAR(rtd_resistance(k, 0.0).value, 1000.0, 1e-12);
}

TEST(Rtd, ExactRoundTripOverTheFullRangeInDouble) {
  for (const double r0 : {100.0, 500.0, 1000.0}) {
    const auto k = iec60751<double>(r0);
    double worst = 0;
    for (double t = -200.0; t <= 850.0; t += 0.137) {
      const auto r = rtd_resistance(k, t);
      ASSERT_TRUE(r.ok());
      const auto back = rtd_temperature(k, r.value);
      ASSERT_TRUE(back.ok()) << t;
      worst = std::max(worst, std::fabs(back.value - t));
    }
    EXPECT_LT(worst, 1e-9) << "R0 = " << r0;
  }
}

TEST(Rtd, AnyCoefficientSetIsInvertedExactly) {
  // An older (IPTS-68 style) set and a made-up one with a stronger C term: Newton still converges.
  RtdCoefficients<double> k{100.0, 3.90802e-3, -5.802e-7, -4.2735e-12};
  RtdCoefficients<double> strong{1000.0, 3.85e-3, -6.0e-7, -2.0e-11};
  for (const auto& kk : {k, strong}) {
    for (double t = -200.0; t <= 850.0; t += 1.3) {
      const auto back = rtd_temperature(kk, rtd_resistance(kk, t).value);
      ASSERT_TRUE(back.ok()) << t;
      EXPECT_NEAR(back.value, t, 1e-9);
    }
  }
}

TEST(Rtd, OutOfRangeAndBadInputAreErrorsNeverNumbers) {
  const auto k = iec60751<double>(1000.0);
  EXPECT_TRUE(rtd_resistance(k, -200.0).ok());
  EXPECT_TRUE(rtd_resistance(k, 850.0).ok());
  auto r = rtd_resistance(k, -200.001);
  EXPECT_EQ(r.status, RtdStatus::kBelowRange);
  EXPECT_TRUE(std::isnan(r.value));
  EXPECT_EQ(rtd_resistance(k, 850.001).status, RtdStatus::kAboveRange);
  EXPECT_EQ(rtd_resistance(k, NAN).status, RtdStatus::kNotANumber);
  EXPECT_EQ(rtd_resistance(k, INFINITY).status, RtdStatus::kAboveRange);

  const double r_min = rtd_resistance(k, -200.0).value;
  const double r_max = rtd_resistance(k, 850.0).value;
  EXPECT_NEAR(rtd_temperature(k, r_min).value, -200.0, 1e-9);
  EXPECT_NEAR(rtd_temperature(k, r_max).value, 850.0, 1e-9);
  // Within the documented margin (0.02 degC) of the ends: accepted, result just beyond the end.
  EXPECT_NEAR(rtd_temperature(k, r_min - 0.02).value, -200.005, 0.001);
  EXPECT_NEAR(rtd_temperature(k, r_max + 0.02).value, 850.0068, 0.0001);  // 2.93 ohm/degC there
  auto t = rtd_temperature(k, r_min - 0.1);
  EXPECT_EQ(t.status, RtdStatus::kBelowRange);
  EXPECT_TRUE(std::isnan(t.value));
  EXPECT_EQ(rtd_temperature(k, r_max + 0.1).status, RtdStatus::kAboveRange);
  EXPECT_EQ(rtd_temperature(k, 0.0).status, RtdStatus::kBelowRange);     // shorted probe
  EXPECT_EQ(rtd_temperature(k, -5.0).status, RtdStatus::kBelowRange);
  EXPECT_EQ(rtd_temperature(k, 1e9).status, RtdStatus::kAboveRange);     // open probe
  EXPECT_EQ(rtd_temperature(k, NAN).status, RtdStatus::kNotANumber);

  RtdCoefficients<double> bad = k;
  bad.r0_ohm = 0.0;
  EXPECT_EQ(rtd_temperature(bad, 1000.0).status, RtdStatus::kBadCoefficients);
  bad = k;
  bad.a = -1e-3;
  EXPECT_EQ(rtd_resistance(bad, 10.0).status, RtdStatus::kBadCoefficients);
  bad = k;
  bad.b = -1e-5;  // R(t) would turn over below 850 degC: no unique inverse
  EXPECT_EQ(rtd_temperature(bad, 1500.0).status, RtdStatus::kBadCoefficients);
  bad = k;
  bad.c = NAN;
  EXPECT_EQ(rtd_temperature(bad, 900.0).status, RtdStatus::kBadCoefficients);
}

// The MCU computes in float from a float resistance. Over the BTSM range (-40...150 degC) compare
// with the double path fed with the same (float-rounded) resistance, so the figure is the
// arithmetic error, and separately the total including the rounding of R to float.
TEST(RtdFloat, WorstErrorOverBtsmRangeIsMeasuredAndBounded) {
  const auto kd = iec60751<double>(1000.0);
  const auto kf = iec60751<float>(1000.0f);
  double worst_inv_arith = 0, worst_inv_total = 0, worst_fwd = 0;
  double at_inv = 0;
  for (int i = 0; i <= 190000; ++i) {
    const double t = -40.0 + i * 0.001;
    const double r_exact = rtd_resistance(kd, t).value;
    const float r_f = static_cast<float>(r_exact);
    const auto tf = rtd_temperature(kf, r_f);
    ASSERT_TRUE(tf.ok()) << t;
    const double t_ref = rtd_temperature(kd, static_cast<double>(r_f)).value;
    const double arith = std::fabs(static_cast<double>(tf.value) - t_ref);
    if (arith > worst_inv_arith) worst_inv_arith = arith, at_inv = t;
    worst_inv_total = std::max(worst_inv_total, std::fabs(static_cast<double>(tf.value) - t));
    const auto rf = rtd_resistance(kf, static_cast<float>(t));
    const double r_ref = rtd_resistance(kd, static_cast<double>(static_cast<float>(t))).value;
    worst_fwd = std::max(worst_fwd, std::fabs(static_cast<double>(rf.value) - r_ref));
  }
  std::printf("[rtd] float vs double, Pt1000, -40...150 degC: T(R) arithmetic %.2e degC (at %.3f), "
              "incl. R rounded to float %.2e degC; R(T) %.2e ohm\n",
              worst_inv_arith, at_inv, worst_inv_total, worst_fwd);
  // Float ulp of t near 150 degC is 1.5e-5 degC; of R near 1573 ohm 1.2e-4 ohm (= 3.3e-5 degC).
  EXPECT_LT(worst_inv_arith, 4e-5);
  EXPECT_LT(worst_inv_total, 6e-5);
  EXPECT_LT(worst_fwd, 2.5e-4);
}

TEST(RtdFloat, FullRangeFloatInverseStaysWithinAMillikelvinScale) {
  const auto kd = iec60751<double>(1000.0);
  const auto kf = iec60751<float>(1000.0f);
  double worst = 0;
  for (double t = -200.0; t <= 850.0; t += 0.01) {
    const float r_f = static_cast<float>(rtd_resistance(kd, t).value);
    const auto tf = rtd_temperature(kf, r_f);
    if (!tf.ok()) {
      // Only the very ends may fall outside after rounding R to float.
      EXPECT_TRUE(t < -199.99 || t > 849.99) << t << " " << rtd_status_name(tf.status);
      continue;
    }
    worst = std::max(worst, std::fabs(tf.value - rtd_temperature(kd, double(r_f)).value));
  }
  std::printf("[rtd] float vs double, Pt1000, full range: T(R) arithmetic %.2e degC\n", worst);
  EXPECT_LT(worst, 3e-4);
}

// The MCU's table inverse (pt1000_temperature_fast): every coefficient is the exact double
// inverse interpolated at the segment's three Chebyshev nodes (recomputed here, so the literals in
// common/rtd.hpp are provably derived from RtdInverse), in the ulp units of its binade.
TEST(RtdFast, TableCoefficientsAreTheExactInverseAtChebyshevNodes) {
  const auto kd = iec60751<double>(1000.0);
  const detail_rtd::QuadSegment* table = detail_rtd::pt1000_segments();
  for (int seg = 0; seg < detail_rtd::kPt1000Segments; ++seg) {
    const int e = seg < 16 ? 9 : 10;  // binade [2^e, 2^(e+1))
    const double width = std::ldexp(1.0, e) / 16, ulp = std::ldexp(1.0, e - 23);
    const double mid = std::ldexp(1.0, e) + (seg % 16 + 0.5) * width, h = width / 2;
    const double u = std::cos(M_PI / 6);
    const double y0 = rtd_temperature(kd, mid - u * h).value, y1 = rtd_temperature(kd, mid).value,
                 y2 = rtd_temperature(kd, mid + u * h).value;
    const double c0 = y1, c1 = (y2 - y0) / (2 * u) / h * ulp, c2 = (y0 + y2 - 2 * y1) / (2 * u * u) / (h * h) * ulp * ulp;
    EXPECT_NEAR(table[seg].a0, c0, std::fabs(c0) * 1.2e-7 + 1e-12) << "segment " << seg;
    EXPECT_NEAR(table[seg].a1, c1, std::fabs(c1) * 1.2e-7) << "segment " << seg;
    EXPECT_NEAR(table[seg].a2, c2, std::fabs(c2) * 1.2e-7) << "segment " << seg;
  }
}

// Every float resistance in steps of ~1/100 ohm over the whole table range [512, 2048) ohm (the
// step walks across every segment boundary) against the double exact inverse of the same float R.
TEST(RtdFast, ErrorOverTheTableRangeIsMeasuredAndBounded) {
  const auto kd = iec60751<double>(1000.0);
  const auto kf = iec60751<float>(1000.0f);
  double worst = 0, worst_btsm = 0, worst_exact_float = 0, at = 0;
  for (double r = 512.0; r < 2048.0; r += 0.0097) {
    const float r_f = static_cast<float>(r);
    const RtdResult<float> fast = pt1000_temperature_fast(r_f);
    ASSERT_TRUE(fast.ok()) << r;
    const double t_ref = rtd_temperature(kd, static_cast<double>(r_f)).value;
    const double err = std::fabs(static_cast<double>(fast.value) - t_ref);
    if (err > worst) worst = err, at = t_ref;
    if (t_ref >= -40.0 && t_ref <= 150.0) {
      worst_btsm = std::max(worst_btsm, err);
      worst_exact_float = std::max(worst_exact_float, std::fabs(double(rtd_temperature(kf, r_f).value) - t_ref));
    }
  }
  std::printf("[rtd] table inverse (float) vs exact double, 512...2048 ohm: worst %.2e degC (at %.1f degC); "
              "-40...150 degC: %.2e degC (RtdInverse<float> there: %.2e)\n",
              worst, at, worst_btsm, worst_exact_float);
  EXPECT_LT(worst, 3.5e-5);       // float ulp of t is 1.5e-5 degC above 128 degC
  EXPECT_LT(worst_btsm, 2.5e-5);  // same scale as the exact float inverse (4e-5 bound above)
}

// Outside [512, 2048) ohm (and for NaN) the result is RtdInverse<float>'s, bit for bit, errors
// included; the table's first and last resistances are in the table.
TEST(RtdFast, OutsideTheTableItIsTheExactInverse) {
  const auto kf = iec60751<float>(1000.0f);
  for (float r : {10.0f, 18.0f, 185.2f, 400.0f, 511.99997f, 2048.0f, 2500.0f, 3900.0f, 3905.0f, 1e6f, -1.0f, 0.0f, NAN}) {
    const RtdResult<float> a = pt1000_temperature_fast(r), b = rtd_temperature(kf, r);
    EXPECT_EQ(a.status, b.status) << r;
    if (b.ok()) {
      EXPECT_EQ(std::memcmp(&a.value, &b.value, sizeof(float)), 0) << r;
    } else {
      EXPECT_TRUE(std::isnan(a.value)) << r;
    }
  }
  EXPECT_TRUE(pt1000_temperature_fast(512.0f).ok());
  EXPECT_NEAR(pt1000_temperature_fast(512.0f).value, rtd_temperature(kf, 512.0f).value, 3e-5);
  EXPECT_NEAR(pt1000_temperature_fast(2047.9999f).value, rtd_temperature(kf, 2047.9999f).value, 3e-5);
  EXPECT_NEAR(pt1000_temperature_fast(1000.0f).value, 0.0f, 1e-5);
}

}  // namespace
}  // namespace btsm
