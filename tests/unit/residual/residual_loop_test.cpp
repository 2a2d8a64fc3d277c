// The closed loop on synthetic spindles: the spindle4 truth plus ONE effect of the library (or
// none). Each family must be proposed by the screening, fitted back to its truth, named with its
// nodes, and cut the check error (>= 5x, a sensor lag >= 3x) or bring it within 2x the noise (the
// issue's goal); clean data must give "none", and a family the fit recordings cannot identify is
// refused with the reason.
#include "host/residual/candidate_fit.hpp"
#include "host/residual/effects.hpp"
#include "host/residual/residual_loop.hpp"
#include "host/residual/residual_report.hpp"
#include "synthetic_spindle.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace btsm::residual {
namespace {
namespace th = btsm::thermal;

struct FamilyCase {
  std::string name;
  test::Truth truth;
  std::string family;
  std::vector<std::string> nodes;            // every one must be named, none outside `allowed`
  std::vector<std::string> allowed;
  std::string quantity;                      // an effect_quantities() name checked against the truth
  double quantity_truth = 0;
  double min_cut = 5;
};

void PrintTo(const FamilyCase& c, std::ostream* os) { *os << c.name; }

EffectSpec spec(EffectKind k, std::vector<std::string> nodes, std::string column = "") {
  const th::Network net = th::preset_network("spindle4");
  EffectSpec s;
  s.kind = k;
  for (const auto& n : nodes) s.nodes.push_back(net.node_index(n));
  s.column = std::move(column);
  return s;
}

LoopOptions quiet_options() {
  LoopOptions o;
  if (std::getenv("BTSM_RESIDUAL_VERBOSE")) o.progress = [](const std::string& s) { std::fprintf(stderr, "%s\n", s.c_str()); };
  return o;
}

class ResidualLoopFamily : public ::testing::TestWithParam<FamilyCase> {};

// Known misses skip by name with the reason (reported as skipped, not hidden). None at present.
// second_boundary_housing was one until the refits were continued past their iteration budget
// while still descending (LoopOptions::refit_continuation): at 300 iterations the base fit's joint
// stage stopped at 0.2261 K and the effect's joint refit at 0.0399 K (NOT converged), check cut
// x4.7 < 5. Continued, the base stage ends at 0.1948 K (661 iterations, converged), the refit at
// the noise (0.004975 K, 468 iterations, converged): named at housing, g 1.5 +- 0.0005 W/K, check
// 0.1601 -> 0.0051 K (x31.5).
bool not_met_yet(const std::string& name) { return name.empty(); }

TEST_P(ResidualLoopFamily, IsProposedFittedBackNamedAndCutsTheCheckError) {
  const FamilyCase& fc = GetParam();
  // A "DISABLED_" parameter name is not disabled under ctest: gtest_discover_tests marks only a
  // suite or test name that starts with it and runs the rest with --gtest_also_run_disabled_tests,
  // so such a case ran and failed there. The known misses skip here, by name, with the reason.
  if (not_met_yet(fc.name)) GTEST_SKIP() << fc.name << ": not met yet (see the comment at not_met_yet)";
  const test::Recordings rec = test::make_recordings(fc.truth);
  const auto t0 = std::chrono::steady_clock::now();
  const LoopResult r = run_residual_loop(th::preset_network("spindle4"), Eigen::VectorXd(), rec.fit, rec.check, quiet_options());
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[ residual ] %-30s -> %-10s %-46s check %.4f -> %.4f K (x%.1f) %.1f s\n", fc.name.c_str(), r.verdict.c_str(),
              r.label.c_str(), r.before_check.rmse_k, r.after_check.rmse_k, r.before_check.rmse_k / r.after_check.rmse_k, secs);
  for (const auto& q : r.quantities) std::printf("    %s = %.4g +- %.2g %s (%s)\n", q.name.c_str(), q.value, q.sigma, q.unit.c_str(), q.meaning.c_str());
  EXPECT_EQ(r.verdict, "effect") << format_table(r);
  EXPECT_EQ(r.effect, fc.family) << format_table(r);
  for (const auto& n : fc.nodes) EXPECT_NE(std::find(r.nodes.begin(), r.nodes.end(), n), r.nodes.end()) << n << " not named: " << r.label;
  for (const auto& n : r.nodes) EXPECT_NE(std::find(fc.allowed.begin(), fc.allowed.end(), n), fc.allowed.end()) << n << " named wrongly";
  // the goal: the check error cut >= min_cut, or brought to within 2x the noise (a base
  // re-polished close to the truth leaves less to cut: sensor_drift_T1's drift, fitted back to
  // 0.0203 +- 0.0002 K/h, leaves the check at 0.0051 K = the noise, x3.6 against that base)
  const double cut = r.before_check.rmse_k / r.after_check.rmse_k;
  EXPECT_TRUE(cut >= fc.min_cut || r.after_check.rmse_k <= 2 * r.noise_sigma_k)
      << "check cut x" << cut << " < " << fc.min_cut << " and " << r.after_check.rmse_k << " K > 2x the noise " << r.noise_sigma_k << " K";
  // fitted back: the physical quantity within 3 sigma (at least 10 %) of the truth
  const auto q = std::find_if(r.quantities.begin(), r.quantities.end(), [&](const EffectQuantity& x) { return x.name == fc.quantity; });
  ASSERT_NE(q, r.quantities.end()) << fc.quantity;
  EXPECT_NEAR(q->value, fc.quantity_truth, std::max(3 * q->sigma, 0.1 * std::abs(fc.quantity_truth))) << q->meaning;
  const nlohmann::json j = to_json(r);
  for (const char* key : {"verdict", "effect", "nodes", "rmse_before_K", "rmse_after_K", "candidates", "quantities"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["verdict"], "effect");
  EXPECT_EQ(j["undecided"], "");  // a claim carries no reason why it cannot be decided
}

FamilyCase family(std::string name, EffectSpec s, std::map<std::string, double> values, std::vector<std::string> nodes,
                  std::string quantity, double truth) {
  FamilyCase c;
  c.name = std::move(name);
  c.truth.spec = s;
  c.truth.values = std::move(values);
  c.family = effect_name(s.kind);
  c.nodes = nodes;
  c.allowed = nodes;
  c.quantity = std::move(quantity);
  c.quantity_truth = truth;
  return c;
}

std::vector<FamilyCase> family_cases() {
  std::vector<FamilyCase> v;
  {
    EffectSpec s = spec(EffectKind::HeatSourceTransient, {"rear_bearing", "front_bearing"});
    v.push_back(family("transient_additive", s, {{"tau_transient", 1200}, {"a_transient_rear_bearing", 4}, {"a_transient_front_bearing", 4}},
                       {"rear_bearing", "front_bearing"}, "tau_transient", 1200));
  }
  {
    // the run-in, "all friction heat higher after each start": restarted by starts only.
    // The warm-ups fit it exactly as one restarted by every speed change; the check run's steps
    // tell them apart (the loop's starts-only twin, residual_loop.cpp add_with_twins)
    EffectSpec s = spec(EffectKind::HeatSourceTransient, {"rear_bearing", "front_bearing"});
    s.trigger = TransientTrigger::Start;
    s.multiplicative = true;
    v.push_back(family("transient_gain_starts_only", s,
                       {{"tau_transient", 1800}, {"a_transient_rear_bearing", 0.3}, {"a_transient_front_bearing", 0.3}},
                       {"rear_bearing", "front_bearing"}, "tau_transient", 1800));
  }
  v.push_back(family("temperature_dependent_rising", spec(EffectKind::TemperatureDependentHeat, {"rear_bearing"}),
                     {{"k_heat_T_rear_bearing", 0.6}}, {"rear_bearing"}, "heat_per_K_rear_bearing", 0.6));
  {
    EffectSpec s = spec(EffectKind::CoupledHeat, {"front_bearing"});
    s.hot = 0;   // rear_bearing
    s.cold = 1;  // housing
    FamilyCase c = family("coupled_heat", s, {{"k_couple_front_bearing", 3.0}}, {"front_bearing"}, "coupled_heat_front_bearing", 3.0);
    c.allowed = {"front_bearing", "rear_bearing", "housing"};
    v.push_back(c);
  }
  v.push_back(family("extra_heat_housing", spec(EffectKind::ExtraHeatInput, {"housing"}), {{"q_extra_housing", 6.0}}, {"housing"},
                     "extra_heat_housing", 6.0));
  {
    EffectSpec s = spec(EffectKind::SensorLag, {}, "T2");
    FamilyCase c = family("sensor_lag_T2", s, {{"tau_probe_T2", 300}}, {"housing"}, "tau_probe_T2", 300);
    c.min_cut = 3;
    v.push_back(c);
  }
  v.push_back(family("sensor_drift_T1", spec(EffectKind::SensorDrift, {}, "T1"), {{"d_T1", 0.02}}, {"rear_bearing"}, "drift_T1", 0.02));
  {
    FamilyCase c = family("ambient_dynamics", spec(EffectKind::AmbientDynamics, {}), {{"C_ambient_lag", 2e5}, {"g_ambient_lag", 100}},
                          {}, "tau_ambient_lag", 2000);
    c.truth.ambient_varies = true;
    c.allowed = {"rear_bearing", "housing", "front_bearing", "shaft"};
    v.push_back(c);
  }
  {
    FamilyCase c = family("second_boundary_housing", spec(EffectKind::SecondBoundary, {"housing"}, "coolant_c"),
                          {{"g_coolant_c_housing", 1.5}}, {"housing"}, "g_coolant_c_housing", 1.5);
    c.truth.coolant_column = true;
    v.push_back(c);
  }
  {
    FamilyCase c = family("event_conductance", spec(EffectKind::EventConductance, {"housing"}, "lid_open"),
                          {{"g_lid_open_housing", 1.5}}, {"housing"}, "g_lid_open_housing", 1.5);
    c.truth.event_column = true;
    v.push_back(c);
  }
  v.push_back(family("latent_mass_housing", spec(EffectKind::LatentMass, {"housing"}), {{"C_latent_housing", 4000}, {"g_latent_housing", 3}},
                     {"housing"}, "C_latent_housing", 4000));
  return v;
}

INSTANTIATE_TEST_SUITE_P(Spindle4, ResidualLoopFamily, ::testing::ValuesIn(family_cases()),
                         [](const ::testing::TestParamInfo<FamilyCase>& i) {
                           return i.param.name;
                         });

// Clean data: nothing beyond noise, no claim, the after model is the base model.
// The run-in transient as the simulated plant defines it (host/sim/plant/effect_dynamics.cpp):
// a W per 1000 rpm of increase, decaying with tau, added at the node while it runs. The library's
// virtual state must deliver that heat and nothing else: its coupling g (T_state - T_node) also
// drains g (T_node - T_ambient) once the state has decayed, a leak that grows with the capacity
// of the state (at C = 1000 J/K: 0.1-0.2 W at a 20-30 K bearing rise, and seed 99's suite case
// fitted to 0.013 K with the plant's own base values instead of 0.0019 K).
TEST(TransientEffect, TheVirtualStateDeliversThePlantsRunInHeatWithoutALeak) {
  const th::Network base = th::preset_network("spindle4");
  const Eigen::VectorXd bp = th::default_parameters(base);
  const int node = base.node_index("rear_bearing");
  const double a_w = 5.6, tau_s = 1200.0, rpm = 8000.0;
  EffectSpec e;
  e.kind = EffectKind::HeatSourceTransient;
  e.nodes = {node};
  e.trigger = TransientTrigger::SpeedIncrease;
  e.tau_s = tau_s;
  const AugmentedModel am = augment(base, bp, e, {{"a_transient_rear_bearing", a_w}, {"tau_transient", tau_s}});
  // 6 h at 8000 rpm from a cold start, then 4 h at rest, 1 s rows
  th::Recording rec;
  rec.source = "run_in.csv";
  for (int k = 0; k <= 36000; ++k) {
    rec.time_s.push_back(k);
    rec.speed_rpm.push_back(k >= 10 && k < 10 + 6 * 3600 ? rpm : 0.0);
    rec.ambient_c.push_back(21.0);
  }
  for (const auto& m : base.measurements) rec.channels.push_back(m.column);
  rec.temp_c = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rec.rows()), static_cast<Eigen::Index>(rec.channels.size()));
  const Eigen::MatrixXd impulses = transient_impulses_w(am.net, am.params, rec, am.transient_node, am.trigger);
  const Eigen::MatrixXd with_state =
      th::simulate_recording(am.net, am.params, rec, Eigen::VectorXd::Constant(am.net.node_count(), 21.0), &impulses);
  // the plant's heat, a (rpm / 1000) e^(-t/tau) while running, averaged over each row (the
  // simulator holds a row's heat over its interval); the state starts at the end of the start row
  Eigen::MatrixXd plant_w = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rec.rows()), base.node_count());
  for (std::size_t k = 11; k + 1 < rec.rows(); ++k)
    if (rec.speed_rpm[k] > 0)
      plant_w(static_cast<Eigen::Index>(k), node) = a_w * rpm / 1000.0 * tau_s *
                                                   (std::exp(-(rec.time_s[k] - 11.0) / tau_s) - std::exp(-(rec.time_s[k + 1] - 11.0) / tau_s));
  const Eigen::MatrixXd plant = th::simulate_recording(base, bp, rec, Eigen::VectorXd::Constant(base.node_count(), 21.0), &plant_w);
  double worst = 0;
  for (Eigen::Index k = 0; k < plant.rows(); ++k)
    for (int n = 0; n < base.node_count(); ++n) worst = std::max(worst, std::abs(with_state(k, n) - plant(k, n)));
  std::printf("library transient vs the plant's: largest node difference %.5f K\n", worst);
  EXPECT_LT(worst, 0.005) << "largest node temperature difference [K] between the library's transient and the plant's";
}

