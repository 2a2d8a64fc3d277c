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

// The MCU's table inverse (pt1000_temperature_q, fixed point): every coefficient is the exact
// double inverse interpolated at the segment's three Chebyshev nodes (recomputed here, so the
// integers in common/rtd.hpp are provably derived from RtdInverse), written in powers of the
// position x in [0, 1) from the segment start, in 1/256 mK (d1, d2 scaled by 256; d2 stored in
// units of 2^(5 + 2 binade)).
// The last segments reach past 850 degC: there the closed-form root (exact above 0 degC) continued.
TEST(RtdFixed, TableCoefficientsAreTheExactInverseAtChebyshevNodes) {
  const auto kd = iec60751<double>(1000.0);
  const auto t_of = [&kd](double r) {
    if (r <= 3900.0) return rtd_temperature(kd, r).value;
    const double a = 1000.0 * kd.a, b = 1000.0 * kd.b, d = r - 1000.0;
    return 2 * d / (a + std::sqrt(a * a + 4 * b * d));
  };
  const detail_rtd::QuadSegmentFixed* table = detail_rtd::pt1000_fixed_segments();
  for (int seg = 0; seg < detail_rtd::kPt1000FixedSegments; ++seg) {
    const int b = seg / 16;  // binade [512 2^b, 1024 2^b) ohm
    const double width = 32.0 * (1 << b), h = width / 2;
    const double mid = 512.0 * (1 << b) + (seg % 16 + 0.5) * width;
    const double u = std::cos(M_PI / 6);
    const double y0 = t_of(mid - u * h), y1 = t_of(mid), y2 = t_of(mid + u * h);
    // t = c0 + c1 z + c2 z^2 for z in [-1, 1] around the centre; x = (z + 1) / 2 from the start.
    const double c0 = y1, c1 = (y2 - y0) / (2 * u), c2 = (y0 + y2 - 2 * y1) / (2 * u * u);
    const double d0 = c0 - c1 + c2, d1 = 2 * c1 - 4 * c2, d2 = 4 * c2;
    EXPECT_NEAR(table[seg].d0, d0 * 256000.0, 0.5 + 1e-6) << "segment " << seg;
    EXPECT_NEAR(table[seg].d1, d1 * 256000.0 * 256, 0.5 + 1e-3) << "segment " << seg;
    EXPECT_NEAR(table[seg].d2, d2 * 256000.0 * 256 / (1 << (5 + 2 * b)), 0.5 + 1e-6) << "segment " << seg;
  }
}

// Every resistance in steps of ~1/100 ohm (in ohm x 2^16, walking across every segment boundary)
// over the whole table range against the double exact inverse of the same resistance.
TEST(RtdFixed, ErrorOverTheTableRangeIsMeasuredAndBounded) {
  const auto kd = iec60751<double>(1000.0);
  double worst_low = 0, worst_high = 0, worst_btsm = 0, at = 0;
  for (uint32_t r_q16 = detail_rtd::kPt1000FixedMinQ16; r_q16 <= detail_rtd::kPt1000FixedMaxQ16; r_q16 += 653) {
    const Pt1000FixedResult fx = pt1000_temperature_q(r_q16);
    ASSERT_TRUE(fx.ok()) << r_q16;
    const double t_ref = rtd_temperature(kd, r_q16 / 65536.0).value;
    const double err = std::fabs(fx.t / 256000.0 - t_ref);
    if (r_q16 < (2048u << 16)) {
      if (err > worst_low) worst_low = err, at = t_ref;
    } else {
      worst_high = std::max(worst_high, err);
    }
    if (t_ref >= -40.0 && t_ref <= 150.0) worst_btsm = std::max(worst_btsm, err);
  }
  std::printf("[rtd] table inverse (fixed point, 1/256 mK) vs exact double: 512...2048 ohm worst %.2e degC (at "
              "%.1f degC), 2048 ohm...850 degC %.2e degC; -40...150 degC: %.2e degC\n",
              worst_low, at, worst_high, worst_btsm);
  EXPECT_LT(worst_low, 1.3e-5);   // fit 9.2e-6 + the 3.9 uK unit
  EXPECT_LT(worst_high, 2.5e-4);  // fit 2.3e-4 above 297 degC (128 ohm segments)
  EXPECT_LT(worst_btsm, 1.2e-5);  // the float table it replaced: 2.3e-5
}

// Below 512 ohm (-118.3 degC) kBelowRange, above R(850.02 degC) kAboveRange; both ends inside.
TEST(RtdFixed, OutsideTheTableIsARangeError) {
  for (uint32_t r : {0u, 1u, 18u << 16, 185u << 16, 500u << 16, detail_rtd::kPt1000FixedMinQ16 - 1})
    EXPECT_EQ(pt1000_temperature_q(r).status, RtdStatus::kBelowRange) << r;
  for (uint32_t r : {detail_rtd::kPt1000FixedMaxQ16 + 1, 3905u << 16, 4096u << 16, 0xFFFFFFFFu})
    EXPECT_EQ(pt1000_temperature_q(r).status, RtdStatus::kAboveRange) << r;
  const auto kd = iec60751<double>(1000.0);
  for (uint32_t r : {detail_rtd::kPt1000FixedMinQ16, 1000u << 16, 1024u << 16, 2048u << 16, detail_rtd::kPt1000FixedMaxQ16}) {
    const Pt1000FixedResult t = pt1000_temperature_q(r);
    ASSERT_TRUE(t.ok()) << r;
    EXPECT_NEAR(t.t / 256000.0, rtd_temperature(kd, r / 65536.0).value, 2.5e-4) << r;
  }
  EXPECT_NEAR(pt1000_temperature_q(1000u << 16).t, 0, 4);  // 0 degC within a unit or so
  EXPECT_NEAR(pt1000_temperature_q(detail_rtd::kPt1000FixedMaxQ16).t / 256000.0, 850.02, 1e-3);
}

}  // namespace
}  // namespace btsm
