// Reduction against the numbers of the reference toolchain (sysid-notes) and the firmware blob.
#include "host/thermal/reduce.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

namespace btsm::thermal {
namespace {

TEST(ThermalReduce, HankelSingularValuesAndPolesAt6000rpmWithTrueParameters) {
  const Network net = preset_network("spindle4");
  const SpeedReduction r = reduce_at_speed(net, test::true_parameters(net), 6000.0);
  const double hsv[4] = {0.18980, 0.059386, 0.010976, 0.0021142};
  ASSERT_EQ(r.hsv.size(), 4);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(r.hsv[i] / hsv[i], 1.0, 1e-3) << i;
  EXPECT_NEAR(r.dc.pole / -3.775e-4, 1.0, 1e-3);
  EXPECT_NEAR(r.bt.pole / -3.894e-4, 1.0, 1e-3);
  // DC matching keeps the steady state exactly; plain truncation misses it (notes: 49 %).
  const Eigen::VectorXd dc_ss = r.dc.c * (-(r.dc.b * r.source_w)(0) / r.dc.pole) + r.dc.d * r.source_w;
  EXPECT_LT((dc_ss - r.steady_rise_K).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_GT((r.bt_steady_rise_K - r.steady_rise_K).cwiseAbs().maxCoeff() / r.steady_rise_K.maxCoeff(), 0.3);
  // only the sum of the SCTC rates is exact
  EXPECT_NEAR(r.sctc_rate_sum, -r.poles.sum(), 1e-12);
}

TEST(ThermalReduce, QuantizedFirmwareModelTracksItsDoubleReduction) {
  const Network net = preset_network("spindle4");
  ReduceOptions o;
  o.speeds_rpm = {4000, 6000, 8000};
  const ScheduledReduction s = build_scheduled_model(net, test::true_parameters(net), o);
  ASSERT_TRUE(s.quantize_status.ok()) << model_status_name(s.quantize_status.status);
  ASSERT_EQ(s.blob.size(), kReducedModelBlobSize);
  EXPECT_LE(s.deviation.quantized_vs_double_max_K, 0.01);
  // the 1st-order model itself is honest about its error against the full network
  EXPECT_GT(s.deviation.double_vs_full_max_K, 0.0);
  EXPECT_LT(s.deviation.double_vs_full_max_K, 3.0);
  ReducedModel back;
  EXPECT_TRUE(decode(s.blob.data(), s.blob.size(), back).ok());
  EXPECT_EQ(back.n_breakpoints, 4);
  EXPECT_EQ(back.speed_rpm[2], 6000);
}

TEST(ThermalReduce, RejectsBadSpeeds) {
  const Network net = preset_network("spindle4");
  ReduceOptions o;
  o.speeds_rpm = {6000, 4000};
  EXPECT_THROW(build_scheduled_model(net, default_parameters(net), o), std::invalid_argument);
  o.speeds_rpm = {};
  EXPECT_THROW(build_scheduled_model(net, default_parameters(net), o), std::invalid_argument);
}

}  // namespace
}  // namespace btsm::thermal