// The triggers' units: an increase adds its 1000-rpm units, a restart tops the state up to one
// unit (what the decay took since the last), a starts-only transient ignores a speed change while
// turning. Warm-ups restart both restarting kinds alike; a speed step while turning does not.
TEST(TransientEffect, TriggersRestartOrPileUpAsTheirKindSays) {
  const th::Network base = th::preset_network("spindle4");
  th::Recording rec;
  rec.source = "steps.csv";
  // standstill, 4000 rpm at 100 s, 6000 rpm at 1900 s, stop at 3700 s, 4000 rpm again at 5500 s
  for (int k = 0; k <= 70; ++k) {
    const double t = 100.0 * k;
    rec.time_s.push_back(t);
    rec.speed_rpm.push_back(t < 100 ? 0.0 : t < 1900 ? 4000.0 : t < 3700 ? 6000.0 : t < 5500 ? 0.0 : 4000.0);
    rec.ambient_c.push_back(21.0);
  }
  const std::vector<double> inc = transient_triggers(base, rec, TransientTrigger::SpeedIncrease);
  EXPECT_DOUBLE_EQ(inc[1], 4.0);
  EXPECT_DOUBLE_EQ(inc[19], 2.0);
  EXPECT_DOUBLE_EQ(inc[55], 4.0);
  const double tau = 1800.0;
  const std::vector<double> change = transient_triggers(base, rec, TransientTrigger::StartOrChange, tau);
  EXPECT_DOUBLE_EQ(change[1], 1.0);
  EXPECT_NEAR(change[19], 1.0 - std::exp(-1800.0 / tau), 1e-12);  // topped up, not a second unit
  EXPECT_NEAR(change[55], 1.0 - std::exp(-3600.0 / tau), 1e-12);
  const std::vector<double> start = transient_triggers(base, rec, TransientTrigger::Start, tau);
  EXPECT_DOUBLE_EQ(start[1], 1.0);
  EXPECT_DOUBLE_EQ(start[19], 0.0);  // a speed change while turning
  EXPECT_NEAR(start[55], 1.0 - std::exp(-5400.0 / tau), 1e-12);
  EXPECT_FALSE(starts_only_restarts_alike(base, {rec}));
  th::Recording warm = rec;
  for (auto& w : warm.speed_rpm) w = w > 0 ? 5000.0 : 0.0;
  warm.speed_rpm.resize(37);
  warm.time_s.resize(37);
  warm.ambient_c.resize(37);
  EXPECT_TRUE(starts_only_restarts_alike(base, {warm}));
}

