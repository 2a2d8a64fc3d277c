// Declared inputs: a second boundary column and 0/1 event columns, from the recording's metadata
// (or the command line) to the network JSON, the node matrices and the exact simulator.
#include "host/thermal/column_map.hpp"
#include "host/thermal/declared_columns.hpp"
#include "host/thermal/heat_inverse.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"
#include "host/thermal/simulator.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>

namespace btsm::thermal {
namespace {

// One node (C = 1000 J/K) tied to the room (g0 = 2 W/K) and to the coolant (g1 = 3 W/K); a lid
// conductance g2 = 5 W/K to the room while the lid is open.
const char* kOneNode = R"({
  "name": "box", "boundaries": ["coolant_c"], "events": ["lid_open"],
  "parameters": [ {"name": "C", "initial": 1000, "fixed": true}, {"name": "g0", "initial": 2}, {"name": "g1", "initial": 3},
                  {"name": "g2", "initial": 5} ],
  "nodes": [ {"name": "air", "capacitance": "C"} ],
  "links": [ {"name": "walls", "between": ["air", "ambient"], "both": [ {"conductance": "g0"} ]},
             {"name": "coolant", "between": ["coolant_c", "air"], "both": [ {"conductance": "g1"} ]},
             {"name": "lid", "between": ["air", "ambient"], "both": [ {"conductance": "g2", "event": "lid_open"} ]} ],
  "measurements": [ {"column": "T", "node": "air"} ]
})";

Recording box_recording(double dt, int rows, int lid_from, int lid_to) {
  Recording rec;
  rec.source = "box.csv";
  rec.channels = {"T", "coolant_c", "lid_open"};
  rec.temp_c = Eigen::MatrixXd::Zero(rows, 3);
  for (int k = 0; k < rows; ++k) {
    rec.time_s.push_back(k * dt);
    rec.speed_rpm.push_back(0);
    rec.ambient_c.push_back(20.0);
    rec.temp_c(k, 0) = NAN;
    rec.temp_c(k, 1) = 10.0;
    rec.temp_c(k, 2) = k >= lid_from && k < lid_to ? 1.0 : 0.0;
  }
  rec.meta = {{"boundary_columns", "coolant_c"}, {"event_columns", "lid_open"}};
  return rec;
}

TEST(DeclaredInputs, NetworkJsonRoundTripsBoundaryLinksAndEventTerms) {
  const Network net = network_from_json(nlohmann::json::parse(kOneNode), "box.json");
  ASSERT_EQ(net.boundaries.size(), 1u);
  ASSERT_EQ(net.events.size(), 1u);
  EXPECT_EQ(net.links[1].a, 0);  // the node end comes first whatever the JSON order
  EXPECT_EQ(net.links[1].b, boundary_end(0));
  ASSERT_EQ(net.links[2].operating.size(), 1u);
  EXPECT_EQ(net.links[2].operating[0].event, 0);
  EXPECT_EQ(net.links[2].cooling[0].event, 0);
  const Network back = network_from_json(network_to_json(net), "again");
  EXPECT_EQ(network_to_json(back), network_to_json(net));
  const Eigen::VectorXd p = default_parameters(net);
  const NodeMatrices closed = assemble(net, p, 0.0, 0u), open = assemble(net, p, 0.0, 1u);
  EXPECT_DOUBLE_EQ(closed.G(0, 0), 5.0);
  EXPECT_DOUBLE_EQ(open.G(0, 0), 10.0);
  EXPECT_DOUBLE_EQ(open.ambient_conductance[0], 7.0);
  EXPECT_DOUBLE_EQ(open.boundary_conductance(0, 0), 3.0);
}

