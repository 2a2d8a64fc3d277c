// reduce and the demo's index.html printed a node that does not fall after a stop (its pole at the
// reduction's clamp, 3e-8 1/s) as "555555.6 (until 10 min)" minutes.
#include "host/thermal/time_constant_text.hpp"

#include <gtest/gtest.h>

namespace th = btsm::thermal;

TEST(StopTimeConstantText, TheClampReadsDoesNotCool) {
  EXPECT_EQ(th::stop_time_constant_text(1.0 / 3e-8), "does not cool");
  EXPECT_EQ(th::stop_time_constant_text(84.5 * 60), "84.5");
  EXPECT_EQ(th::stop_time_constant_text(700.0 * 60), "700.0");  // slow, but it cools
}