TEST(ResidualLoopDecision, CleanDataGiveNone) {
  test::Truth t;
  t.no_effect = true;
  const test::Recordings rec = test::make_recordings(t);
  const LoopResult r = run_residual_loop(th::preset_network("spindle4"), Eigen::VectorXd(), rec.fit, rec.check, quiet_options());
  EXPECT_EQ(r.verdict, "none") << format_table(r);
  EXPECT_EQ(r.effect, "none");
  EXPECT_EQ(r.chosen, -1);
  EXPECT_DOUBLE_EQ(r.after_check.rmse_k, r.before_check.rmse_k);
  for (const auto& c : r.candidates) EXPECT_NE(c.status, "effect") << c.label;
}

// A base that fits the fit recordings at their noise leaves no better minimum of the fit part for a
// refit to be led to: the starts that lead out of the base's basin (the base refitted around the
// screening's effect, the staged fits of base + effect) are skipped, and every candidate is judged
// the same as with them (LoopOptions::basin_starts_above_noise). With an effect the base misfits
// far above the gate and every start runs.
TEST(ResidualLoopDecision, ABaseAtTheNoiseSkipsTheStartsThatLeaveItsBasinAndJudgesAlike) {
  const auto run = [](const test::Truth& t, double gate, std::string& log, int max_candidates = LoopOptions{}.max_candidates) {
    LoopOptions o = quiet_options();
    o.basin_starts_above_noise = gate;
    o.max_candidates = max_candidates;
    o.progress = [&log](const std::string& s) { log += s + "\n"; };
    const test::Recordings rec = test::make_recordings(t);
    return run_residual_loop(th::preset_network("spindle4"), Eigen::VectorXd(), rec.fit, rec.check, o);
  };
  const auto basin_starts = [](const std::string& log) {
    return log.find("base refitted around the screening's effect") != std::string::npos || log.find("staged fit of base") != std::string::npos;
  };
  test::Truth clean;
  clean.no_effect = true;
  std::string gated, always;
  const LoopResult g = run(clean, LoopOptions{}.basin_starts_above_noise, gated);
  const LoopResult a = run(clean, 0.0, always);
  ASSERT_LE(g.before_fit.rmse_k, 1.05 * g.noise_sigma_k) << "the clean case no longer fits at its noise";
  EXPECT_NE(gated.find("at their noise"), std::string::npos) << gated;
  EXPECT_FALSE(basin_starts(gated)) << gated;
  EXPECT_TRUE(basin_starts(always)) << "with the gate off those starts run: " << always;
  EXPECT_EQ(g.verdict, a.verdict);
  EXPECT_EQ(g.label, a.label);
  ASSERT_EQ(g.candidates.size(), a.candidates.size());
  for (std::size_t i = 0; i < g.candidates.size(); ++i) {
    EXPECT_EQ(g.candidates[i].label, a.candidates[i].label);
    EXPECT_EQ(g.candidates[i].status, a.candidates[i].status) << g.candidates[i].label;
  }

  test::Truth lag;  // the family case sensor_lag_T2; its refits are not the point here
  lag.spec = spec(EffectKind::SensorLag, {}, "T2");
  lag.values["tau_probe_T2"] = 300;
  std::string with_effect;
  const LoopResult e = run(lag, LoopOptions{}.basin_starts_above_noise, with_effect, 0);
  EXPECT_GT(e.before_fit.rmse_k, 1.05 * e.noise_sigma_k);
  EXPECT_EQ(with_effect.find("at their noise"), std::string::npos) << with_effect;
}

