// Hidden effects of the simulated spindle (the truth side of the undeclared-effect suite): every
// family parses with its units, refuses nonsense naming it, and acts on the plant the way its
// physics says -- checked against the plant without the effect, in closed form where there is one.
#include "host/sim/plant/spindle_plant.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace btsm::sim {
namespace {

// spindle4 node indices
constexpr int kRear = 0, kHousing = 1, kFront = 2, kShaft = 3;

PlantOptions with(const std::string& profile, std::initializer_list<const char*> effects, const std::string& ambient = "20") {
  PlantOptions o;
  o.speed = SpeedProfile::parse(profile);
  o.ambient = AmbientProfile::parse(ambient);
  o.ch5 = Ch5Mode::ShaftEnd;
  for (const char* e : effects) parse_effect(e, o.effects);
  return o;
}

// Friction heat of the paper's sources at a speed (W per node).
Eigen::VectorXd sources_at(const SpindlePlant& p, double rpm) {
  return thermal::assemble(p.network(), thermal::default_parameters(p.network()), rpm).heat_w;
}

TEST(HiddenEffects, EveryFamilyParsesWithItsUnits) {
  HiddenEffects fx;
  parse_effect("transient:4W/20m@rear_bearing+front_bearing", fx);
  parse_effect("transient-gain:30%/15m@front_bearing", fx);
  parse_effect("temp-heat:-0.012@rear_bearing", fx);
  parse_effect("coupled-heat:3W/K@rear_bearing/rear_bearing-housing^0.5", fx);
  parse_effect("speed-heat:6W@shaft^2", fx);
  parse_effect("sensor-lag:5m@ch5", fx);
  parse_effect("sensor-drift:-0.02K/h@ch2", fx);
  parse_effect("ambient-lag:1h", fx);
  parse_effect("coolant:0.8W/K@housing=18,30m@19,30m@18", fx);
  parse_effect("event:1.5@housing+front_bearing=1h-1.25h,7200-7500", fx);
  parse_effect("latent:3000/2@shaft/0.1", fx);
  ASSERT_EQ(fx.transients.size(), 2u);
  EXPECT_EQ(fx.transients[0].nodes, (std::vector<std::string>{"rear_bearing", "front_bearing"}));
  EXPECT_FALSE(fx.transients[0].multiplicative);
  EXPECT_DOUBLE_EQ(fx.transients[0].amplitude, 4);
  EXPECT_DOUBLE_EQ(fx.transients[0].tau_s, 1200);
  EXPECT_TRUE(fx.transients[1].multiplicative);
  EXPECT_DOUBLE_EQ(fx.transients[1].amplitude, 0.3);
  EXPECT_DOUBLE_EQ(fx.temperature_heat[0].coeff_per_k, -0.012);
  EXPECT_EQ(fx.coupled_heat[0].hot, "rear_bearing");
  EXPECT_EQ(fx.coupled_heat[0].cold, "housing");
  EXPECT_DOUBLE_EQ(fx.coupled_heat[0].w_per_k, 3);
  EXPECT_DOUBLE_EQ(fx.coupled_heat[0].speed_exponent, 0.5);
  EXPECT_DOUBLE_EQ(fx.speed_heat[0].speed_exponent, 2);
  EXPECT_EQ(fx.sensor_lag[0].channel, 5);
  EXPECT_DOUBLE_EQ(fx.sensor_lag[0].tau_s, 300);
  EXPECT_DOUBLE_EQ(fx.sensor_drift[0].k_per_h, -0.02);
  EXPECT_DOUBLE_EQ(fx.ambient_lag_tau_s, 3600);
  EXPECT_DOUBLE_EQ(fx.boundaries[0].temperature.celsius_at(900), 18.5);
  EXPECT_EQ(fx.events[0].on_s.size(), 2u);
  EXPECT_TRUE(fx.events[0].on_at(3700));
  EXPECT_FALSE(fx.events[0].on_at(4500));
  EXPECT_DOUBLE_EQ(fx.latent[0].c_j_per_k, 3000);
  EXPECT_DOUBLE_EQ(fx.latent[0].g_ambient_w_per_k, 0.1);
  EXPECT_EQ(fx.boundary_columns(), std::vector<std::string>{"coolant_c"});
  EXPECT_EQ(fx.event_columns(), std::vector<std::string>{"lid_open"});
  EXPECT_EQ(fx.specs.size(), 11u);
  EXPECT_TRUE(fx.any());
  EXPECT_FALSE(HiddenEffects{}.any());
}

TEST(HiddenEffects, NonsenseIsRefusedNamingWhatIsWrong) {
  const std::pair<const char*, const char*> bad[] = {
      {"transient:4W@rear_bearing", "W/TAU"},
      {"transient:4W/20m", "@NODE"},
      {"transient:-1W/20m@housing", "heat"},
      {"temp-heat:0.5@rear_bearing", "coefficient"},
      {"coupled-heat:3@rear_bearing/housing", "HOT-COLD"},
      {"coupled-heat:3@rear_bearing/housing-housing", "different"},
      {"speed-heat:xW@housing", "not a number"},
      {"sensor-lag:5m@ch4", "ch4 is the ambient"},
      {"sensor-drift:0.01@T1", "channel"},
      {"coolant:0.5@housing", "PROFILE"},
      {"coolant:0.5@housing=hot", "coolant profile"},
      {"event:1@housing=2h", "START-END"},
      {"event:1@housing=2h-1h", "end must be after start"},
      {"latent:3000@shaft", "C/G"},
      {"ambient-lag:0", "time constant"},
      {"warp:9", "unknown kind"},
  };
  for (const auto& [spec, why] : bad) {
    HiddenEffects fx;
    try {
      parse_effect(spec, fx);
      ADD_FAILURE() << "accepted " << spec;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(spec), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << spec << ": " << e.what();
    }
  }
  // Nodes are checked against the network when the plant is built.
  EXPECT_THROW(SpindlePlant(with("1h@6000", {"speed-heat:5@spindle_nose"})), std::invalid_argument);
  try {
    SpindlePlant p(with("1h@6000", {"transient-gain:0.3/10m@housing"}));
    ADD_FAILURE();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("no friction source"), std::string::npos) << e.what();
  }
}

