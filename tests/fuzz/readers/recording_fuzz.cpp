// Recording CSV reader. Any input either parses or throws io::InputError (a std::invalid_argument)
// -- nothing else escapes, nothing crashes or hangs. A parsed recording holds what the format
// promises: a header with unique names, at least one row, strictly increasing finite time, speeds
// and temperatures inside the reader's physical bounds (NaN only for an empty temperature cell).
#include "fuzz_check.hpp"
#include "host/io/input_error.hpp"
#include "host/thermal/recording.hpp"

#include <cmath>
#include <set>
#include <string>

using namespace btsm;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  thermal::Recording r;
  try {
    r = thermal::parse_recording_csv(text, "fuzz.csv");
  } catch (const io::InputError&) {
    return 0;
  }
  FUZZ_CHECK(r.rows() >= 1);
  FUZZ_CHECK(!r.channels.empty());
  FUZZ_CHECK(r.speed_rpm.size() == r.rows() && r.ambient_c.size() == r.rows());
  FUZZ_CHECK(static_cast<size_t>(r.temp_c.rows()) == r.rows() && static_cast<size_t>(r.temp_c.cols()) == r.channels.size());
  FUZZ_CHECK(std::set<std::string>(r.channels.begin(), r.channels.end()).size() == r.channels.size());
  for (size_t k = 0; k < r.rows(); ++k) {
    FUZZ_CHECK(std::isfinite(r.time_s[k]));
    if (k > 0) FUZZ_CHECK(r.time_s[k] > r.time_s[k - 1]);
    FUZZ_CHECK(r.speed_rpm[k] >= 0 && r.speed_rpm[k] <= thermal::kMaxRecordedSpeedRpm);
    FUZZ_CHECK(r.ambient_c[k] >= thermal::kMinRecordedTempC && r.ambient_c[k] <= thermal::kMaxRecordedTempC);
    for (Eigen::Index c = 0; c < r.temp_c.cols(); ++c) {
      const double t = r.temp_c(static_cast<Eigen::Index>(k), c);
      FUZZ_CHECK(std::isnan(t) || (t >= thermal::kMinRecordedTempC && t <= thermal::kMaxRecordedTempC));
    }
  }
  return 0;
}
