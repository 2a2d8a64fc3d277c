#pragma once
// The host's side of the module's reduced model (definition in common/model_blob.hpp): the model
// in physical units and double precision, the reference the fixed-point step is tested against
// and the host predicts with, and the quantizer that turns it into the blob's fixed point.
#include "common/model_blob.hpp"

#include <cstdint>
#include <string>

namespace btsm::thermal {

// One channel's detector, in physical units (the quantizer converts to the blob's units).
struct ChannelDetector {
  double drift_K = 0.5;                 // K, residual forgiven per sample by the upper evidence
  double low_drift_K = 0.5;             // K, the same for the lower evidence
  double warn_evidence_K_min = 2.0;     // K min, upper evidence -> WARN
  double alarm_evidence_K_min = 4.0;    // K min, upper evidence -> ALARM (> warn)
  double low_warn_evidence_K_min = 4.0; // K min, lower evidence -> WARN; 0 = off
  double abs_limit_c = 80.0;            // degC, measured above -> ALARM
  double max_rise_K_per_min = 2.0;      // K/min, rate of rise above -> ALARM; 0 = off
};

struct ReducedModelF64 {
  uint16_t dt_ms = 5000;                       // ms, the sample period the poles are for
  uint8_t n_breakpoints = 0;                   // 2..kModelMaxBreakpoints
  uint8_t ambient_channel = 3;                 // 0-based, kModelAmbientNone = none (default ch4)
  uint8_t enabled_mask = 0x1F;                 // channels with a prediction (ambient included)
  uint16_t stop_end_s[kModelEarlyStopPhases] = {};  // s, ends of the early stop phases (0 = unused)
  uint16_t speed_rpm[kModelMaxBreakpoints] = {};    // rpm, breakpoint 0 = 0
  double a[kModelMaxBreakpoints][kModelChannels] = {};  // 1, discrete pole per step
  double b_K[kModelMaxBreakpoints][kModelChannels] = {};  // K per step while running
  double stop_a[kModelEarlyStopPhases][kModelChannels] = {};  // 1, early stop-phase poles
  uint8_t role[kModelChannels] = {};            // channel map (model_blob.hpp)
  uint8_t carrier[kModelChannels] = {};         // 0 = none, h + 1 = channel h carries channel j (model_blob.hpp)
  double couple[kModelChannels] = {};           // 1, c_j per step on the carrier's rise (0 without a carrier)
  ChannelDetector detector[kModelChannels];
};

struct ReducedModelF64State {
  double t_c[kModelChannels] = {};  // degC, predicted temperature per channel
  double stopped_s = 1e300;         // s since the stop (long stopped at the start)
};

// The same definition as the fixed-point step with the exact interpolation fraction and no
// rounding: predictions (degC; NaN for unmodelled channels, the ambient for the ambient channel),
// then the update.
void step(const ReducedModelF64& m, ReducedModelF64State& st, double speed_rpm, double ambient_c,
          double predicted_c[kModelChannels]);
// Channel j's update at a speed and a time since the stop, as the model defines it:
// T' = T_amb + a (T - T_amb) + c_j (T_carrier - T_amb) + b_K, with a and b_K interpolated between
// the breakpoints while running, and a the early stop phase's pole (else breakpoint 0's) when stopped.
struct ChannelUpdate {
  double a = 1.0;   // 1, the pole for this step
  double b_K = 0.0; // K, the heat input's step (0 when stopped)
};
ChannelUpdate channel_update(const ReducedModelF64& m, int j, double speed_rpm, double stopped_s);
// Every channel at the ambient (a cold machine), long stopped.
void init_at_ambient(const ReducedModelF64& m, ReducedModelF64State& st, double ambient_c);

// The module role code of a node name (a wire role name such as "rear_bearing"), else
// kModelRoleUnchecked: the channel map `reduce` writes into the blob for the channel of that node.
uint8_t role_for_node(const std::string& node_name);

// Converts to the blob's fixed point and validates. On error `out` is unspecified and the check
// names the status and the breakpoint/channel at fault.
ModelCheck quantize(const ReducedModelF64& f, ReducedModel& out);
// quantize() without validate(): only each field's conversion and range (a pole in [0, 1), a limit
// within the probes' range, a value that fits its field). Lets a table that was edited into an
// invalid model (a 100 K gain: steady rise > 1000 K) still be encoded and compared field by field.
ModelCheck quantize_fields(const ReducedModelF64& f, ReducedModel& out);

// The evidence threshold units of the blob for `K_min` K x minutes at sample period dt_ms.
double evidence_units(double K_min, uint16_t dt_ms);
// And back (K x minutes).
double evidence_K_min(uint16_t units, uint16_t dt_ms);

}  // namespace btsm::thermal