// Clean plant recorded by a module (metadata module_id), every reading through a filter that lags
// it by 20 s (below the 30 s sample period, as the module's own filter): the base model's check
// error is above twice the white noise (what the noise test alone calls something to explain) but
// within the check recordings' measurement floor (noise and a reading up to one sample period
// late). The held-out part holds nothing to explain, not even part of it: `none`, with that
// reason, and no candidate `partial` or `effect`. (Recordings without module_id: the floor is the
// noise sigma, which the family tests above run on.)
TEST(ResidualLoopDecision, ACheckErrorWithinTheMeasurementFloorGivesNone) {
  test::Truth t;
  t.no_effect = true;
  t.reading_lag_s = 20;
  t.module_recording = true;
  const test::Recordings rec = test::make_recordings(t);
  const LoopResult r = run_residual_loop(th::preset_network("spindle4"), Eigen::VectorXd(), rec.fit, rec.check, quiet_options());
  ASSERT_GT(r.check_floor_k, r.noise_sigma_k);
  EXPECT_GT(r.before_check.rmse_k, 2 * r.noise_sigma_k) << "the case no longer tests the floor: " << format_table(r);
  EXPECT_LE(r.before_check.rmse_k, r.check_floor_k) << format_table(r);
  EXPECT_EQ(r.verdict, "none") << format_table(r);
  EXPECT_NE(r.explanation.find("measurement floor"), std::string::npos) << r.explanation;
  for (const auto& c : r.candidates) EXPECT_TRUE(c.status != "effect" && c.status != "partial") << c.label << ": " << c.reason;
  EXPECT_EQ(to_json(r)["check_floor_K"], r.check_floor_k);
}

