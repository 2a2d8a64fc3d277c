// Spindle plant: profile/fault/effect parsing with clear errors, the shared thermal simulator
// behind it, faults and hidden effects acting where they should.
#include "host/sim/plant/probes.hpp"
#include "host/sim/plant/spindle_plant.hpp"
#include "host/io/decimal_number.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

namespace btsm::sim {
namespace {

TEST(SpeedProfile, ParsesUnitsAndHoldsTheLastSpeed) {
  const auto p = SpeedProfile::parse("6h@6000,4h@0, 30m@3000,90@1500rpm");
  ASSERT_EQ(p.segments().size(), 4u);
  EXPECT_DOUBLE_EQ(p.total_duration_s(), 6 * 3600 + 4 * 3600 + 1800 + 90);
  EXPECT_EQ(p.rpm_at(0), 6000);
  EXPECT_EQ(p.rpm_at(6 * 3600 - 1e-6), 6000);
  EXPECT_EQ(p.rpm_at(6 * 3600), 0);
  EXPECT_EQ(p.rpm_at(1e9), 1500);
  EXPECT_DOUBLE_EQ(p.next_change_after(0), 6 * 3600);
}

TEST(SpeedProfile, RejectsBadItemsNamingThem) {
  for (const char* bad : {"", "6h", "x@6000", "6h@-1", "0s@100", "6h@abc", "6q@100"}) {
    try {
      SpeedProfile::parse(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("speed profile"), std::string::npos) << e.what();
    }
  }
}

TEST(SpeedProfile, LoadsFilesWithCommentsAndReportsTheLine) {
  const std::string path = testing::TempDir() + "/profile.txt";
  std::ofstream(path) << "# warm-up\n1h@6000  # run\n\n30m@0,15m@3000\n";
  const auto p = SpeedProfile::load_file(path);
  EXPECT_EQ(p.segments().size(), 3u);
  std::ofstream(path) << "1h@6000\n1h@fast\n";
  try {
    SpeedProfile::load_file(path);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(":2"), std::string::npos) << e.what();
  }
}

// The third hostile-input probe: an empty item, hex, a 0 s segment were taken silently; a BOM
// made "item 1 duration: '\xEF\xBB\xBF1' is not a number".
TEST(SpeedProfile, EmptyItemsHexAndVanishingSegmentsAreRefused) {
  for (const char* bad : {"1m@6000,,1m@0", ",1m@6000", "1m@6000,", "1m@6000, ,1m@0", "1m@0x1770", "0x3c@6000", "1e-9s@6000",
                          "50ms@6000"}) {
    try {
      SpeedProfile::parse(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("speed profile"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(SpeedProfile::parse("1m @ 6000, 200ms@0 30s@100").segments().size(), 3u);
  try {  // probe 5 P3-10: the item is quoted as written ('1mm' was reported as '1m')
    SpeedProfile::parse("1mm@6000");
    ADD_FAILURE() << "accepted 1mm";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'1mm' is not a duration"), std::string::npos) << e.what();
  }
  EXPECT_THROW(AmbientProfile::parse("20,,1h@22"), std::invalid_argument);
  EXPECT_THROW(AmbientProfile::parse("20,1h@0x16"), std::invalid_argument);
  const std::string path = testing::TempDir() + "/profile_bom.txt";
  std::ofstream(path) << "\xEF\xBB\xBF" << "1h@6000,\n30m@0\n";  // a line may end in a comma
  EXPECT_EQ(SpeedProfile::load_file(path).segments().size(), 2u);
  std::ofstream(path) << "1h@6000,,30m@0\n";
  EXPECT_THROW(SpeedProfile::load_file(path), std::invalid_argument);
}

TEST(SpeedProfile, ReplaceFromKeepsThePast) {
  auto p = SpeedProfile::parse("1h@6000");
  p.replace_from(1800, {{600, 0}});
  EXPECT_EQ(p.rpm_at(1000), 6000);
  EXPECT_EQ(p.rpm_at(1900), 0);
  EXPECT_DOUBLE_EQ(p.total_duration_s(), 2400);
}

TEST(Ambient, ConstantAndRamps) {
  const auto a = AmbientProfile::parse("20,2h@22,1h@22");
  EXPECT_DOUBLE_EQ(a.celsius_at(0), 20);
  EXPECT_DOUBLE_EQ(a.celsius_at(3600), 21);
  EXPECT_DOUBLE_EQ(a.celsius_at(1e6), 22);
  EXPECT_THROW(AmbientProfile::parse("20,2h"), std::invalid_argument);
}

TEST(Faults, ParseEveryKindAndRejectNonsense) {
  auto f = parse_fault("open:ch2@3600");
  EXPECT_EQ(f.kind, FaultKind::OpenProbe);
  EXPECT_EQ(f.channel, 2);
  EXPECT_EQ(f.start_s, 3600);
  f = parse_fault("short:ch1@100-200");
  EXPECT_EQ(f.kind, FaultKind::ShortedProbe);
  EXPECT_TRUE(f.active_at(150));
  EXPECT_FALSE(f.active_at(200));
  EXPECT_EQ(parse_fault("noadc@0").kind, FaultKind::MissingAdc);
  EXPECT_EQ(parse_fault("noref@50").kind, FaultKind::LostReference);
  f = parse_fault("bearing:25W@2h");
  EXPECT_EQ(f.kind, FaultKind::BearingHeat);
  EXPECT_EQ(f.heat_w, 25);
  EXPECT_EQ(f.start_s, 7200);
  EXPECT_EQ(f.place, BearingPlace::Rear);
  f = parse_fault("bearing:front:10W@30m");
  EXPECT_EQ(f.kind, FaultKind::BearingHeat);
  EXPECT_EQ(f.place, BearingPlace::Front);
  EXPECT_EQ(f.heat_w, 10);
  EXPECT_EQ(f.start_s, 1800);
  EXPECT_EQ(to_string(f), "bearing:front:10W@1800");
  EXPECT_EQ(parse_fault("bearing:rear:10W@0").place, BearingPlace::Rear);
  EXPECT_EQ(to_string(parse_fault("bearing:rear:10W@0")), "bearing:10W@0");
  for (const char* bad : {"open:ch6@1", "open@1", "melt:ch1@1", "noadc:ch1@1", "bearing:xW@1", "open:ch1", "short:ch1@20-10",
                          "bearing:middle:5W@1", "bearing:front:@1", "bearing:front:-5W@1"})
    EXPECT_THROW(parse_fault(bad), std::invalid_argument) << bad;
  HiddenEffects fx;
  parse_effect("bearing-tc:0.01", fx);
  parse_effect("run-in:6W/20m", fx);
  EXPECT_DOUBLE_EQ(fx.bearing_temp_coeff_per_k, 0.01);
  EXPECT_DOUBLE_EQ(fx.runin_w_per_krpm, 6);
  EXPECT_DOUBLE_EQ(fx.runin_tau_s, 1200);
  EXPECT_THROW(parse_effect("run-in:6W", fx), std::invalid_argument);
  EXPECT_THROW(parse_effect("magic:1", fx), std::invalid_argument);
}

PlantOptions warm(double hours) {
  PlantOptions o;
  o.speed = SpeedProfile::parse(std::to_string(hours) + "h@6000");
  return o;
}

TEST(SpindlePlant, WarmsUpTowardsTheNetworksSteadyState) {
  SpindlePlant p(warm(24));
  p.advance_to(20 * 3600);
  const auto ss = thermal::steady_state_c(p.network(), thermal::default_parameters(p.network()), 6000, 20);
  for (int ch = 1; ch <= 3; ++ch) EXPECT_NEAR(p.probe_temp_c(ch), ss[ch - 1], 1e-3) << "ch" << ch;
  EXPECT_GT(p.probe_temp_c(1), 25.0);
  EXPECT_DOUBLE_EQ(p.probe_temp_c(4), 20.0);
  EXPECT_NEAR(p.probe_temp_c(5), 20.0 + 0.5 * (p.probe_temp_c(2) - 20.0), 1e-12);
}

// A bearing fault's effect after 3 h of warm-up (the fault from 1 h): the rise it adds at the rear
// (channel 1) and front (channel 3) bearing probes over the same plant without it.
struct FaultRise {
  double rear_k, front_k;
  std::vector<double> extra_heat_w;
};
FaultRise rise_from_fault(const std::string& spec) {
  auto with_fault = warm(3);
  with_fault.faults.push_back(parse_fault(spec));
  SpindlePlant base(warm(3)), faulty(with_fault);
  base.advance_to(3 * 3600);
  faulty.advance_to(3 * 3600);
  const auto& extra = faulty.extra_heat_w();
  return {faulty.probe_temp_c(1) - base.probe_temp_c(1), faulty.probe_temp_c(3) - base.probe_temp_c(3),
          std::vector<double>(extra.data(), extra.data() + extra.size())};
}

TEST(SpindlePlant, BearingFaultHeatsTheRearBearingMost) {
  const FaultRise r = rise_from_fault("bearing:25W@1h");
  EXPECT_GT(r.rear_k, 1.0);
  EXPECT_GT(r.rear_k, r.front_k);
  EXPECT_DOUBLE_EQ(r.extra_heat_w[0], 25.0);
}

TEST(SpindlePlant, FrontBearingFaultHeatsTheFrontBearingMost) {
  const FaultRise r = rise_from_fault("bearing:front:25W@1h");
  EXPECT_GT(r.front_k, 1.0);
  EXPECT_GT(r.front_k, r.rear_k);
  EXPECT_DOUBLE_EQ(r.extra_heat_w[2], 25.0);
  EXPECT_DOUBLE_EQ(r.extra_heat_w[0], 0.0);
}

TEST(SpindlePlant, HiddenEffectsAddHeatTheModelDoesNotHave) {
  auto o = warm(2);
  parse_effect("bearing-tc:0.02", o.effects);
  SpindlePlant with(o), without(warm(2));
  with.advance_to(7200);
  without.advance_to(7200);
  EXPECT_GT(with.probe_temp_c(1) - without.probe_temp_c(1), 0.05);
  auto r = PlantOptions();
  r.speed = SpeedProfile::parse("1h@0,1h@6000");
  parse_effect("run-in:5W/10m", r.effects);
  SpindlePlant runin(r);
  runin.advance_to(3600 + 1);
  EXPECT_NEAR(runin.extra_heat_w()[0], 30.0, 0.5);  // 5 W per 1000 rpm x 6
  runin.advance_to(3600 + 1800);
  EXPECT_LT(runin.extra_heat_w()[0], 30.0 * std::exp(-2.5));
}

TEST(Probes, Pt1000AndFaultsReachTheFrontEnd) {
  EXPECT_NEAR(pt1000_ohm(0.0), 1000.0, 1e-9);
  EXPECT_NEAR(pt1000_ohm(100.0), 1385.055, 1e-3);
  auto o = warm(1);
  o.faults.push_back(parse_fault("open:ch2@0"));
  o.faults.push_back(parse_fault("short:ch3@0"));
  o.faults.push_back(parse_fault("noref@0"));
  SpindlePlant p(o);
  AnalogFrontEnd fe;
  apply_to_front_end(p, fe);
  EXPECT_EQ(fe.probe_fault[0], ProbeFault::kNone);
  EXPECT_EQ(fe.probe_fault[1], ProbeFault::kOpenSense);
  EXPECT_EQ(fe.probe_fault[2], ProbeFault::kShort);
  EXPECT_TRUE(fe.reference_lost);
  EXPECT_FALSE(fe.chip_missing);
  EXPECT_NEAR(fe.probe_ohm[3], pt1000_ohm(20.0), 1e-9);
}

// The one number reader behind profiles, faults, hidden effects and the CLI's numbers: the whole
// text, decimal, finite (hex was read by the plant's specifications while the CLI refused it).
TEST(DecimalNumber, TheWholeTextMustBeOneFiniteDecimalNumber) {
  EXPECT_EQ(io::decimal_number("12"), 12.0);
  EXPECT_EQ(io::decimal_number("-0.5"), -0.5);
  EXPECT_EQ(io::decimal_number("1e3"), 1000.0);
  EXPECT_EQ(io::decimal_number(" 6000\t"), 6000.0);
  for (const char* bad : {"", " ", "12x", "x", "6h", "1.5W", "nan", "inf", "1e999", "1e-400", "--1", "0x10", "0x1p4", "1 2"})
    EXPECT_FALSE(io::decimal_number(bad).has_value()) << bad;
}

}  // namespace
}  // namespace btsm::sim
