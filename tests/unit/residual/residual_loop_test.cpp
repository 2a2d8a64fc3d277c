// The closed loop on synthetic spindles: the shared simulator with the spindle4 truth plus ONE effect
// the base model lacks (or none). Each effect must be found and named, and the check RMSE must drop at
// least five-fold; a clean recording must give "none".
#include "host/residual/effects.hpp"
#include "host/residual/residual_loop.hpp"
#include "host/residual/residual_report.hpp"
#include "host/thermal/simulator.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

namespace btsm::residual {
namespace {
namespace th = btsm::thermal;

struct Programme {
  std::string name;
  std::vector<std::pair<double, double>> segments;  // (hours, rpm)
  double ambient_phase = 0;
};

const std::vector<Programme> kFit = {
    {"fit_a", {{2.0, 4000}, {1.5, 7000}, {2.5, 0}}, 0.0},
    {"fit_b", {{1.5, 6000}, {1.5, 3000}, {0.5, 8000}, {2.0, 0}}, 2.0},
};
const std::vector<Programme> kCheck = {
    {"check", {{1.5, 5000}, {1.0, 8000}, {1.0, 2000}, {2.0, 0}}, 4.0},
};

// Simulates the truth (base + effect) with the shared simulator; 30 s sampling, noise 0.005 K,
// T4 (shaft) only measured at standstill, ambient drifting 1.5 K with an 8 h period.
th::Recording make_recording(const Programme& prog, const AugmentedModel& truth, int transient_node, unsigned seed) {
  th::Recording rec;
  rec.source = prog.name;
  const double dt = 30.0;
  double t = 0;
  for (const auto& [hours, rpm] : prog.segments)
    for (int k = 0; k < static_cast<int>(hours * 3600 / dt); ++k) {
      rec.time_s.push_back(t);
      rec.speed_rpm.push_back(rpm);
      rec.ambient_c.push_back(22.0 + 1.5 * std::sin(2 * M_PI * t / (8 * 3600.0) + prog.ambient_phase));
      t += dt;
    }
  for (const auto& m : truth.net.measurements) rec.channels.push_back(m.column);
  rec.temp_c = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rec.rows()), static_cast<Eigen::Index>(rec.channels.size()));
  Eigen::MatrixXd extra;
  if (transient_node >= 0) extra = transient_impulses_w(truth.net, rec, transient_node);
  const Eigen::VectorXd x0 = Eigen::VectorXd::Constant(truth.net.node_count(), rec.ambient_c[0]);
  const Eigen::MatrixXd nodes = th::simulate_recording(truth.net, truth.params, rec, x0, transient_node >= 0 ? &extra : nullptr);
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.005);
  for (std::size_t j = 0; j < truth.net.measurements.size(); ++j)
    for (std::size_t k = 0; k < rec.rows(); ++k) {
      const bool shaft_hidden = rec.channels[j] == "T4" && rec.speed_rpm[k] > 0;
      rec.temp_c(k, j) = shaft_hidden ? NAN : nodes(k, truth.net.measurements[j].node) + noise(rng);
    }
  return rec;
}

struct Scenario {
  std::string name;
  EffectKind kind;
  std::string where;   // node or column ("" = none)
  std::map<std::string, double> truth;
  std::string expect_effect;
  std::string expect_node;
  bool no_effect = false;
};

void PrintTo(const Scenario& s, std::ostream* os) { *os << s.name; }

class ResidualLoop : public ::testing::TestWithParam<Scenario> {};

TEST_P(ResidualLoop, FindsAndNamesTheEffect) {
  const Scenario& sc = GetParam();
  const th::Network base = th::preset_network("spindle4");
  const Eigen::VectorXd truth_params = th::default_parameters(base);
  AugmentedModel truth;
  int transient_node = -1;
  if (sc.no_effect) {
    truth.net = base;
    truth.params = truth_params;
  } else {
    EffectSpec spec{sc.kind, base.node_index(sc.where), sc.kind == EffectKind::SensorLag ? sc.where : ""};
    if (sc.kind == EffectKind::SensorLag) spec.node = 0;
    truth = augment(base, truth_params, spec, sc.truth);
    transient_node = truth.transient_node;
  }
  std::vector<th::Recording> fit, check;
  unsigned seed = 100;
  for (const auto& p : kFit) fit.push_back(make_recording(p, truth, transient_node, seed++));
  for (const auto& p : kCheck) check.push_back(make_recording(p, truth, transient_node, seed++));

  LoopOptions o;
  if (std::getenv("BTSM_RESIDUAL_VERBOSE")) o.progress = [](const std::string& s) { std::fprintf(stderr, "%s\n", s.c_str()); };
  const auto t0 = std::chrono::steady_clock::now();
  const LoopResult r = run_residual_loop(base, Eigen::VectorXd(), fit, check, o);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[ residual ] %-28s -> %-34s check rmse %.4f -> %.4f K (x%.1f)  %.1f s\n", sc.name.c_str(), r.label.c_str(),
              r.before_check.rmse_k, r.after_check.rmse_k, r.before_check.rmse_k / r.after_check.rmse_k, secs);
  for (const auto& c : r.candidates) std::printf("    %-34s %s\n", c.label.c_str(), c.reason.c_str());
  for (const auto& p : r.params) std::printf("    %s = %.5g +- %.2g %s\n", p.name.c_str(), p.value, p.sigma, p.unit.c_str());

  EXPECT_EQ(r.effect, sc.expect_effect) << format_table(r);
  if (sc.no_effect) {
    EXPECT_EQ(r.chosen, -1);
    EXPECT_NEAR(r.after_check.rmse_k, r.before_check.rmse_k, 1e-12);
    EXPECT_LT(r.before_check.rmse_k, 0.0075);
  } else {
    EXPECT_NE(std::find(r.nodes.begin(), r.nodes.end(), sc.expect_node), r.nodes.end()) << r.label;
    EXPECT_GE(r.before_check.rmse_k / r.after_check.rmse_k, 5.0);
  }
  const nlohmann::json j = to_json(r);
  for (const char* key : {"effect", "nodes", "rmse_before_K", "rmse_after_K", "candidates"}) EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["candidates"].size(), r.candidates.size());
}

