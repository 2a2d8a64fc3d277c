// Reduced-model blob (format version 2): layout, codec round trip, fault injection at every byte,
// a real version-1 blob refused by name, validation of every rule, quantisation errors.
#include "common/diagnosis.hpp"
#include "common/model_blob.hpp"
#include "host/thermal/model_reference.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <vector>

#include "spindle_model_fixture.hpp"

namespace btsm {
namespace {

using test::spindle_model;
using thermal::ReducedModelF64;

ReducedModel quantized_spindle() {
  ReducedModel m;
  const ModelCheck c = thermal::quantize(spindle_model(), m);
  EXPECT_TRUE(c.ok()) << model_status_name(c.status) << " bp " << int(c.breakpoint) << " ch " << int(c.channel);
  return m;
}

std::vector<uint8_t> blob_of(const ReducedModel& m) {
  std::vector<uint8_t> b(kReducedModelBlobSize);
  encode(m, b.data());
  return b;
}

// Re-seal a blob after editing it so the content checks (not the CRC) are what is tested.
void reseal(std::vector<uint8_t>& b) { put_le32(b.data() + kBlobOffCrc, crc32(b.data(), kBlobOffCrc)); }

TEST(ReducedModelBlob, SizeFitsTwoSlotsInEeprom) {
  EXPECT_EQ(kReducedModelBlobSize, 464u);
  EXPECT_LE(2 * kReducedModelBlobSize, 1024u - 96u);  // leaves >= 96 B for slot headers + config
}

TEST(ReducedModelBlob, LayoutIsLittleEndianWithMagicVersionTwoAndCrcLast) {
  const ReducedModel m = quantized_spindle();
  const std::vector<uint8_t> b = blob_of(m);
  EXPECT_EQ(b[0], 'B');
  EXPECT_EQ(b[1], 'T');
  EXPECT_EQ(b[2], 'R');
  EXPECT_EQ(b[3], 'M');
  EXPECT_EQ(b[kBlobOffVersion], 2);
  EXPECT_EQ(b[kBlobOffBreakpointCount], 5);
  EXPECT_EQ(b[kBlobOffAmbientChannel], 3);
  EXPECT_EQ(b[kBlobOffEnabledMask], 0x1F);
  EXPECT_EQ(get_le16(&b[kBlobOffDtMs]), 5000);
  EXPECT_EQ(get_le16(&b[kBlobOffStopEnds]), 600);
  EXPECT_EQ(get_le16(&b[kBlobOffStopEnds + 2]), 2400);
  EXPECT_EQ(get_le16(&b[kBlobOffSpeeds + 2 * 4]), 8000);
  // a of channel 2 (front bearing) at breakpoint 3 (6000 rpm): exp(-5 / 2900) in Q1.30.
  const size_t bp3 = kBlobOffBreakpoints + 3 * kBlobBreakpointSize;
  EXPECT_EQ(static_cast<int32_t>(get_le32(&b[bp3 + 2 * kBlobChannelCoeffSize])),
            static_cast<int32_t>(std::lround(std::exp(-5.0 / 2900.0) * (1 << 30))));
  // Its b: 10.7 K steady rise * (1 - a), in Q21.10 mK.
  EXPECT_EQ(static_cast<int32_t>(get_le32(&b[bp3 + 2 * kBlobChannelCoeffSize + 4])),
            static_cast<int32_t>(std::lround(10.7 * (1 - std::exp(-5.0 / 2900.0)) * 1000 * 1024)));
  // Stop phase 1 pole of channel 0.
  EXPECT_EQ(static_cast<int32_t>(get_le32(&b[kBlobOffStopPoles + 4 * (kModelChannels * 1 + 0)])),
            static_cast<int32_t>(std::lround(std::exp(-5.0 / 6000.0) * (1 << 30))));
  const uint8_t roles[5] = {3, 4, 2, 1, 8};
  for (int j = 0; j < 5; ++j) EXPECT_EQ(b[kBlobOffRoles + j], roles[j]) << j;
  EXPECT_EQ(get_le16(&b[kBlobOffDrift]), 400);
  EXPECT_EQ(get_le16(&b[kBlobOffLowDrift + 2]), 600);
  EXPECT_EQ(get_le16(&b[kBlobOffWarnEvidence + 2]), 141);   // 1.5 K min at 5 s = 18,000 mK samples / 128
  EXPECT_EQ(get_le16(&b[kBlobOffAlarmEvidence + 4]), 281);   // 36,000 / 128 = 281.25
  EXPECT_EQ(get_le16(&b[kBlobOffLowWarnEvidence]), 188);     // 24,000 / 128 = 187.5
  EXPECT_EQ(get_le16(&b[kBlobOffDrift + 6]), 0) << "the ambient channel has no detector";
  EXPECT_EQ(static_cast<int32_t>(get_le32(&b[kBlobOffAbsLimits + 4 * 4])), 70000);
  EXPECT_EQ(get_le16(&b[kBlobOffMaxRise]), 3000);
  for (size_t i = kBlobOffReserved; i < kBlobOffCrc; ++i) EXPECT_EQ(b[i], 0) << i;
  EXPECT_EQ(get_le32(&b[kBlobOffCrc]), crc32(b.data(), kBlobOffCrc));
  EXPECT_EQ(blob_stored_crc(b.data()), get_le32(&b[460]));
  EXPECT_EQ(blob_version(b.data(), b.size()), 2);
}

TEST(ReducedModelBlob, EvidenceUnitsConvertBothWays) {
  EXPECT_DOUBLE_EQ(thermal::evidence_units(1.0, 5000), 93.75);  // 1 K min = 12 samples x 1000 mK / 128
  EXPECT_DOUBLE_EQ(thermal::evidence_units(1.0, 2000), 234.375);
  EXPECT_DOUBLE_EQ(thermal::evidence_K_min(96, 5000), 1.024);
  // On the module: units x 128, and the evidence cap 2 x the ALARM threshold, within 24 bits.
  EXPECT_EQ(evidence_mk_samples(94), 12032);
  EXPECT_EQ(evidence_mk_samples(65535), 8388480);
  EXPECT_EQ(evidence_cap_mk_samples(65535), 16776960);
  EXPECT_LE(evidence_cap_mk_samples(65535), ResidualEvidence::kMax);
}

TEST(ReducedModelBlob, RoundTripIsExact) {
  const ReducedModel m = quantized_spindle();
  const std::vector<uint8_t> b = blob_of(m);
  ReducedModel back;
  const ModelCheck c = decode(b.data(), b.size(), back);
  ASSERT_TRUE(c.ok()) << model_status_name(c.status);
  EXPECT_EQ(blob_of(back), b);
  EXPECT_EQ(back.bp[2].ch[1].b, m.bp[2].ch[1].b);
  EXPECT_EQ(back.stop_a_q30[0][4], m.stop_a_q30[0][4]);
  EXPECT_EQ(back.schedule.role[4], 8);
  EXPECT_EQ(back.limits[2].abs_limit_mK, 70000);
  EXPECT_EQ(back.limits[1].low_warn_evidence, 188);
}

// A front bearing (ch3) riding on the housing (ch2): carrier and coupling at their offsets and back;
// the first version-2 layout (those bytes zero) is the same model without carriers.
TEST(ReducedModelBlob, CarriersRoundTripAndZeroMeansNone) {
  ReducedModel m = quantized_spindle();
  const std::vector<uint8_t> plain = blob_of(m);
  for (size_t i = kBlobOffCarriers; i < kBlobOffCrc; ++i) EXPECT_EQ(plain[i], 0) << i;
  m.schedule.coupling.carrier[2] = 2;
  m.schedule.coupling.c_q30[2] = 123456;
  ASSERT_TRUE(validate(m).ok());
  const std::vector<uint8_t> b = blob_of(m);
  EXPECT_EQ(b[kBlobOffCarriers + 2], 2);
  EXPECT_EQ(static_cast<int32_t>(get_le32(&b[kBlobOffCouplings + 8])), 123456);
  ReducedModel back;
  ASSERT_TRUE(decode(b.data(), b.size(), back).ok());
  EXPECT_EQ(back.schedule.coupling.carrier[2], 2);
  EXPECT_EQ(back.schedule.coupling.c_q30[2], 123456);
  EXPECT_EQ(back.schedule.coupling.carrier[0], kModelNoCarrier);
  EXPECT_EQ(blob_of(back), b);
}

TEST(ReducedModelBlob, EveryByteCorruptionIsRejectedByCrc) {
  const std::vector<uint8_t> good = blob_of(quantized_spindle());
  for (size_t i = 0; i < good.size(); ++i) {
    for (uint8_t flip : {0x01, 0x80, 0xFF}) {
      std::vector<uint8_t> b = good;
      b[i] ^= flip;
      ReducedModel out;
      const ModelCheck c = decode(b.data(), b.size(), out);
      EXPECT_EQ(c.status, ModelStatus::kBadCrc) << "byte " << i << " flip " << int(flip);
      EXPECT_EQ(model_status_class(c.status), ModelStatusClass::kCrc);
    }
  }
}

TEST(ReducedModelBlob, WrongLengthsAreRejected) {
  const std::vector<uint8_t> good = blob_of(quantized_spindle());
  ReducedModel out;
  for (size_t len = 0; len < good.size(); ++len)
    EXPECT_EQ(decode(good.data(), len, out).status, ModelStatus::kBadLength) << len;
  std::vector<uint8_t> longer = good;
  longer.push_back(0);
  EXPECT_EQ(decode(longer.data(), longer.size(), out).status, ModelStatus::kBadLength);
  EXPECT_EQ(decode(nullptr, kReducedModelBlobSize, out).status, ModelStatus::kBadLength);
}

// A blob written by the version-1 encoder (one shared state; tests/data/model-blob-v1): same
// magic, size and CRC place, so only the version tells it apart -- it is refused by its version,
// never decoded with the version-2 layout.
TEST(ReducedModelBlob, VersionOneBlobIsRefusedByItsVersion) {
  std::ifstream f(std::string(BTSM_TEST_DATA_DIR) + "/model-blob-v1/spindle_v1.bin", std::ios::binary);
  const std::vector<uint8_t> v1((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  ASSERT_EQ(v1.size(), kReducedModelBlobSize);
  EXPECT_EQ(crc32(v1.data(), kBlobOffCrc), blob_stored_crc(v1.data())) << "a genuine, intact v1 blob";
  EXPECT_EQ(blob_version(v1.data(), v1.size()), 1);
  ReducedModel out;
  memset(&out, 0xA5, sizeof(out));
  const ModelCheck c = decode(v1.data(), v1.size(), out);
  EXPECT_EQ(c.status, ModelStatus::kBadVersion);
  EXPECT_EQ(c.channel, 1) << "the check carries the version found";
  EXPECT_EQ(c.detail(), static_cast<uint16_t>(static_cast<uint16_t>(ModelStatus::kBadVersion) | (1u << 8)));
  EXPECT_EQ(model_status_class(c.status), ModelStatusClass::kVersion);
  EXPECT_EQ(out.schedule.n_breakpoints, 0xA5) << "nothing decoded";
}

struct Edit {
  const char* what;
  void (*apply)(std::vector<uint8_t>&);
  ModelStatus expected;
  uint8_t breakpoint;
  uint8_t channel;
};

void set32(std::vector<uint8_t>& b, size_t off, int32_t v) { put_le32(&b[off], static_cast<uint32_t>(v)); }
size_t a_off(int i, int ch) { return kBlobOffBreakpoints + kBlobBreakpointSize * i + kBlobChannelCoeffSize * ch; }
size_t b_off(int i, int ch) { return a_off(i, ch) + 4; }

TEST(ReducedModelBlob, EveryContentRuleIsEnforcedWithLocation) {
  const Edit edits[] = {
      {"magic", [](std::vector<uint8_t>& b) { b[0] = 'X'; }, ModelStatus::kBadMagic, 0xFF, 0xFF},
      {"version 0", [](std::vector<uint8_t>& b) { b[kBlobOffVersion] = 0; }, ModelStatus::kBadVersion, 0xFF, 0},
      {"version 3", [](std::vector<uint8_t>& b) { b[kBlobOffVersion] = 3; }, ModelStatus::kBadVersion, 0xFF, 3},
      {"reserved byte", [](std::vector<uint8_t>& b) { b[kBlobOffCrc - 1] = 1; }, ModelStatus::kUnusedNotZero, 0xFF, 0xFF},
      {"n=1", [](std::vector<uint8_t>& b) { b[kBlobOffBreakpointCount] = 1; }, ModelStatus::kBadBreakpointCount, 0xFF, 0xFF},
      {"n=8", [](std::vector<uint8_t>& b) { b[kBlobOffBreakpointCount] = 8; }, ModelStatus::kBadBreakpointCount, 0xFF, 0xFF},
      {"dt=99", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffDtMs], 99); }, ModelStatus::kBadDt, 0xFF, 0xFF},
      {"dt=60001", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffDtMs], 60001); }, ModelStatus::kBadDt, 0xFF, 0xFF},
      {"mask bit 5", [](std::vector<uint8_t>& b) { b[kBlobOffEnabledMask] = 0x3F; }, ModelStatus::kBadChannelMask, 0xFF, 0xFF},
      {"mask empty", [](std::vector<uint8_t>& b) { b[kBlobOffEnabledMask] = 0; }, ModelStatus::kBadChannelMask, 0xFF, 0xFF},
      {"ambient 5", [](std::vector<uint8_t>& b) { b[kBlobOffAmbientChannel] = 5; }, ModelStatus::kBadAmbientChannel, 0xFF, 0xFF},
      {"ambient disabled", [](std::vector<uint8_t>& b) { b[kBlobOffEnabledMask] = 0x17; }, ModelStatus::kBadAmbientChannel, 0xFF, 0xFF},
      {"speed0 != 0", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffSpeeds], 10); }, ModelStatus::kBadSpeeds, 0, 0xFF},
      {"speeds not ascending", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffSpeeds + 6], 4000); }, ModelStatus::kBadSpeeds, 3, 0xFF},
      {"unused speed", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffSpeeds + 12], 9000); }, ModelStatus::kBadSpeeds, 6, 0xFF},
      {"stop end 1 without 0", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffStopEnds], 0); }, ModelStatus::kBadStopPhases, 0xFF, 0xFF},
      {"stop ends not ascending", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffStopEnds + 2], 600); }, ModelStatus::kBadStopPhases, 0xFF, 0xFF},
      {"role: bearing on the ambient channel", [](std::vector<uint8_t>& b) { b[kBlobOffRoles + 3] = 3; }, ModelStatus::kBadChannelMap, 0xFF, 3},
      {"role: spare for a modelled channel", [](std::vector<uint8_t>& b) { b[kBlobOffRoles + 1] = 7; }, ModelStatus::kBadChannelMap, 0xFF, 1},
      {"role: ambient twice", [](std::vector<uint8_t>& b) { b[kBlobOffRoles + 0] = 1; }, ModelStatus::kBadChannelMap, 0xFF, 0},
      {"role: unknown code", [](std::vector<uint8_t>& b) { b[kBlobOffRoles + 2] = 9; }, ModelStatus::kBadChannelMap, 0xFF, 2},
      // Carriers (channel 3 is the ambient here): another modelled channel, not carried itself.
      {"coupling without a carrier", [](std::vector<uint8_t>& b) { set32(b, kBlobOffCouplings + 4, 7); }, ModelStatus::kBadCarrier, 0xFF, 1},
      {"carried by itself", [](std::vector<uint8_t>& b) { b[kBlobOffCarriers + 2] = 3; }, ModelStatus::kBadCarrier, 0xFF, 2},
      {"carried by the ambient", [](std::vector<uint8_t>& b) { b[kBlobOffCarriers + 0] = 4; }, ModelStatus::kBadCarrier, 0xFF, 0},
      {"carrier beyond the channels", [](std::vector<uint8_t>& b) { b[kBlobOffCarriers + 0] = 6; }, ModelStatus::kBadCarrier, 0xFF, 0},
      {"a chain of carriers", [](std::vector<uint8_t>& b) { b[kBlobOffCarriers + 0] = 2; b[kBlobOffCarriers + 1] = 3; }, ModelStatus::kBadCarrier, 0xFF, 0},
      {"the ambient carried", [](std::vector<uint8_t>& b) { b[kBlobOffCarriers + 3] = 1; }, ModelStatus::kBadCarrier, 0xFF, 3},
      {"coupling 1", [](std::vector<uint8_t>& b) { b[kBlobOffCarriers + 0] = 2; set32(b, kBlobOffCouplings, 1 << 30); }, ModelStatus::kBadCarrier, 0xFF, 0},
      {"coupling < 0", [](std::vector<uint8_t>& b) { b[kBlobOffCarriers + 0] = 2; set32(b, kBlobOffCouplings, -1); }, ModelStatus::kBadCarrier, 0xFF, 0},
      {"a = 1", [](std::vector<uint8_t>& b) { set32(b, a_off(2, 0), 1 << 30); }, ModelStatus::kUnstablePole, 2, 0},
      {"a < 0", [](std::vector<uint8_t>& b) { set32(b, a_off(1, 4), -5); }, ModelStatus::kUnstablePole, 1, 4},
      {"b at 0 rpm", [](std::vector<uint8_t>& b) { set32(b, b_off(0, 1), 5); }, ModelStatus::kInputAtStandstill, 0, 1},
      // b = 1 K/step with a = exp(-5/2400): steady rise 480 K is fine, 2 K/step -> 961 K too; 3 K/step -> 1441 K is not.
      {"steady rise > 1000 K", [](std::vector<uint8_t>& b) { set32(b, b_off(3, 0), 3 * 1000 * 1024); }, ModelStatus::kSteadyStateOutOfRange, 3, 0},
      {"unused slot", [](std::vector<uint8_t>& b) { set32(b, a_off(6, 2), 1); }, ModelStatus::kUnusedNotZero, 6, 2},
      {"ambient channel coefficient", [](std::vector<uint8_t>& b) { set32(b, b_off(2, 3), 7); }, ModelStatus::kUnusedNotZero, 2, 3},
      {"stop pole a = 1", [](std::vector<uint8_t>& b) { set32(b, kBlobOffStopPoles + 4 * 6, 1 << 30); }, ModelStatus::kUnstablePole, 0, 1},
      {"stop pole on the ambient channel", [](std::vector<uint8_t>& b) { set32(b, kBlobOffStopPoles + 4 * 3, 5); }, ModelStatus::kUnusedNotZero, 0xFF, 3},
      {"drift 0", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffDrift + 2], 0); }, ModelStatus::kBadDetector, 0xFF, 1},
      {"lower warn without its drift", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffLowDrift + 4], 0); }, ModelStatus::kBadDetector, 0xFF, 2},
      {"warn 0", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffWarnEvidence + 2], 0); }, ModelStatus::kBadDetector, 0xFF, 1},
      {"alarm <= warn", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffAlarmEvidence + 8], 141); }, ModelStatus::kBadDetector, 0xFF, 4},
      {"detector on the ambient channel", [](std::vector<uint8_t>& b) { put_le16(&b[kBlobOffDrift + 6], 1); }, ModelStatus::kUnusedNotZero, 0xFF, 3},
      {"limit 851 C", [](std::vector<uint8_t>& b) { set32(b, kBlobOffAbsLimits + 8, 851000); }, ModelStatus::kLimitOutOfRange, 0xFF, 2},
      {"limit -201 C", [](std::vector<uint8_t>& b) { set32(b, kBlobOffAbsLimits, -201000); }, ModelStatus::kLimitOutOfRange, 0xFF, 0},
  };
  const std::vector<uint8_t> good = blob_of(quantized_spindle());
  for (const Edit& e : edits) {
    std::vector<uint8_t> b = good;
    e.apply(b);
    reseal(b);
    ReducedModel out;
    const ModelCheck c = decode(b.data(), b.size(), out);
    EXPECT_EQ(c.status, e.expected) << e.what << ": got " << model_status_name(c.status);
    EXPECT_EQ(c.breakpoint, e.breakpoint) << e.what;
    EXPECT_EQ(c.channel, e.channel) << e.what;
    EXPECT_EQ(model_status_class(c.status),
              e.expected == ModelStatus::kBadVersion ? ModelStatusClass::kVersion : ModelStatusClass::kInvalid)
        << e.what;
  }
}