TEST(HiddenEffects, AdditiveTransientAfterEachSpeedIncreaseWhileRunning) {
  // From standstill (a cold machine at t = 0 counts as stopped before) to 6000 rpm: 6 x W.
  SpindlePlant p(with("1h@6000,1h@0,1h@3000,1h@5000", {"transient:5W/10m@housing"}));
  p.advance_to(1);
  EXPECT_NEAR(p.extra_heat_w()[kHousing], 30.0, 0.1);
  p.advance_to(600);
  EXPECT_NEAR(p.extra_heat_w()[kHousing], 30.0 * std::exp(-1.0), 0.1);
  p.advance_to(3600 + 60);  // stopped: no friction, no run-in heat
  EXPECT_EQ(p.extra_heat_w()[kHousing], 0.0);
  p.advance_to(3 * 3600 + 1);  // 0 -> 5000 rpm in two steps, the first long decayed: 15 + 10 W
  EXPECT_NEAR(p.extra_heat_w()[kHousing], 15.0 * std::exp(-3600.0 / 600) + 10.0, 0.1);
  EXPECT_EQ(p.extra_heat_w()[kRear], 0.0);
}

TEST(HiddenEffects, MultiplicativeTransientReArmsAtEveryStartOrSpeedChange) {
  SpindlePlant p(with("1h@6000,1h@4000", {"transient-gain:0.4/20m@rear_bearing"}));
  const double q6 = sources_at(p, 6000)[kRear], q4 = sources_at(p, 4000)[kRear];
  p.advance_to(1);
  EXPECT_NEAR(p.extra_heat_w()[kRear], 0.4 * q6, 0.05);
  p.advance_to(1200);
  EXPECT_NEAR(p.extra_heat_w()[kRear], 0.4 * q6 * std::exp(-1.0), 0.01);
  p.advance_to(3600 + 1);  // a speed decrease re-arms it too
  EXPECT_NEAR(p.extra_heat_w()[kRear], 0.4 * q4, 0.05);
  EXPECT_EQ(p.extra_heat_w()[kFront], 0.0);
}

// The run-in, "all friction heat higher after each start": a speed change while turning
// does not restart it, a start from standstill does (either kind).
TEST(HiddenEffects, StartsOnlyTransientsReArmAtAStartAndNotAtASpeedChange) {
  SpindlePlant p(with("1h@6000,1h@4000,1h@0,1h@4000", {"transient-gain-start:0.4/20m@rear_bearing", "transient-start:3W/20m@housing"}));
  const double q6 = sources_at(p, 6000)[kRear], q4 = sources_at(p, 4000)[kRear];
  p.advance_to(1);
  EXPECT_NEAR(p.extra_heat_w()[kRear], 0.4 * q6, 0.05);
  EXPECT_NEAR(p.extra_heat_w()[kHousing], 3.0, 0.01);  // W per start, not per 1000 rpm
  p.advance_to(3600 + 1);  // the step down keeps decaying from the start
  EXPECT_NEAR(p.extra_heat_w()[kRear], 0.4 * q4 * std::exp(-3.0), 0.01);
  EXPECT_NEAR(p.extra_heat_w()[kHousing], 3.0 * std::exp(-3.0), 0.01);
  p.advance_to(3 * 3600 + 1);  // started again
  EXPECT_NEAR(p.extra_heat_w()[kRear], 0.4 * q4, 0.05);
  EXPECT_NEAR(p.extra_heat_w()[kHousing], 3.0, 0.01);
}