TEST(DeclaredInputs, NetworkJsonRejectsWhatCannotBe) {
  auto with = [](const std::string& from, const std::string& to) {
    std::string s = kOneNode;
    s.replace(s.find(from), from.size(), to);
    return nlohmann::json::parse(s);
  };
  auto message = [](const nlohmann::json& j) {
    try {
      network_from_json(j, "box.json");
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message(with(R"("event": "lid_open")", R"("event": "door")")).find("unknown event column 'door'"), std::string::npos);
  EXPECT_NE(message(with(R"(["coolant_c", "air"])", R"(["coolant_c", "ambient"])")).find("at least one node end"), std::string::npos);
  EXPECT_NE(message(with(R"({"column": "T", "node": "air"})", R"({"column": "coolant_c", "node": "air"})")).find("boundary column"),
            std::string::npos);
  EXPECT_NE(message(with(R"("events": ["lid_open"])", R"("events": ["lid_open", "coolant_c"])")).find("declared as a boundary too"),
            std::string::npos);
}

TEST(DeclaredInputs, SimulatorFollowsTheBoundaryAndSwitchesTheEventConductance) {
  const Network net = network_from_json(nlohmann::json::parse(kOneNode), "box.json");
  const Eigen::VectorXd p = default_parameters(net);
  const double dt = 10.0;
  const Recording rec = box_recording(dt, 400, 200, 400);
  const Eigen::MatrixXd x = simulate_recording(net, p, rec, Eigen::VectorXd::Constant(1, 30.0));
  // lid closed: relaxes to (2*20 + 3*10)/5 = 14 degC with tau = 1000/5 = 200 s
  for (int k : {0, 7, 50, 199}) EXPECT_NEAR(x(k, 0), 14.0 + 16.0 * std::exp(-k * dt / 200.0), 1e-9) << k;
  // lid open from row 200: (7*20 + 3*10)/10 = 17 degC with tau = 100 s
  const double x200 = x(200, 0);
  for (int k : {201, 230, 399}) EXPECT_NEAR(x(k, 0), 17.0 + (x200 - 17.0) * std::exp(-(k - 200) * dt / 100.0), 1e-9) << k;
}

TEST(DeclaredInputs, SteadyStateAndStepNeedTheBoundaryTemperatures) {
  const Network net = network_from_json(nlohmann::json::parse(kOneNode), "box.json");
  const Eigen::VectorXd p = default_parameters(net);
  EXPECT_THROW(steady_state_c(net, p, 0.0, 20.0), std::invalid_argument);
  const Eigen::VectorXd b = Eigen::VectorXd::Constant(1, 10.0);
  EXPECT_NEAR(steady_state_c(net, p, 0.0, 20.0, &b)[0], 14.0, 1e-12);
  EXPECT_NEAR(steady_state_c(net, p, 0.0, 20.0, &b, 1u)[0], 17.0, 1e-12);
  Simulator sim(net, p);
  sim.reset(Eigen::VectorXd::Constant(1, 20.0));
  EXPECT_THROW(sim.step(1.0, 0.0, 20.0), std::invalid_argument);
}

TEST(DeclaredInputs, RecordingInputsNameTheBadCell) {
  const Network net = network_from_json(nlohmann::json::parse(kOneNode), "box.json");
  Recording rec = box_recording(10.0, 20, 5, 8);
  rec.temp_c(6, 2) = 0.5;
  try {
    recording_inputs(net, rec);
    FAIL() << "accepted an event value of 0.5";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("box.csv: event column 'lid_open' must be 0 or 1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("row 7"), std::string::npos) << e.what();
  }
  rec.channels[1] = "water";
  EXPECT_THROW(recording_inputs(net, rec), std::invalid_argument);
}

TEST(DeclaredInputs, InverseHeatKnowsTheBoundaryAndTheEvents) {
  // 10 W of unmodelled heat from row 300 on; the lid opens at row 200. Without the boundary and the
  // event in the inverse problem the coolant and the lid would show up as heat.
  const Network net = network_from_json(nlohmann::json::parse(kOneNode), "box.json");
  const Eigen::VectorXd p = default_parameters(net);
  Recording rec = box_recording(10.0, 600, 200, 600);
  for (int k = 0; k < 600; ++k) rec.temp_c(k, 1) = 10.0 + 0.01 * k;  // coolant drifts up 6 K
  Eigen::MatrixXd extra = Eigen::MatrixXd::Zero(600, 1);
  extra.bottomRows(300).setConstant(10.0);
  const Eigen::MatrixXd x = simulate_recording(net, p, rec, Eigen::VectorXd::Constant(1, 14.0), &extra);
  rec.temp_c.col(0) = x.col(0);
  InverseProblem ip = make_inverse_problem(net, p, rec, {0}, true);
  HeatInverseOptions o;
  o.step_s = 100.0;
  o.scheme = Discretisation::ExactZoh;
  o.noise_sigma_k = 1e-3;
  const HeatInverseResult r = solve_heat_inverse_fixed(ip, o, 1e-6);
  for (int i = 2; i < r.heat_w.rows() - 2; ++i) {
    if (std::abs(r.piece_start_s[static_cast<std::size_t>(i)] - 3000.0) < 250.0) continue;  // the step itself is smoothed
    EXPECT_NEAR(r.heat_w(i, 0), r.piece_start_s[static_cast<std::size_t>(i)] >= 3000.0 ? 10.0 : 0.0, 0.3) << r.piece_start_s[static_cast<std::size_t>(i)];
  }
}

TEST(DeclaredColumns, MetadataAndCommandLineDeclarationsMergeAndAreChecked) {
  const std::string text =
      "# boundary_columns: coolant_c\n"
      "time_s,speed_rpm,ambient_c,T,coolant_c,lid_open,pump\n"
      "0,0,20,25,10,0,1\n"
      "5,0,20,25,10,1,0\n";
  Recording rec = parse_recording_csv(text, "r.csv");
  EXPECT_EQ(boundary_columns(rec), std::vector<std::string>{"coolant_c"});
  EXPECT_TRUE(event_columns(rec).empty());
  declare_columns(rec, {}, {"lid_open, pump"});
  EXPECT_EQ(event_columns(rec), (std::vector<std::string>{"lid_open", "pump"}));
  EXPECT_TRUE(is_declared_column(rec, "pump"));
  EXPECT_FALSE(is_declared_column(rec, "T"));
  // the declarations survive writing and reading back
  const std::string path = ::testing::TempDir() + "/declared.csv";
  write_recording_csv(path, rec);
  const Recording back = read_recording_csv(path);
  EXPECT_EQ(boundary_columns(back), boundary_columns(rec));
  EXPECT_EQ(event_columns(back), event_columns(rec));

  Recording bad = parse_recording_csv(text, "r.csv");
  EXPECT_THROW(declare_columns(bad, {}, {"T"}), std::invalid_argument);  // 25 is not 0/1
  EXPECT_THROW(declare_columns(bad, {"water"}, {}), std::invalid_argument);
  EXPECT_THROW(declare_columns(bad, {}, {"coolant_c"}), std::invalid_argument);  // both kinds
  try {
    declare_columns(bad, {}, {"T"});
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("r.csv: event column 'T' must be 0 or 1, found 25"), std::string::npos) << e.what();
  }
}

TEST(DeclaredColumns, ADeclaredColumnNeverMeasuresANode) {
  Recording rec = box_recording(5.0, 4, 0, 0);
  Network net = network_from_json(nlohmann::json::parse(kOneNode), "box.json");
  EXPECT_NO_THROW(check_measurements_not_declared(net, rec));
  net.measurements[0].column = "lid_open";
  EXPECT_THROW(check_measurements_not_declared(net, rec), std::invalid_argument);
}

// time_s, speed_rpm and ambient_c given where a temperature column belongs (a network measuring
// one, --boundary time_s) were "no column 'time_s'" / "is not in the header": the user looked for a
// typo in a column the header plainly has (probe 7, P3-d). They are named as reserved now.
TEST(DeclaredColumns, AReservedColumnIsNamedAsReservedNotAsMissing) {
  const auto refusal = [](const std::function<void()>& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  Recording rec = box_recording(5.0, 4, 0, 0);
  rec.source = "box.csv";
  const std::string b = refusal([&] { declare_columns(rec, {"time_s"}, {}); });
  EXPECT_NE(b.find("box.csv: declared boundary column 'time_s' is reserved: the recording's time (s)"), std::string::npos) << b;
  Recording rec2 = box_recording(5.0, 4, 0, 0);
  rec2.source = "box.csv";
  const std::string e = refusal([&] { declare_columns(rec2, {}, {"ambient_c"}); });
  EXPECT_NE(e.find("declared event column 'ambient_c' is reserved: the ambient temperature"), std::string::npos) << e;
  Network net = network_from_json(nlohmann::json::parse(kOneNode), "box.json");
  net.measurements[0].column = "speed_rpm";
  const std::string m = refusal([&] { (void)measurement_columns(net, rec2); });
  EXPECT_NE(m.find("column 'speed_rpm' (measures node '"), std::string::npos) << m;
  EXPECT_NE(m.find("is reserved: the spindle speed (rpm)"), std::string::npos) << m;
  EXPECT_EQ(reserved_column_problem("T1"), "");
}

}  // namespace
}  // namespace btsm::thermal
