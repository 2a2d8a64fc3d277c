#include "host/report/axis_ticks.hpp"
#include "host/report/plot.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;
using namespace btsm::report;

TEST(AxisTicks, CoversDataWithNiceSteps) {
  const AxisTicks t = linear_ticks(0.13, 9.7, 6);
  EXPECT_LE(t.lo, 0.13);
  EXPECT_GE(t.hi, 9.7);
  ASSERT_GE(t.values.size(), 3u);
  const double step = t.values[1] - t.values[0];
  EXPECT_NEAR(step, 2.0, 1e-12);  // span 9.6 over ~6 ticks -> 2
}

TEST(AxisTicks, DegenerateAndNonFiniteRangesStillUsable) {
  const AxisTicks flat = linear_ticks(25.0, 25.0);
  EXPECT_LT(flat.lo, 25.0);
  EXPECT_GT(flat.hi, 25.0);
  const AxisTicks nan = linear_ticks(NAN, NAN);
  EXPECT_LT(nan.lo, nan.hi);
}

TEST(AxisTicks, LogDecades) {
  const AxisTicks t = log_ticks(0.0021, 0.19);
  EXPECT_DOUBLE_EQ(t.lo, 1e-3);
  EXPECT_DOUBLE_EQ(t.hi, 1.0);
  EXPECT_EQ(t.labels.front(), "1e-3");
}

TEST(Plot, WritesPngAndSvgWithMissingSamples) {
  const fs::path dir = fs::temp_directory_path() / "btsm_plot_test";
  fs::create_directories(dir);
  Series s{"T1", {0, 1, 2, 3, 4}, {25, 26, NAN, 27, 27.5}, Series::Style::Line};
  Series r{"residual", {0, 1, 2, 3, 4}, {0.1, -0.1, 0.05, 0, 0.02}, Series::Style::Points};
  save_panels({Plot{"temps", "time (s)", "°C", {s}, false}, Plot{"res", "time (s)", "K", {r}, false}},
              (dir / "p").string());
  ASSERT_TRUE(fs::exists(dir / "p.png"));
  ASSERT_TRUE(fs::exists(dir / "p.svg"));
  std::ifstream png(dir / "p.png", std::ios::binary);
  char magic[8];
  png.read(magic, 8);
  EXPECT_EQ(std::string(magic + 1, 3), "PNG");
  EXPECT_GT(fs::file_size(dir / "p.svg"), 1000u);
  fs::remove_all(dir);
}

TEST(Plot, UnwritablePathIsAnErrorNamingIt) {
  try {
    save_plot(Plot{"x", "", "", {Series{"a", {0, 1}, {0, 1}}}, false}, "/nonexistent_dir/zzz/plot");
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent_dir/zzz/plot"), std::string::npos);
  }
}
