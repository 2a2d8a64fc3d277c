// The real AVR image in simavr: power cuts at >= 200 random EEPROM-write positions while a new
// model is uploaded; every boot afterwards reports a valid model, the old or the new one. A host
// without the device key cannot change a single EEPROM byte. And a power cycle in the middle of
// measuring: the module comes back and measures again.
#include "avr_link.hpp"
#include "host/sim/plant/probes.hpp"
#include "tests/hil/sim/model_upload.hpp"

#include <gtest/gtest.h>

#include <random>

namespace btsm::test {
namespace {

class AvrPowerLoss : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(firmware_elf())) GTEST_SKIP() << "firmware image missing: " << firmware_elf();
  }
};

TEST_F(AvrPowerLoss, EveryBootHasTheOldOrTheNewModel) {
  const auto blob_a = spindle_model_blob(0), blob_b = spindle_model_blob(1);
  const uint32_t crc_a = blob_stored_crc(blob_a.data()), crc_b = blob_stored_crc(blob_b.data());
  uint8_t seq = 0;
  std::vector<uint8_t> image_a;
  {
    AvrLink l;
    l.step(0.5);
    ASSERT_EQ(upload_model(l, blob_a, seq), 0);
    l.step(0.1);
    ASSERT_EQ(get_info(l, seq).model_crc, crc_a);
    image_a = l.h->eeprom();
  }
  uint64_t upload_writes = 0;
  {
    AvrLink l;
    l.h->set_eeprom(image_a);
    l.step(0.5);
    const uint64_t w0 = l.h->stats().eeprom_writes;
    ASSERT_EQ(upload_model(l, blob_b, seq), 0);
    upload_writes = l.h->stats().eeprom_writes - w0;
    ASSERT_EQ(get_info(l, seq).model_crc, crc_b);
  }
  ASSERT_GE(upload_writes, 464u);

  std::mt19937_64 rng(77);
  std::vector<uint64_t> cuts;
  std::uniform_int_distribution<uint64_t> pick(0, upload_writes + 19);
  for (int i = 0; i < 200; ++i) cuts.push_back(pick(rng));
  for (uint64_t k = upload_writes - 12; k < upload_writes; ++k) cuts.push_back(k);
  int old_model = 0, new_model = 0;
  for (size_t trial = 0; trial < cuts.size(); ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial) + ", cut at EEPROM write " + std::to_string(cuts[trial]));
    AvrLink l;
    l.h->set_eeprom(image_a);
    l.step(0.3);
    l.h->cut_power_at_eeprom_write(cuts[trial], uint8_t(rng()));
    int status = -1;
    try {
      status = upload_model(l, blob_b, seq);
    } catch (const std::runtime_error&) {
    }
    if (cuts[trial] < upload_writes) ASSERT_TRUE(l.h->power_lost());
    else ASSERT_EQ(status, 0);
    l.reboot();
    l.step(0.3);
    const wire::Info info = get_info(l, seq);
    ASSERT_TRUE(info.model_crc == crc_a || info.model_crc == crc_b) << "model crc " << info.model_crc;
    (info.model_crc == crc_a ? old_model : new_model)++;
  }
  std::printf("%zu trials (cuts during %llu-write uploads, some just after): %d old model, %d new\n", cuts.size(),
              static_cast<unsigned long long>(upload_writes), old_model, new_model);
  EXPECT_GT(old_model, 0);
  EXPECT_GT(new_model, 0);
}

// After a power cycle the image boots, calibrates and streams good temperatures again (the
// simulated DOUT/RDY line must read high again after the reset: a stale low made every
// calibration "finish" at once and the firmware re-initialise the chip for ever).
// The keyless host of HilUploadAuth against the real image: every step refused, the whole EEPROM
// byte for byte unchanged, no EEPROM write at all.
TEST_F(AvrPowerLoss, KeylessHostCannotChangeAnEepromByte) {
  AvrLink l;
  uint8_t seq = 0;
  l.step(1.0);  // boot (its counter write) and a sweep
  const std::vector<uint8_t> before = l.h->eeprom();
  const uint64_t writes_before = l.h->stats().eeprom_writes;
  const KeylessAttempt r = keyless_upload(l, spindle_model_blob(1), seq);
  l.step(0.5);
  EXPECT_EQ(r.chunks_before_auth, int(wire::Nack::NoSession));
  EXPECT_EQ(r.auth, int(wire::Nack::AuthFailed));
  EXPECT_EQ(r.chunks_after_auth, int(wire::Nack::NoSession));
  EXPECT_EQ(r.commit, int(wire::Nack::NoSession));
  EXPECT_EQ(l.h->stats().eeprom_writes, writes_before);
  EXPECT_TRUE(l.h->eeprom() == before) << "a keyless host changed EEPROM bytes";
  EXPECT_EQ(upload_model(l, spindle_model_blob(1), seq), 0);
  EXPECT_EQ(get_info(l, seq).model_crc, blob_stored_crc(spindle_model_blob(1).data()));
}

TEST_F(AvrPowerLoss, MeasuresAgainAfterAPowerCycle) {
  AvrLink l;
  const double temps[5] = {20.0, 35.5, 42.0, 22.0, 60.0};
  for (int j = 0; j < 5; ++j) l.adc.front_end().probe_ohm[size_t(j)] = sim::pt1000_ohm(temps[j]);
  l.h->set_tach_hz(100.0);
  l.step(8.0);
  ASSERT_GE(l.capture().samples.size(), 1u);
  const uint64_t calibrations = l.adc.counters().calibrations;
  l.step(2.3);  // mid-sweep or between sweeps: either way the power goes
  l.reboot();
  l.step(8.0);
  const auto& s = l.capture().samples;
  ASSERT_GE(s.size(), 2u) << "no samples after the power cycle";
  EXPECT_EQ(s.front().sample_index, 0u);  // a fresh boot
  for (const auto& smp : s) {
    for (int j = 0; j < 5; ++j) {
      const uint8_t hard = wire::kFaultOpen | wire::kFaultShort | wire::kFaultAdc | wire::kFaultReference;
      ASSERT_EQ(smp.channel_status[j] & hard, 0) << "sample " << smp.sample_index << " channel " << j;
      EXPECT_NEAR(smp.temp_mK[j] / 1000.0, temps[j], 0.01) << "sample " << smp.sample_index << " channel " << j;
    }
  }
  EXPECT_EQ(l.adc.counters().calibrations - calibrations, 10u);  // zero + full scale, five channels, once
  EXPECT_EQ(s.back().speed_rpm, 6000);  // the tach pulse train is back at its own rate

  // The REBOOT command: a watchdog reset inside the simulated MCU, not a power cycle.
  uint8_t seq = 1;
  l.send(frame(uint8_t(wire::MsgType::Reboot), seq++, nullptr, 0));
  l.step(0.5);
  const size_t before = l.capture().samples.size();
  l.step(8.0);
  ASSERT_GE(l.capture().samples.size(), before + 2) << "no samples after the REBOOT command";
  const auto& r = l.capture().samples.back();
  for (int j = 0; j < 5; ++j) EXPECT_NEAR(r.temp_mK[j] / 1000.0, temps[j], 0.01) << "after REBOOT, channel " << j;
  EXPECT_EQ(r.speed_rpm, 6000);
}

}  // namespace
}  // namespace btsm::test
