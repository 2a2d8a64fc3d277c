// The detection benchmark, reduced to a quick native run: commissioning through the whole
// toolchain (the demo's quick identification procedure), a 12 h production profile with stops and
// speed steps, 30 W at either bearing and an open probe at two moments (cold start, restart after a
// stop), and the fault-free run.
//
// The bounds below are what the per-channel first-order models (the bearings riding on a carrier)
// and the evidence (CUSUM) detector calibrated by `reduce --calibrate-bands`'s rule achieve after
// the quick commissioning (measured: 30 W rear -> ALARM 4.2-4.5 min on T1, front 7.3-8.4 min on
// T3, no false WARN or ALARM in 12 h; before the carriers 4.7-5.4 and 11.0-13.7), with margin. The targets (30 W -> ALARM <= 10 min, 10 W -> <= 30 min, no false
// WARN or ALARM in 48 h) are printed by `bench_detection` on the AVR image with the full
// identification.
#include "tests/bench/detection/detection_harness.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <unistd.h>

namespace {

using namespace btsm;
using namespace btsm::bench;

const DetectionResult& run() {
  static const DetectionResult r = [] {
    DetectionOptions o;
    o.board = sim::BoardKind::Native;
    o.quick_identification = true;
    o.out_dir = (std::filesystem::temp_directory_path() / ("btsm-detection-test-" + std::to_string(::getpid()))).string();
    o.profile.hours = 12;
    o.heats_w = {30};
    o.open_probe_channels = {1};
    o.kinds = {MomentKind::ColdStart, MomentKind::Restart};
    o.moments_per_kind = 1;
    o.window_h = 3;
    o.jobs = 2;  // the fault runs two at a time, as the benchmark runs them: each report must land in its own run
    const DetectionResult res = run_detection(o);
    std::filesystem::remove_all(o.out_dir);
    std::printf("%s%s%s\n", res.runs_table().c_str(), res.summary_table().c_str(), res.fault_free_line().c_str());
    return res;
  }();
  return r;
}

const FaultRun* find(const DetectionResult& r, const std::string& fault, const std::string& place, MomentKind k) {
  for (const auto& f : r.faults)
    if (f.fault == fault && f.place == place && f.moment.kind == k) return &f;
  return nullptr;
}

TEST(Detection, EveryFaultRunsAtEveryMoment) {
  const auto& r = run();
  ASSERT_EQ(r.faults.size(), 6u);  // (30 W rear, 30 W front, open ch1) x (cold start, restart)
  for (const auto& f : r.faults) EXPECT_TRUE(f.ok) << f.fault << " " << f.place << ": " << f.error;
}

TEST(Detection, ThirtyWattsAtTheRearBearingRaiseAlarmOnItsChannel) {
  const auto& r = run();
  for (MomentKind k : {MomentKind::ColdStart, MomentKind::Restart}) {
    const FaultRun* f = find(r, "bearing 30 W", "rear", k);
    ASSERT_NE(f, nullptr) << moment_kind_name(k);
    EXPECT_EQ(f->state_before, kNormal) << moment_kind_name(k);
    EXPECT_GE(f->alarm_s, 0) << moment_kind_name(k) << ": no ALARM in " << f->window_s / 60 << " min";
    EXPECT_LE(f->alarm_s, 6.5 * 60) << moment_kind_name(k);
    EXPECT_EQ(f->alarm_channel, 1) << moment_kind_name(k) << ": the rear bearing's probe";
    EXPECT_GE(f->warn_s, 0);
    EXPECT_LE(f->warn_s, f->alarm_s);
  }
}

TEST(Detection, ThirtyWattsAtTheFrontBearingRaiseAlarmOnItsChannel) {
  const auto& r = run();
  for (MomentKind k : {MomentKind::ColdStart, MomentKind::Restart}) {
    const FaultRun* f = find(r, "bearing 30 W", "front", k);
    ASSERT_NE(f, nullptr) << moment_kind_name(k);
    EXPECT_EQ(f->state_before, kNormal) << moment_kind_name(k);
    EXPECT_GE(f->alarm_s, 0) << moment_kind_name(k);
    EXPECT_LE(f->alarm_s, 10.5 * 60) << moment_kind_name(k);
    EXPECT_EQ(f->alarm_channel, 3) << moment_kind_name(k) << ": the front bearing's probe";
  }
}

TEST(Detection, AnOpenProbeIsASensorFaultOnItsChannelAndNoAlarm) {
  const auto& r = run();
  for (MomentKind k : {MomentKind::ColdStart, MomentKind::Restart}) {
    const FaultRun* f = find(r, "open probe", "ch1", k);
    ASSERT_NE(f, nullptr) << moment_kind_name(k);
    EXPECT_EQ(f->sensor_channel, 1);
    EXPECT_GE(f->sensor_s, 0);
    EXPECT_LE(f->sensor_s, 30.0);  // three sweeps: the rotating open-wire check
    EXPECT_LT(f->alarm_s, 0) << "a broken probe is no overheating";
  }
}

TEST(Detection, FaultFreeRunHasNoFalseWarnOrAlarm) {
  const auto& r = run();
  EXPECT_GT(r.fault_free.samples, 8000);  // 12 h at 5 s
  EXPECT_EQ(r.fault_free.alarm_episodes, 0) << r.fault_free_line();
  EXPECT_EQ(r.fault_free.warn_episodes, 0) << r.fault_free_line();
  EXPECT_EQ(r.fault_free.sensor_fault_samples, 0);
}

}  // namespace