TEST(ReducedModelBlob, UnmodelledChannelsCarryNothing) {
  ReducedModelF64 f = spindle_model();
  f.enabled_mask = 0x0F;  // channel 5 not modelled: its coefficients and limits are not written
  f.role[4] = kModelRoleNotModelled;
  ReducedModel m;
  ASSERT_TRUE(thermal::quantize(f, m).ok());
  for (int i = 0; i < 5; ++i) EXPECT_EQ(m.bp[i].ch[4].a_q30, 0);
  EXPECT_EQ(m.limits[4].abs_limit_mK, 0);
  f.role[4] = 8;  // ... and must not claim a role
  EXPECT_EQ(thermal::quantize(f, m).status, ModelStatus::kBadChannelMap);
  f = spindle_model();
  f.ambient_channel = kModelAmbientNone;  // channel 4 is now a probe without a model
  EXPECT_EQ(thermal::quantize(f, m).status, ModelStatus::kBadChannelMap);
}

TEST(ReducedModelBlob, DetailPacksStatusAndLocation) {
  const ModelCheck c = model_check(ModelStatus::kUnstablePole, 2);
  EXPECT_EQ(c.detail(), 0x0209);
  EXPECT_EQ(model_check(ModelStatus::kBadDetector, 0xFF, 4).detail(), 0x040F);
}

