// Real recordings with declared columns (tests/data/*/README.md for source, licence and cut): what a
// network that uses the declared column explains on the held-out part, against the same network
// without it. Measured with fit_network + validate_recording only, so these figures are the answer
// the residual loop must reach by itself (its own verdicts are pinned in tests/unit/residual).
#include "host/thermal/declared_columns.hpp"
#include "host/thermal/fit.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"
#include "host/thermal/validate.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

namespace btsm::thermal {
namespace {

const std::string kData = BTSM_TEST_DATA_DIR;

// Number of 0 -> 1 switches of a declared event column (a row holds its value over [t_k, t_k+1)).
int switch_ons(const Recording& rec, const std::string& column) {
  const auto it = std::find(rec.channels.begin(), rec.channels.end(), column);
  if (it == rec.channels.end()) return -1;
  const Eigen::Index j = it - rec.channels.begin();
  int n = 0;
  for (Eigen::Index k = 0; k < rec.temp_c.rows(); ++k)
    if (rec.temp_c(k, j) == 1.0 && (k == 0 || rec.temp_c(k - 1, j) == 0.0)) ++n;
  return n;
}

// RMSE over every measured cell of the check recording (equal weight per cell).
double check_rmse(const Network& net, const FitResult& fit, const Recording& check) {
  const RecordingValidation v = validate_recording(net, fit.params, check);
  double ss = 0;
  std::size_t n = 0;
  for (const ErrorMetrics& m : v.all) {
    ss += m.rmse_K * m.rmse_K * static_cast<double>(m.count);
    n += m.count;
  }
  return n ? std::sqrt(ss / static_cast<double>(n)) : NAN;
}

double param(const Network& net, const FitResult& fit, const std::string& name) {
  const int i = net.param_index(name);
  EXPECT_GE(i, 0) << name;
  return i >= 0 ? fit.params[i] : NAN;
}

double sigma(const FitResult& fit, const std::string& name) {
  for (const ParameterEstimate& e : fit.estimates)
    if (e.name == name) return e.sigma;
  ADD_FAILURE() << name;
  return NAN;
}

// Incubator DT 2021 lid-opening run, re-cut so that the fit part (0-170 min) holds six of the seven
// logged openings; the lid state is a declared event column. The 2-node network of the source
// (heater - air - room) cannot know the lid was open; one switched conductance from the air and one
// from the heater to the room while lid_open = 1 (2 parameters) is the effect. Measured: check RMSE
// 3.59 K -> 0.76 K (x4.7); the goal is >= 4x.
TEST(IncubatorLidEvents, DeclaredEventColumnHoldsTheLoggedOpenings) {
  const Recording fit = read_recording_csv(kData + "/incubator-dt/lid2021_events_fit_0-170min.csv");
  const Recording check = read_recording_csv(kData + "/incubator-dt/lid2021_events_check_170-323min.csv");
  EXPECT_EQ(event_columns(fit), std::vector<std::string>{"lid_open"});
  EXPECT_EQ(event_columns(check), std::vector<std::string>{"lid_open"});
  EXPECT_EQ(switch_ons(fit, "lid_open"), 6);    // 34, 61, 86, 111, 137, 162 min
  EXPECT_EQ(switch_ons(check, "lid_open"), 1);  // 294 min
}

TEST(IncubatorLidEvents, SwitchedConductanceToTheRoomCutsTheHeldOutErrorAtLeastFourFold) {
  const std::string dir = kData + "/incubator-dt/";
  const std::vector<Recording> fit = {read_recording_csv(dir + "lid2021_events_fit_0-170min.csv")};
  const Recording check = read_recording_csv(dir + "lid2021_events_check_170-323min.csv");
  const Network base = load_network(dir + "incubator2_2021_network.json");
  const Network lid = load_network(dir + "incubator2_2021_lid_network.json");
  ASSERT_EQ(lid.events, std::vector<std::string>{"lid_open"});

  const FitResult fb = fit_network(base, fit);
  const FitResult fl = fit_network(lid, fit);
  const double before = check_rmse(base, fb, check);
  const double after = check_rmse(lid, fl, check);
  RecordProperty("check_rmse_before_K", std::to_string(before));
  RecordProperty("check_rmse_after_K", std::to_string(after));
  std::printf("incubator lid: fit RMSE %.3f -> %.3f K, check RMSE %.3f -> %.3f K (x%.2f)\n", fb.rms_K, fl.rms_K,
              before, after, before / after);
  EXPECT_GT(before, 3.0);           // 3.59 K: the base overheats after every opening it cannot see
  EXPECT_LT(fl.rms_K, 0.6 * fb.rms_K);
  EXPECT_GE(before / after, 4.0);   // 4.7x measured
  // The air's extra loss while the lid is open is what the data determine (15 +- 3.5 W/K, 6 to 20
  // times the closed box's 1/R_box); the heater's share is not identifiable from the air sensor alone.
  const double g_air = param(lid, fl, "g_lid_air");
  EXPECT_GT(g_air, 3.0 * sigma(fl, "g_lid_air"));
  EXPECT_GT(g_air, 5.0 / param(lid, fl, "R_box"));
}

// SJTU motorized spindle: the cooling-water temperature (T8, the supply line, declared as the boundary
// column coolant_c) as a second boundary of the front and rear bearings (2 parameters). The plateau
// error of the base network (1.09 K) comes from the rear bearing's slow mode and a room sensor the
// machine does not follow; the water boundary takes little of it (1.04 K), far from an explanation.
TEST(SjtuCoolant, DeclaredCoolingWaterBoundaryExplainsLittleOfThePlateauError) {
  const std::string dir = kData + "/spindle-sjtu-elongation/";
  const std::vector<Recording> fit = {read_recording_csv(dir + "sjtu_fit_0-24h.csv")};
  const Recording check = read_recording_csv(dir + "sjtu_check_24-78h.csv");
  EXPECT_EQ(boundary_columns(fit[0]), std::vector<std::string>{"coolant_c"});
  const Network base = load_network(dir + "sjtu4_network.json");
  const Network cooled = load_network(dir + "sjtu4_coolant_network.json");
  ASSERT_EQ(cooled.boundaries, std::vector<std::string>{"coolant_c"});

  const FitResult fb = fit_network(base, fit);
  const FitResult fc = fit_network(cooled, fit);
  const double before = check_rmse(base, fb, check);
  const double after = check_rmse(cooled, fc, check);
  std::printf("sjtu coolant: fit RMSE %.3f -> %.3f K, check RMSE %.3f -> %.3f K (x%.2f)\n", fb.rms_K, fc.rms_K,
              before, after, before / after);
  EXPECT_GT(before, 0.9);
  EXPECT_LE(fc.rms_K, fb.rms_K + 1e-6);   // nested: the boundary can only help on the fit part
  EXPECT_GT(before / after, 1.0);         // it explains some of the plateau (1.09 -> 1.04 K) ...
  EXPECT_LT(before / after, 1.25);        // ... but not enough to count as an explanation
}

}  // namespace
}  // namespace btsm::thermal
