// Instantiates the numeric templates and kernels as the firmware does (fixed point, the float
// templates, int sizes of the AVR where int is 16 bits) and links a real ATmega328P image, so code
// that only a template instantiation reveals (conversions, 16-bit int promotions, missing libm/libgcc symbols) is caught
// and the flash/RAM cost of the numeric core is printed by avr-size.
#include "diagnosis.hpp"
#include "fixed_point.hpp"
#include "kalman.hpp"
#include "ratiometric.hpp"
#include "model_blob.hpp"
#include "model_step.hpp"
#include "rtd.hpp"

volatile uint32_t g_code = 0x2F0000UL;
volatile uint16_t g_speed = 6000;
volatile int32_t g_sink[5];
uint8_t g_blob[btsm::kReducedModelBlobSize];
btsm::ReducedModel model;
btsm::ReducedModelState state;
btsm::ScalarKalman<float> kalman[btsm::kModelChannels];
btsm::KalmanFixedSetup kalman_fixed_setup;
btsm::KalmanFixedChannel kalman_fixed[btsm::kModelChannels];
btsm::Diagnosis<btsm::kModelChannels> diag;
btsm::ResidualEvidence evidence[btsm::kModelChannels];
btsm::RiseRate<13> rise[btsm::kModelChannels];

int main() {
  const btsm::RtdCoefficients<float> k = btsm::iec60751<float>(1000.0f);
  const btsm::RatiometricConfig<float> cfg;
  const btsm::ChannelCalibration<float> cal;
  const btsm::ModelCheck check = btsm::decode(g_blob, sizeof g_blob, model);
  int32_t predicted[btsm::kModelChannels];
  btsm::step(model, state, g_speed, 20000, predicted);
  btsm::DiagInput in[btsm::kModelChannels];
  for (uint8_t j = 0; j < btsm::kModelChannels; ++j) {
    const btsm::RatioResult<float> r = btsm::code_to_resistance(g_code + j, false, cfg, cal);
    const btsm::RtdResult<float> t = btsm::rtd_temperature(k, r.r_ohm);
    kalman[j].update(t.value);
    const int32_t t_mK = static_cast<int32_t>(kalman[j].estimate() * 1000.0f);
    in[j].measured_mK = t_mK;
    evidence[j].add(t_mK - predicted[j], 500, 700, 1000000);
    in[j].evidence_high = evidence[j].high();
    in[j].evidence_low = evidence[j].low();
    in[j].rise_mK_per_min = rise[j].push(t_mK);
    in[j].fault = !r.ok() || !t.ok();
  }
  // The firmware's own path: fixed-point resistance, table inverse, fixed-point filter.
  kalman_fixed_setup.configure(btsm::KalmanFixedParams());
  btsm::KalmanFixedGainMemo memo;
  for (uint8_t j = 0; j < btsm::kModelChannels; ++j) {
    const uint32_t r_q16 = btsm::code_to_ohm_q16(g_code + j, 2, btsm::ohm_q16_from_milliohm(6800000UL));
    const btsm::Pt1000FixedResult t = btsm::pt1000_temperature_q(r_q16);
    kalman_fixed[j].update(kalman_fixed_setup, t.t, &memo);
    g_sink[2 + (j & 1)] += kalman_fixed[j].estimate_mk();
  }
  g_sink[0] = static_cast<int32_t>(diag.update(in)) + static_cast<int32_t>(check.status);
  g_sink[1] = btsm::fx::fx_mul<btsm::fx::Q16_16>(btsm::fx::Q1_30::from_raw(g_sink[2]),
                                                 btsm::fx::Q16_16::from_raw(g_sink[3]),
                                                 btsm::fx::Rounding::kNearestHalfAway).raw();
  return 0;
}
