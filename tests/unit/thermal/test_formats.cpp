// Input errors name what and where: recording CSV (file:line:column) and network JSON (field).
#include "host/thermal/fit.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"
#include "host/thermal/validate.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

namespace btsm::thermal {
namespace {

// A reader's refusal is bad input (io::InputError, a std::invalid_argument: exit 2 in the CLI).
std::string error_of(const std::string& csv) {
  try {
    parse_recording_csv(csv, "rec.csv");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(RecordingCsv, ParsesMetadataMissingValuesAndChannels) {
  const Recording r = parse_recording_csv("# module: 42\n# fw: 1.0\ntime_s,speed_rpm,ambient_c,T1,T2\n0,6000,25,25.1,\n5,6000,25.5,25.2,26\n",
                                          "x.csv");
  ASSERT_EQ(r.rows(), 2u);
  EXPECT_EQ(r.meta_value("module"), "42");
  EXPECT_EQ(r.channel_index("T2"), 1);
  EXPECT_TRUE(std::isnan(r.temp_c(0, 1)));
  EXPECT_DOUBLE_EQ(r.temp_c(1, 1), 26.0);
  EXPECT_DOUBLE_EQ(r.ambient_c[1], 25.5);
}

TEST(RecordingCsv, AcceptsAUtf8ByteOrderMarkBeforeTheHeader) {
  const Recording r = parse_recording_csv("\xEF\xBB\xBFtime_s,speed_rpm,ambient_c,T1\r\n0,6000,25,25.1\r\n5,6000,25,25.2\r\n", "bom.csv");
  ASSERT_EQ(r.rows(), 2u);
  EXPECT_DOUBLE_EQ(r.temp_c(1, 0), 25.2);
  // Only at the start of the file: the same bytes inside the header are a bad column name.
  EXPECT_NE(error_of("time_s,\xEF\xBB\xBFspeed_rpm,ambient_c,T1\n0,0,25,1\n").find("rec.csv:1:2:"), std::string::npos);
}

TEST(RecordingCsv, ErrorsNameFileLineAndColumn) {
  EXPECT_EQ(error_of("time_s,speed_rpm,T1\n0,0,1\n").rfind("rec.csv:1:3:", 0), 0u) << error_of("time_s,speed_rpm,T1\n0,0,1\n");
  const std::string bad = error_of("time_s,speed_rpm,ambient_c,T1,T2\n0,0,25,1,2\n5,0,25,1x,2\n");
  EXPECT_NE(bad.find("rec.csv:3:4:"), std::string::npos) << bad;
  EXPECT_NE(bad.find("'T1'"), std::string::npos) << bad;
  const std::string nan = error_of("time_s,speed_rpm,ambient_c,T1\n0,0,25,nan\n");
  EXPECT_NE(nan.find("rec.csv:2:4:"), std::string::npos) << nan;
  const std::string missing = error_of("time_s,speed_rpm,ambient_c,T1,T2\n0,0,25,1\n");
  EXPECT_NE(missing.find("rec.csv:2:"), std::string::npos) << missing;
  EXPECT_NE(missing.find("T2"), std::string::npos) << missing;
  const std::string time = error_of("time_s,speed_rpm,ambient_c,T1\n5,0,25,1\n5,0,25,1\n");
  EXPECT_NE(time.find("rec.csv:3:1:"), std::string::npos) << time;
  EXPECT_NE(error_of("").find("no header"), std::string::npos);
}

// 1e-400 was a "bad number"; it is a well-formed number too small for a double, i.e. 0. One too
// large is named as beyond the range, not as malformed.
TEST(RecordingCsv, NumbersBeyondADoubleAreZeroOrNamed) {
  const Recording r = parse_recording_csv("time_s,speed_rpm,ambient_c,T1\n0,1e-400,25,25.1\n5,0,25,1e-999\n", "tiny.csv");
  EXPECT_EQ(r.speed_rpm[0], 0.0);
  EXPECT_EQ(r.temp_c(1, 0), 0.0);
  const std::string big = error_of("time_s,speed_rpm,ambient_c,T1\n0,0,25,1e400\n");
  EXPECT_NE(big.find("rec.csv:2:4:"), std::string::npos) << big;
  EXPECT_NE(big.find("beyond the range of a number"), std::string::npos) << big;
}

// "+-20" was read as -20: the '+' was skipped and the rest read as a number (probe 7, P3-c). One
// sign only; a single leading '+' before a number is still taken.
TEST(RecordingCsv, ASignAfterAPlusIsABadNumber) {
  for (const char* cell : {"+-20", "+-0", "+-1e3", "++20"}) {
    const std::string why = error_of(std::string("time_s,speed_rpm,ambient_c,T1\n0,0,25,20\n5,0,25,") + cell + "\n");
    EXPECT_NE(why.find(std::string("rec.csv:3:4: column 'T1': bad number '") + cell + "'"), std::string::npos) << cell << ": " << why;
  }
  const Recording r = parse_recording_csv("time_s,speed_rpm,ambient_c,T1\n0,+6000,+25,+20.5\n5,0,25,+.5\n", "plus.csv");
  EXPECT_EQ(r.speed_rpm[0], 6000.0);
  EXPECT_EQ(r.temp_c(0, 0), 20.5);
  EXPECT_EQ(r.temp_c(1, 0), 0.5);
}

// Rows exactly the minimum step (1 ms) apart were refused ("0.009 is less than 0.001 s after
// 0.008": the difference of the two binary times is 0.000999...); less than it still is.
TEST(RecordingCsv, RowsExactlyTheMinimumStepApartAreKept) {
  const Recording r = parse_recording_csv("time_s,speed_rpm,ambient_c,T1\n0.008,0,25,25.1\n0.009,0,25,25.1\n1000000.001,0,25,25\n1000000.002,0,25,25\n",
                                          "ms.csv");
  EXPECT_EQ(r.rows(), 4u);
  const std::string close = error_of("time_s,speed_rpm,ambient_c,T1\n0.008,0,25,25.1\n0.0089,0,25,25.1\n");
  EXPECT_NE(close.find("duplicated timestamp"), std::string::npos) << close;
}

// A 15-year gap between two rows was bridged without a word (validate, heat); a long gap is now
// named with its place, a stop logged every 10 min among 5 s rows is not.
TEST(RecordingCsv, ALongGapBetweenRowsIsNamed) {
  std::string csv = "time_s,speed_rpm,ambient_c,T1\n";
  for (int k = 0; k < 50; ++k) csv += std::to_string(5 * k) + ",6000,25,26\n";
  const Recording even = parse_recording_csv(csv, "even.csv");
  EXPECT_EQ(long_gap_warning(even), "");
  const Recording gap = parse_recording_csv(csv + "500000000,0,25,25\n500000005,0,25,25\n", "gap.csv");
  const std::string w = long_gap_warning(gap);
  EXPECT_NE(w.find("gap.csv: a gap of 1.389e+05 h between the rows at t = 245 s and 500000000 s"), std::string::npos) << w;
  EXPECT_NE(w.find("speed (6000 rpm)"), std::string::npos) << w;
  const Recording sparse = parse_recording_csv(csv + "845,0,25,25\n1445,0,25,25\n", "sparse.csv");
  EXPECT_EQ(long_gap_warning(sparse), "");  // 10 min apart: under an hour
}

// A validation table printed NMSE -9.9e27 for a constant -273.15 degC column (the mean's rounding
// left 1e-25 K^2 of variance) and "--" for a constant 20 degC one: both have no variance.
TEST(RecordingCsv, AConstantReferenceHasNoNmse) {
  for (const double c : {-273.15, 20.0, 0.1}) {
    const Eigen::VectorXd ref = Eigen::VectorXd::Constant(37, c), pred = ref.array() + 0.5;
    const ErrorMetrics m = error_metrics(ref, pred);
    EXPECT_TRUE(std::isnan(m.nmse)) << c << ": " << m.nmse;
    EXPECT_NEAR(m.rmse_K, 0.5, 1e-9);
  }
  Eigen::VectorXd ramp(3);
  ramp << 20.0, 21.0, 22.0;
  EXPECT_NEAR(error_metrics(ramp, ramp).nmse, 1.0, 1e-12);
}

// repeated_samples: a copy shifted in time or thinned repeats; the same temperatures at another
// speed, another run with its own noise, or the same run's other half alone do not cover the rows.
TEST(RecordingCsv, RepeatedSamplesAreThoseOfACopyNotOfAnotherRun) {
  const auto run = [](int rows, double t0, int every, double rpm, double noise_k, int skip) {
    std::string s = "time_s,speed_rpm,ambient_c,T1,T2\n";
    unsigned state = 7;
    for (int k = skip; k < rows; k += every) {
      state = state * 1103515245u + 12345u;
      const double n = noise_k * (static_cast<int>((state >> 8) % 2001u) - 1000) / 1000.0;
      char line[128];
      std::snprintf(line, sizeof line, "%.10g,%g,20,%.4f,%.4f\n", t0 + 10.0 * k, k < rows / 2 ? rpm : 0.0,
                    20 + 8 * (1 - std::exp(-10.0 * k / 3000)) + n, 20 + 5 * (1 - std::exp(-10.0 * k / 3000)));
      s += line;
    }
    return parse_recording_csv(s, "r.csv");
  };
  const Recording a = run(400, 0, 1, 6000, 0, 0);
  EXPECT_NE(repeated_samples(a, run(400, 5e8, 1, 6000, 0, 0)).find("times shifted by 500000000 s"), std::string::npos);
  EXPECT_NE(repeated_samples(a, run(400, 0, 3, 6000, 0, 0)).find("1 of every 3 rows"), std::string::npos);
  EXPECT_EQ(repeated_samples(a, run(400, 0, 1, 5000, 0, 0)), "");     // another speed
  EXPECT_EQ(repeated_samples(a, run(400, 0, 1, 6000, 0.005, 0)), "");  // another run: 5 mK noise on T1
  EXPECT_NE(repeated_samples(a, run(400, 0, 1, 6000, 0, 200)), "");    // its cooling half: a's rows
  EXPECT_EQ(repeated_samples(run(400, 0, 1, 6000, 0, 200), a), "");    // half of a's rows are not a's copy
  EXPECT_THROW(refuse_repeated_recordings({a, run(400, 5e8, 2, 6000, 0, 0)}), std::invalid_argument);
}

TEST(RecordingCsv, WriterRoundTrip) {
  const std::string path = ::testing::TempDir() + "/btsm_rec_roundtrip.csv";
  {
    RecordingWriter w;
    w.open(path, {"T1", "T2"});
    w.write_meta("module", "7");
    w.append(0, 6000, 25, {25.12345, std::nan("")});
    w.append(5, 0, 25, {25.2, 26.0});
    EXPECT_THROW(w.write_meta("late", "x"), std::logic_error);
    EXPECT_THROW(w.append(10, 0, 25, {1.0}), std::invalid_argument);
  }
  const Recording r = read_recording_csv(path);
  EXPECT_EQ(r.meta_value("module"), "7");
  EXPECT_NEAR(r.temp_c(0, 0), 25.12345, 0.6e-4);
  EXPECT_TRUE(std::isnan(r.temp_c(0, 1)));
  std::remove(path.c_str());
}

std::string network_error(const nlohmann::json& j) {
  try {
    network_from_json(j, "net.json");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(NetworkJson, PresetRoundTripsAndBadFieldsErrorClearly) {
  const Network net = preset_network("spindle4");
  EXPECT_EQ(net.node_count(), 4);
  EXPECT_EQ(net.param_count(), 23);
  const Network again = network_from_json(network_to_json(net), "roundtrip");
  EXPECT_EQ(again.param_names(), net.param_names());

  nlohmann::json j = network_to_json(net);
  j["parameters"][0]["min"] = "small";
  EXPECT_NE(network_error(j).find("parameter 'R12': field 'min' must be a number"), std::string::npos) << network_error(j);
  j = network_to_json(net);
  j["links"][0]["both"] = {{{"resistance", "R99"}}};
  EXPECT_NE(network_error(j).find("unknown parameter 'R99'"), std::string::npos) << network_error(j);
  j = network_to_json(net);
  j["nodes"][0]["colour"] = "red";
  EXPECT_NE(network_error(j).find("unknown field 'colour'"), std::string::npos) << network_error(j);
  j = network_to_json(net);
  j["links"][0]["between"] = {"rear_bearing", "nowhere"};
  EXPECT_NE(network_error(j).find("unknown node 'nowhere'"), std::string::npos) << network_error(j);
  j = network_to_json(net);
  j["links"][5]["cooling"] = {{{"resistance", "Rc_a1"}, {"speed_exponent", -0.5}}};
  EXPECT_NE(network_error(j).find("speed_exponent 0"), std::string::npos) << network_error(j);
  EXPECT_THROW(preset_network("lathe9"), std::invalid_argument);
}

TEST(NetworkJson, FitRefusesToRunWithoutAScaleGauge) {
  Network net = preset_network("spindle4");
  net.sum_capacitance_J_per_K = std::nan("");
  Recording rec = parse_recording_csv("time_s,speed_rpm,ambient_c,T1,T2,T3,T4\n0,0,25,26,26,26,26\n5,0,25,26,26,26,26\n", "r.csv");
  try {
    fit_network(net, {rec});
    FAIL() << "expected a gauge error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("gauge"), std::string::npos);
  }
  Recording no_t4 = parse_recording_csv("time_s,speed_rpm,ambient_c,T1,T2,T3\n0,0,25,26,26,26\n5,0,25,26,26,26\n", "r3.csv");
  try {
    fit_network(preset_network("spindle4"), {no_t4});
    FAIL() << "expected a missing column error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("r3.csv: no column 'T4'"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace btsm::thermal