// A declared event column without any event in the fit recordings: the family is refused with the
// reason, even though the check recording has events.
TEST(ResidualLoopDecision, AnEventFamilyWithoutEventsInTheFitPartIsRefused) {
  test::Truth t;
  t.spec = spec(EffectKind::EventConductance, {"housing"}, "lid_open");
  t.values = {{"g_lid_open_housing", 1.5}};
  t.event_column = true;
  test::Recordings rec = test::make_recordings(t);
  for (auto& f : rec.fit) f.temp_c.col(f.channel_index("lid_open")).setZero();  // and re-simulate below
  test::Truth none = t;
  none.event_column = true;
  // the fit part: the same truth, but the lid never opens
  for (std::size_t i = 0; i < rec.fit.size(); ++i) {
    th::Recording& f = rec.fit[i];
    const Eigen::MatrixXd x = th::simulate_recording(rec.truth.net, rec.truth.params, f,
                                                     Eigen::VectorXd::Constant(rec.truth.net.node_count(), f.ambient_c[0]));
    for (std::size_t j = 0; j < rec.truth.net.measurements.size(); ++j)
      f.temp_c.col(static_cast<Eigen::Index>(j)) = x.col(rec.truth.net.measurements[j].node);
  }
  LoopOptions o = quiet_options();
  o.effects = {EffectKind::EventConductance, EffectKind::ExtraHeatInput};
  const LoopResult r = run_residual_loop(th::preset_network("spindle4"), Eigen::VectorXd(), rec.fit, rec.check, o);
  const auto it = std::find_if(r.candidates.begin(), r.candidates.end(), [](const CandidateResult& c) { return c.effect == "event_conductance"; });
  ASSERT_NE(it, r.candidates.end()) << format_table(r);
  EXPECT_EQ(it->status, "refused");
  EXPECT_NE(it->reason.find("no event in the fit recordings"), std::string::npos) << it->reason;
  EXPECT_NE(r.verdict, "effect") << format_table(r);
}

