#pragma once
// Probes: the plant's true channel temperatures -> PT1000 resistances (IEC 60751 Callendar-Van
// Dusen, common/rtd.hpp in double) and faults -> the AD7794 model's analog front end.
#include "boards/sim/ad7794_model.hpp"
#include "host/sim/plant/spindle_plant.hpp"

namespace btsm::sim {

// Writes probe resistances and fault states for "now" into the front end.
//   open      -> ProbeFault::kOpenSense   (that AIN pair floats)
//   openchain -> ProbeFault::kOpenElement (no excitation current through the chain)
//   short     -> ProbeFault::kShort
//   absent ch5 (Ch5Mode::Disabled) -> kOpenSense (nothing connected to AIN5)
//   noadc -> chip_missing, noref -> reference_lost
void apply_to_front_end(const SpindlePlant& plant, AnalogFrontEnd& fe);

// PT1000 resistance (ohm) at t (degC); throws std::out_of_range outside -200..850 degC.
double pt1000_ohm(double t_c);

}  // namespace btsm::sim