INSTANTIATE_TEST_SUITE_P(
    Spindle4, ResidualLoop,
    ::testing::Values(
        Scenario{"none", EffectKind::ExtraHeatInput, "", {}, "none", "", true},
        Scenario{"transient_rear", EffectKind::HeatSourceTransient, "rear_bearing",
                 {{"a_transient_rear_bearing", 5.0}, {"tau_transient_rear_bearing", 900.0}}, "heat_source_transient", "rear_bearing"},
        Scenario{"temperature_dependent_front", EffectKind::TemperatureDependentHeat, "front_bearing",
                 {{"g_heat_T_front_bearing", -1.5}}, "temperature_dependent_heat", "front_bearing"},
        Scenario{"sensor_lag_T1", EffectKind::SensorLag, "T1", {{"tau_probe_T1", 120.0}}, "sensor_lag", "rear_bearing"},
        Scenario{"ambient_dynamics", EffectKind::AmbientDynamics, "", {{"C_ambient_lag", 1e5}, {"g_ambient_lag", 20.0}},
                 "ambient_dynamics", "housing"},
        Scenario{"extra_heat_housing", EffectKind::ExtraHeatInput, "housing", {{"q_extra_housing", 5.0}}, "extra_heat_input",
                 "housing"}),
    [](const ::testing::TestParamInfo<Scenario>& i) { return i.param.name; });

}  // namespace
}  // namespace btsm::residual

