// `--column NODE=COLUMN`: moving, dropping and refusing measurement mappings.
#include "host/thermal/network.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

namespace th = btsm::thermal;

namespace {

std::string column_of(const th::Network& net, const std::string& node) {
  const int k = net.node_index(node);
  for (const auto& m : net.measurements)
    if (m.node == k) return m.column;
  return "";
}

TEST(ColumnMap, MovesTheShaftToTheFifthProbe) {
  th::Network net = th::preset_network("spindle4");
  ASSERT_EQ(column_of(net, "shaft"), "T4");
  th::remap_measurements(net, {"shaft=T5"});
  EXPECT_EQ(column_of(net, "shaft"), "T5");
  EXPECT_EQ(column_of(net, "rear_bearing"), "T1");
  EXPECT_EQ(net.measurements.size(), 4u);
}

TEST(ColumnMap, EmptyColumnDropsTheMeasurement) {
  th::Network net = th::preset_network("spindle4");
  th::remap_measurements(net, {"shaft="});
  EXPECT_EQ(column_of(net, "shaft"), "");
  EXPECT_EQ(net.measurements.size(), 3u);
}

TEST(ColumnMap, BadSpecsNameWhatIsWrong) {
  th::Network net = th::preset_network("spindle4");
  auto message = [&](const std::string& spec) {
    try {
      th::Network n = net;
      th::remap_measurements(n, {spec});
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("shaftT5").find("expected NODE=COLUMN"), std::string::npos);
  EXPECT_NE(message("spindle=T5").find("no node 'spindle'"), std::string::npos);
  EXPECT_NE(message("shaft=T1").find("already measures node 'rear_bearing'"), std::string::npos);
}

}  // namespace
