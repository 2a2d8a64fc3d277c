// Stage 3 of the fit (operating-only parameters) on recordings where the equation-error start is
// misleading (tests/data/demo-warmups/README.md): the fit must run the neutral start as well and
// keep the physical minimum, not a heat source at its bound balanced by a vanishing resistance.
#include "host/thermal/fit.hpp"

#include <gtest/gtest.h>

#include <iostream>
#include <string>

namespace btsm::thermal {
namespace {

TEST(ThermalFitStarts, NeutralStartRescuesAMisleadingEquationErrorStart) {
  Network net = preset_network("spindle4");
  remap_measurements(net, {"shaft=T5"});
  std::vector<Recording> recs;
  for (const char* f : {"warmup_4000rpm.csv", "warmup_6000rpm.csv", "warmup_8000rpm.csv"})
    recs.push_back(read_recording_csv(std::string(BTSM_TEST_DATA_DIR) + "/demo-warmups/" + f));
  FitOptions o;
  o.sum_capacitance_J_per_K = 20478.7;
  const FitResult r = fit_network(net, recs, o);
  double ee_rms = -1, neutral_rms = -1;
  for (const auto& s : r.stages) {
    std::cout << s.name << ": rms " << s.rms_K << " K, " << s.iterations << " iterations\n";
    if (s.name == "stage 3 (operating output error, equation-error start)") ee_rms = s.rms_K;
    if (s.name == "stage 3 (operating output error, neutral start)") neutral_rms = s.rms_K;
  }
  ASSERT_GT(ee_rms, 0) << "the equation-error start's stage 3 did not run";
  ASSERT_GT(neutral_rms, 0) << "the neutral start's stage 3 did not run";
  // The trap this data set was kept for: without the neutral start the fit ends near 1 K.
  EXPECT_GT(ee_rms, 2 * neutral_rms);
  EXPECT_LT(r.rms_K, 0.25);
  for (const char* q : {"qf1", "qf2"}) EXPECT_LT(r.params[net.param_index(q)], 200.0) << q << " ran off to its bound";
  EXPECT_GT(r.params[net.param_index("Ra3")], 0.01) << "the vanishing-resistance basin";
}

}  // namespace
}  // namespace btsm::thermal