namespace btsm::residual {
namespace {

// Real data (CAIVIAC/FL_THERMAL, MIT; see tests/data/spindle-fl-thermal/README.md): the 3-node network
// chosen from the data does not describe the machine, and the loop must say so ("unexplained") rather
// than claim an effect; it must also name where the residual is.
TEST(ResidualLoopRealData, FlThermalIsUnexplainedNotMisattributed) {
  const std::string dir = std::string(BTSM_TEST_DATA_DIR) + "/spindle-fl-thermal/";
  const thermal::Network net = thermal::load_network(dir + "fl3_network.json");
  const std::vector<thermal::Recording> fit = {thermal::read_recording_csv(dir + "fl_fit_0-20h.csv")};
  const std::vector<thermal::Recording> check = {thermal::read_recording_csv(dir + "fl_check_20-46h.csv")};
  const LoopResult r = run_residual_loop(net, Eigen::VectorXd(), fit, check, {});
  EXPECT_EQ(r.effect, "unexplained") << format_table(r);
  EXPECT_GT(r.before_check.rmse_k, 0.3);
  EXPECT_NE(std::find(r.nodes.begin(), r.nodes.end(), "column"), r.nodes.end());
  EXPECT_FALSE(r.correlated_signals.empty());
  EXPECT_GE(r.candidates.size(), 5u);
}

const CandidateResult* candidate(const LoopResult& r, const std::string& label) {
  for (const auto& c : r.candidates)
    if (c.label == label) return &c;
  return nullptr;
}

// Real data (SJTU motorized spindle warm-up, no licence stated; see
// tests/data/spindle-sjtu-elongation/README.md): a 4-node network fitted on the 24 h warm-up predicts
// the 54 h plateau 1 K off (the machine does not follow the room sensor T15 that the network uses as
// its boundary, and the rear bearing levels off earlier than the fitted slow mode). No effect of the
// library fixes that; the loop must say "unexplained", not claim one.
TEST(ResidualLoopRealData, SjtuElongationIsUnexplainedNotMisattributed) {
  const std::string dir = std::string(BTSM_TEST_DATA_DIR) + "/spindle-sjtu-elongation/";
  const thermal::Network net = thermal::load_network(dir + "sjtu4_network.json");
  const std::vector<thermal::Recording> fit = {thermal::read_recording_csv(dir + "sjtu_fit_0-24h.csv")};
  const std::vector<thermal::Recording> check = {thermal::read_recording_csv(dir + "sjtu_check_24-78h.csv")};
  const LoopResult r = run_residual_loop(net, Eigen::VectorXd(), fit, check, {});
  EXPECT_EQ(r.effect, "unexplained") << format_table(r);
  EXPECT_LT(r.before_fit.rmse_k, 0.4);
  EXPECT_GT(r.before_check.rmse_k, 0.7);  // 1.06 K: the plateau is not predicted
  EXPECT_NE(std::find(r.nodes.begin(), r.nodes.end(), "rear"), r.nodes.end());
  EXPECT_NE(std::find(r.correlated_signals.begin(), r.correlated_signals.end(), "ambient_c"), r.correlated_signals.end());
  EXPECT_GE(r.candidates.size(), 7u);
  for (const auto& c : r.candidates) EXPECT_FALSE(c.accepted) << c.label << ": " << c.reason;
}

// Real data (Incubator DT 2023 calibration run, empty closed box, no licence found; see
// tests/data/incubator-dt/README.md). The heater input is mapped onto the speed_rpm column as
// electrical power in W. The 2-node network (the source's own model structure, C_heater fixed at the
// source's calibration) fits to 0.41 K and predicts the second half to 0.21 K, with a structured,
// non-white residual (too large a swing in the heater cycles). temperature_dependent_heat@heater
// improves the check x1.4 but its parameter is not significant (|z| ~ 2); nothing is claimed.
TEST(ResidualLoopRealData, IncubatorCalibrationIsUnexplained) {
  const std::string dir = std::string(BTSM_TEST_DATA_DIR) + "/incubator-dt/";
  const thermal::Network net = thermal::load_network(dir + "incubator2_2023_network.json");
  const std::vector<thermal::Recording> fit = {thermal::read_recording_csv(dir + "calib2023_fit_0-55min.csv")};
  const std::vector<thermal::Recording> check = {thermal::read_recording_csv(dir + "calib2023_check_55-111min.csv")};
  const LoopResult r = run_residual_loop(net, Eigen::VectorXd(), fit, check, {});
  EXPECT_EQ(r.effect, "unexplained") << format_table(r);
  EXPECT_TRUE(r.base_fit.converged);
  EXPECT_LT(r.before_check.rmse_k, 0.3);
  EXPECT_GT(r.before_check.rmse_k, 0.1);
  // The box-to-room resistance is the well-identified parameter; the source's own calibration of this
  // recording found G_box = 0.5763 W/K, i.e. R_box = 1.735 K/W.
  const int i = net.param_index("R_box");
  ASSERT_GE(i, 0);
  EXPECT_NEAR(r.base_fit.params[i], 1.735, 0.1);
  for (const auto& c : r.candidates) EXPECT_FALSE(c.accepted) << c.label << ": " << c.reason;
}

// Real data (Incubator DT 2021 lid-opening experiment, no licence found; see
// tests/data/incubator-dt/README.md): fitted on the 34 min before the first lid opening, checked on
// the 4.8 h with 7 lid openings and a cup of water. The network has neither, so the check error is
// large (5.9 K). CURRENT BEHAVIOUR, pinned on purpose: the loop claims temperature_dependent_heat@heater
// (heater heat falling as the heater warms; fitted 0.8 W/K at 125 W, the order of a copper heat bed's
// resistance rise, and significant on the lid-free fit part alone), because it trims the model's
// overshoot after every lid-opening recovery just past the 1.25 check threshold. The lid openings
// themselves stay unexplained (check RMSE after ~4.6 K, 30x the fit RMSE). If the decision rule is
// tightened to require that the claimed effect explains most of the check error, this test must change
// to "unexplained" -- deliberately.
// The lid openings (and a cup of water) drive the check error; a temperature-dependent heater
// term trims the overshoot after each opening (check x1.28) but leaves 36x the fit error. That is
// not an explanation, so the loop must say `unexplained` and still show the partial candidate.
TEST(ResidualLoopRealData, IncubatorLidOpeningsAreUnexplainedNotClaimedAsAHeaterEffect) {
  const std::string dir = std::string(BTSM_TEST_DATA_DIR) + "/incubator-dt/";
  const thermal::Network net = thermal::load_network(dir + "incubator2_2021_network.json");
  const std::vector<thermal::Recording> fit = {thermal::read_recording_csv(dir + "lid2021_fit_0-34min.csv")};
  const std::vector<thermal::Recording> check = {thermal::read_recording_csv(dir + "lid2021_check_34-323min.csv")};
  const LoopResult r = run_residual_loop(net, Eigen::VectorXd(), fit, check, {});
  EXPECT_EQ(r.effect, "unexplained") << format_table(r);
  EXPECT_GT(r.before_check.rmse_k, 3.0);
  const CandidateResult* c = candidate(r, "temperature_dependent_heat@heater");
  ASSERT_NE(c, nullptr);
  EXPECT_FALSE(c->accepted);
  EXPECT_GT(c->check_factor, 1.0);                  // it does trim part of the check error ...
  EXPECT_GT(c->check.rmse_k, 10.0 * c->fit.rmse_k);  // ... but most of it stays
}

}  // namespace
}  // namespace btsm::residual
