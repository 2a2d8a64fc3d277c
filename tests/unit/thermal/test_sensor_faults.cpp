// '# sensor_fault:' lines of a recording (host/thermal/sensor_faults.hpp): parsed back, malformed
// ones named, and invisible to the reader otherwise (old files and old readers alike).
#include "host/thermal/sensor_faults.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace btsm::thermal;

TEST(SensorFaults, RoundTripAndTheRowsReadAsBefore) {
  const SensorFaultEpisode e{"T2", "open+adc", 1200, 1500.5};
  const std::string text = "# source: test\ntime_s,speed_rpm,ambient_c,T1,T2\n0,0,20,21,\n5,0,20,21,22\n# " +
                           std::string(kSensorFaultKey) + ": " + format_sensor_fault(e) + "\n";
  const Recording rec = parse_recording_csv(text, "rec.csv");
  ASSERT_EQ(rec.rows(), 2u);
  EXPECT_TRUE(std::isnan(rec.temp_c(0, 1)));
  const auto f = sensor_faults(rec);
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f[0].channel, "T2");
  EXPECT_EQ(f[0].code, "open+adc");
  EXPECT_DOUBLE_EQ(f[0].from_s, 1200);
  EXPECT_DOUBLE_EQ(f[0].to_s, 1500.5);
  EXPECT_TRUE(sensor_faults(parse_recording_csv("time_s,speed_rpm,ambient_c,T1\n0,0,20,21\n", "old.csv")).empty());
}

TEST(SensorFaults, MalformedLineIsNamed) {
  for (const char* bad : {"T2 open", "T2 open 10-x", "X2 open 1-2", "T2 open 5-1", "T2 open 1-2 extra"}) {
    const Recording rec =
        parse_recording_csv(std::string("time_s,speed_rpm,ambient_c,T1\n0,0,20,21\n# sensor_fault: ") + bad + "\n", "r.csv");
    try {
      sensor_faults(rec);
      ADD_FAILURE() << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("r.csv"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
}
