#include "boards/sim/runner/sim_module.hpp"
#include "wire_capture.hpp"
#include <gtest/gtest.h>
#include <cstdio>
using namespace btsm;
TEST(Smoke, NativeSamples) {
  sim::SimModuleOptions o;
  o.plant.speed = sim::SpeedProfile::parse("1h@6000");
  o.plant.start_steady = true; o.plant.start_steady_rpm = 6000;
  sim::SimModule m(o);
  m.run_for(60);
  test::Capture c; c.feed(m.host_receive());
  printf("samples %zu other %lu undec %lu\n", c.samples.size(), c.other_frames, c.undecodable);
  auto t = m.truth();
  for (auto& s : c.samples) printf("%u %u rpm %u T1 %d T2 %d T3 %d T4 %d T5 %d st %02x %02x ov %02x\n", s.sample_index, s.time_ms, s.speed_rpm, s.temp_mK[0], s.temp_mK[1], s.temp_mK[2], s.temp_mK[3], s.temp_mK[4], s.channel_status[0], s.channel_status[4], s.overall);
  printf("truth %f %f %f %f %f\n", t.probe_c[0], t.probe_c[1], t.probe_c[2], t.probe_c[3], t.probe_c[4]);
}