TEST(HiddenEffects, TemperatureDependentHeatFollowsTheRiseOfItsNode) {
  SpindlePlant falling(with("3h@6000", {"temp-heat:-0.02@front_bearing"}));
  SpindlePlant base(with("3h@6000", {}));
  falling.advance_to(7200);
  base.advance_to(7200);
  const double theta = falling.node_temp_c()[kFront] - 20.0;
  EXPECT_NEAR(falling.extra_heat_w()[kFront], -0.02 * theta * sources_at(base, 6000)[kFront], 0.05);
  EXPECT_LT(falling.probe_temp_c(3), base.probe_temp_c(3) - 0.1);
  // The factor never turns friction into cooling.
  SpindlePlant floor(with("10h@6000", {"temp-heat:-0.2@front_bearing"}));
  floor.advance_to(10 * 3600);
  EXPECT_GE(floor.extra_heat_w()[kFront], -sources_at(base, 6000)[kFront] - 1e-9);
  // The historic spec is this family at the rear bearing.
  SpindlePlant legacy(with("2h@6000", {"bearing-tc:0.015"})), general(with("2h@6000", {"temp-heat:0.015@rear_bearing"}));
  legacy.advance_to(7200);
  general.advance_to(7200);
  for (int ch = 1; ch <= 5; ++ch) EXPECT_DOUBLE_EQ(legacy.probe_temp_c(ch), general.probe_temp_c(ch));
}

TEST(HiddenEffects, CoupledHeatIsDrivenByTheDifferenceOfTwoNodes) {
  SpindlePlant p(with("2h@7500,1h@0", {"coupled-heat:4@front_bearing/rear_bearing-housing^1"}));
  p.advance_to(3600);
  const auto& x = p.node_temp_c();
  const double expected = 4.0 * 1.5 * (x[kRear] - x[kHousing]);  // state of the previous step: same to ~1e-4
  EXPECT_GT(expected, 1.0);
  EXPECT_NEAR(p.extra_heat_w()[kFront], expected, 0.01 * expected);
  p.advance_to(2 * 3600 + 60);  // stopped
  EXPECT_EQ(p.extra_heat_w()[kFront], 0.0);
}

TEST(HiddenEffects, SpeedDrivenHeatReachesNodesWithoutASourceOfTheirOwn) {
  SpindlePlant p(with("4h@10000", {"speed-heat:5@shaft^2"})), base(with("4h@10000", {}));
  p.advance_to(4 * 3600);
  base.advance_to(4 * 3600);
  EXPECT_DOUBLE_EQ(p.extra_heat_w()[kShaft], 20.0);  // 5 W x (10000/5000)^2
  EXPECT_GT(p.probe_temp_c(5) - base.probe_temp_c(5), 1.0);  // T5 sits on the shaft end
  EXPECT_GT(p.probe_temp_c(5) - base.probe_temp_c(5), p.probe_temp_c(2) - base.probe_temp_c(2));
}

TEST(HiddenEffects, SensorLagAndDriftChangeTheReadingNotThePlant) {
  SpindlePlant lag(with("2h@6000", {"sensor-lag:5m@ch1", "sensor-drift:0.03@ch3"})), base(with("2h@6000", {}));
  // The lagging probe is a first-order filter of the true reading: integrate the same filter.
  double filtered = 20.0;
  for (int k = 1; k <= 2 * 3600 * 4; ++k) {
    lag.advance_to(k * 0.25);
    base.advance_to(k * 0.25);
    filtered = base.probe_temp_c(1) + (filtered - base.probe_temp_c(1)) * std::exp(-0.25 / 300.0);
  }
  EXPECT_NEAR(lag.probe_temp_c(1), filtered, 1e-9);
  EXPECT_LT(lag.probe_temp_c(1), base.probe_temp_c(1) - 0.01);
  EXPECT_DOUBLE_EQ(lag.node_temp_c()[kRear], base.node_temp_c()[kRear]);
  EXPECT_NEAR(lag.probe_temp_c(3) - base.probe_temp_c(3), 0.03 * 2, 1e-9);
  EXPECT_DOUBLE_EQ(lag.probe_temp_c(2), base.probe_temp_c(2));
}