TEST(ReducedModelQuantize, RejectsValuesThatDoNotFitWithLocation) {
  struct Case {
    const char* what;
    void (*apply)(ReducedModelF64&);
    ModelStatus expected;
    uint8_t bp, ch;
  };
  const Case cases[] = {
      {"NaN a", [](ReducedModelF64& f) { f.a[2][1] = NAN; }, ModelStatus::kNotFinite, 2, 1},
      {"inf b", [](ReducedModelF64& f) { f.b_K[1][4] = INFINITY; }, ModelStatus::kNotFinite, 1, 4},
      {"a = 1", [](ReducedModelF64& f) { f.a[3][0] = 1.0; }, ModelStatus::kUnstablePole, 3, 0},
      {"a = 1 - 1e-12 rounds to 1", [](ReducedModelF64& f) { f.a[3][2] = 1.0 - 1e-12; }, ModelStatus::kUnstablePole, 3, 2},
      {"a < 0", [](ReducedModelF64& f) { f.a[1][0] = -0.5; }, ModelStatus::kUnstablePole, 1, 0},
      {"b = 2100 K per step", [](ReducedModelF64& f) { f.b_K[1][0] = 2100.0; }, ModelStatus::kGainOutOfRange, 1, 0},
      {"stop pole NaN", [](ReducedModelF64& f) { f.stop_a[1][2] = NAN; }, ModelStatus::kNotFinite, 0, 2},
      {"n = 8", [](ReducedModelF64& f) { f.n_breakpoints = 8; }, ModelStatus::kBadBreakpointCount, 0xFF, 0xFF},
      {"drift 70 K", [](ReducedModelF64& f) { f.detector[0].drift_K = 70.0; }, ModelStatus::kLimitOutOfRange, 0xFF, 0},
      {"lower drift negative", [](ReducedModelF64& f) { f.detector[4].low_drift_K = -0.1; }, ModelStatus::kLimitOutOfRange, 0xFF, 4},
      {"rise NaN", [](ReducedModelF64& f) { f.detector[2].max_rise_K_per_min = NAN; }, ModelStatus::kLimitOutOfRange, 0xFF, 2},
      {"evidence beyond u16", [](ReducedModelF64& f) { f.detector[1].alarm_evidence_K_min = 800.0; }, ModelStatus::kLimitOutOfRange, 0xFF, 1},
      {"limit 900 C", [](ReducedModelF64& f) { f.detector[1].abs_limit_c = 900.0; }, ModelStatus::kLimitOutOfRange, 0xFF, 1},
  };
  for (const Case& k : cases) {
    ReducedModelF64 f = spindle_model();
    k.apply(f);
    ReducedModel m;
    const ModelCheck c = thermal::quantize(f, m);
    EXPECT_EQ(c.status, k.expected) << k.what << ": got " << model_status_name(c.status);
    EXPECT_EQ(c.breakpoint, k.bp) << k.what;
    EXPECT_EQ(c.channel, k.ch) << k.what;
  }
}

}  // namespace
}  // namespace btsm
