#pragma once
// Why a temperature cell of a recording is empty: the module's fault code for a channel over a
// stretch of rows, kept as comment lines after the rows so every reader that ignores '#' lines
// reads the file as before (backward compatible):
//
//   # sensor_fault: T2 open 1200.000-1500.000
//
// = channel T2 (hardware channel number, also for the ambient channel) reported `open` on every
// row with time_s from 1200 to 1500 s (inclusive, the recording's time_s). Codes: open, short,
// adc, ref, joined with '+' when several bits were set at once ("open+adc"); `fault` for a
// SENSOR_FAULT state without a fault bit. Written by `btsm record` (host/link/recorder.hpp).
#include "host/thermal/recording.hpp"

#include <string>
#include <vector>

namespace btsm::thermal {

struct SensorFaultEpisode {
  std::string channel;  // "T2"
  std::string code;     // "open", "short", "adc", "ref", "open+adc", "fault"
  double from_s = 0;    // time_s of the first and last row with this code, inclusive
  double to_s = 0;
};

inline constexpr const char* kSensorFaultKey = "sensor_fault";

// The value after "# sensor_fault: " for an episode ("T2 open 1200.000-1500.000").
std::string format_sensor_fault(const SensorFaultEpisode& e);

// One sensor_fault line's value read into `e`: "" when it is well formed, else what is wrong (not
// CHANNEL CODE FROM-TO, a channel other than T1..T5, an unknown code, a time that is not a finite
// number, a range that runs backwards).
std::string parse_sensor_fault(const std::string& value, SensorFaultEpisode& e);
// What parse_sensor_fault finds wrong, with the expected form; "" when well formed. The recording
// reader warns with it (the lines are informative comments: nothing acts on them).
std::string sensor_fault_line_problem(const std::string& value);

// The episodes of a recording's `sensor_fault` lines, in file order. Throws
// std::invalid_argument naming the recording and the line's text when one is malformed.
std::vector<SensorFaultEpisode> sensor_faults(const Recording& rec);

}  // namespace btsm::thermal