// A constant room: ambient dynamics cannot be identified and is refused (issue 14: it used to be
// claimed with a 1e8 J/K lag capacity on a constant 20 degC ambient).
TEST(ResidualLoopDecision, AmbientDynamicsIsRefusedWhenTheAmbientHardlyVaries) {
  test::Truth t;
  t.spec = spec(EffectKind::LatentMass, {"housing"});
  t.values = {{"C_latent_housing", 4000}, {"g_latent_housing", 3}};
  const test::Recordings rec = test::make_recordings(t);
  LoopOptions o = quiet_options();
  o.effects = {EffectKind::AmbientDynamics};
  const LoopResult r = run_residual_loop(th::preset_network("spindle4"), Eigen::VectorXd(), rec.fit, rec.check, o);
  ASSERT_FALSE(r.candidates.empty());
  EXPECT_EQ(r.candidates[0].status, "refused");
  EXPECT_NE(r.candidates[0].reason.find("ambient hardly varies"), std::string::npos) << r.candidates[0].reason;
  EXPECT_NE(r.verdict, "effect");
}

// Only a part of the check error can be explained by the families allowed: `partial`, with the
// family named but not claimed, and the after error of that partial model reported.
TEST(ResidualLoopDecision, APartialExplanationIsReportedNotClaimed) {
  test::Truth t;
  t.spec = spec(EffectKind::ExtraHeatInput, {"housing"});
  t.values = {{"q_extra_housing", 6.0}};
  test::Recordings rec = test::make_recordings(t);
  // plus a drift of T3 in the check run only: nothing fitted on the fit part can explain it
  const int c3 = rec.check[0].channel_index("T3");
  for (Eigen::Index k = 0; k < rec.check[0].temp_c.rows(); ++k)
    rec.check[0].temp_c(k, c3) += 0.06 * std::sin(rec.check[0].time_s[static_cast<std::size_t>(k)] / 2000.0);
  const LoopResult r = run_residual_loop(th::preset_network("spindle4"), Eigen::VectorXd(), rec.fit, rec.check, quiet_options());
  EXPECT_EQ(r.verdict, "partial") << format_table(r);
  EXPECT_EQ(r.effect, "extra_heat_input");
  EXPECT_LT(r.after_check.rmse_k, r.before_check.rmse_k / 1.25);
  EXPECT_GT(r.after_check.rmse_k, r.before_check.rmse_k / 2);
  EXPECT_EQ(to_json(r)["verdict"], "partial");
  // and why the fit part cannot decide more: it is fitted to its noise, the check's drift is not in it
  EXPECT_NE(r.undecided.find("the fit part does not hold what the check needs"), std::string::npos) << r.undecided;
  EXPECT_NE(r.explanation.find(r.undecided), std::string::npos) << r.explanation;
  EXPECT_EQ(to_json(r)["undecided"], r.undecided);
}

}  // namespace
}  // namespace btsm::residual