TEST(HiddenEffects, AmbientLagMakesTheMachineFollowALaggingAir) {
  const std::string ramp = "20,1h@20,1h@24";
  SpindlePlant lag(with("6h@0", {"ambient-lag:30m"}, ramp)), base(with("6h@0", {}, ramp));
  lag.advance_to(2 * 3600);
  base.advance_to(2 * 3600);
  EXPECT_DOUBLE_EQ(lag.probe_temp_c(4), 24.0);  // the ambient probe reads the room
  // air after a 1 h ramp of 4 K through a 30 min lag: 4 - 4 tau/T (1 - e^-T/tau)
  EXPECT_NEAR(lag.network_ambient_c(), 24.0 - 4.0 * 0.5 * (1 - std::exp(-2.0)), 0.01);
  EXPECT_LT(lag.probe_temp_c(2), base.probe_temp_c(2) - 0.3);
  // with a constant room the lag changes nothing
  SpindlePlant still(with("2h@6000", {"ambient-lag:30m"})), plain(with("2h@6000", {}));
  still.advance_to(7200);
  plain.advance_to(7200);
  EXPECT_NEAR(still.probe_temp_c(1), plain.probe_temp_c(1), 1e-12);
}

TEST(HiddenEffects, CoolantIsASecondBoundaryAndItsColumnIsDeclared) {
  SpindlePlant cool(with("3h@6000", {"coolant:1.2@housing=16"})), base(with("3h@6000", {}));
  cool.advance_to(3 * 3600);
  base.advance_to(3 * 3600);
  EXPECT_NEAR(cool.extra_heat_w()[kHousing], 1.2 * (16.0 - cool.node_temp_c()[kHousing]), 0.01);
  EXPECT_LT(cool.probe_temp_c(2), base.probe_temp_c(2) - 1.0);
  EXPECT_EQ(cool.declared_columns(), std::vector<std::string>{"coolant_c"});
  EXPECT_EQ(cool.declared_values(), std::vector<double>{16.0});
  // a column that does nothing: recorded, no effect on the plant
  SpindlePlant idle(with("3h@6000", {"coolant:0@housing=16,1h@17"}));
  idle.advance_to(3 * 3600);
  EXPECT_DOUBLE_EQ(idle.probe_temp_c(2), base.probe_temp_c(2));
  EXPECT_EQ(idle.declared_values(), std::vector<double>{17.0});
}

TEST(HiddenEffects, EventsSwitchAConductanceToAmbientOnlyWhileOn) {
  SpindlePlant p(with("4h@6000", {"event:2@housing+shaft=2h-2.5h"})), base(with("4h@6000", {}));
  p.advance_to(2 * 3600 - 60);
  base.advance_to(2 * 3600 - 60);
  EXPECT_EQ(p.extra_heat_w()[kHousing], 0.0);
  EXPECT_DOUBLE_EQ(p.probe_temp_c(2), base.probe_temp_c(2));
  EXPECT_EQ(p.declared_values(), std::vector<double>{0.0});
  p.advance_to(2.25 * 3600);
  base.advance_to(2.25 * 3600);
  EXPECT_NEAR(p.extra_heat_w()[kHousing], 2.0 * (20.0 - p.node_temp_c()[kHousing]), 0.02);
  EXPECT_NEAR(p.extra_heat_w()[kShaft], 2.0 * (20.0 - p.node_temp_c()[kShaft]), 0.02);
  EXPECT_EQ(p.extra_heat_w()[kRear], 0.0);
  EXPECT_LT(p.probe_temp_c(2), base.probe_temp_c(2) - 0.3);
  EXPECT_EQ(p.declared_values(), std::vector<double>{1.0});
}

TEST(HiddenEffects, ALatentMassSlowsTheNodeButNotItsSteadyState) {
  SpindlePlant p(with("30h@6000", {"latent:4000/3@shaft"})), base(with("30h@6000", {}));
  p.advance_to(1800);
  base.advance_to(1800);
  EXPECT_LT(p.probe_temp_c(5), base.probe_temp_c(5) - 0.2);  // the extra mass soaks up heat
  EXPECT_LT(p.extra_heat_w()[kShaft], 0.0);
  p.advance_to(30 * 3600);
  base.advance_to(30 * 3600);
  EXPECT_NEAR(p.probe_temp_c(5), base.probe_temp_c(5), 1e-3);  // no path to ambient: same steady state
  EXPECT_NEAR(p.extra_heat_w()[kShaft], 0.0, 1e-3);
}

}  // namespace
}  // namespace btsm::sim
