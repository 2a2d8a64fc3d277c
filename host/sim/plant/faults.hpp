#pragma once
// Injectable faults and "hidden effects" of the simulated spindle module.
//
// Fault spec (one per --fault option):   KIND[:ARG]@START[-END]   times with units (s, m, h)
//   open:ch2@3600        probe on channel 2 open (broken sense lead / connector) from t = 3600 s:
//                        that channel's input floats, the series chain still carries current
//   openchain:ch2@3600   element or force lead of channel 2 broken: the series chain carries no
//                        current any more, so EVERY channel loses its signal (a real hazard of
//                        the 5-probe series connection)
//   short:ch1@100-200    probe on channel 1 shorted from 100 s to 200 s
//   noadc@0              AD7794 missing (no answer on SPI, MISO stays high)
//   noref@50             reference lost (REFIN open: NOXREF, codes clamp)
//   bearing:25W@7200     bearing fault: 25 W extra heat at the rear bearing (node 1) from 2 h
//   bearing:front:25W@2h the same at the front bearing (node 3); bearing:rear:25W@2h = bearing:25W@2h
// Hidden effects (physics the paper's model lacks): hidden_effects.hpp.
// Errors throw std::invalid_argument naming the spec and the part that is wrong.
#include "host/sim/plant/hidden_effects.hpp"

#include <limits>
#include <string>
#include <vector>

namespace btsm::sim {

enum class FaultKind { OpenProbe, OpenChain, ShortedProbe, MissingAdc, LostReference, BearingHeat };

// Where a BearingHeat fault heats: the bearing measured by ch1 (rear) or ch3 (front).
enum class BearingPlace { Rear, Front };

struct FaultSpec {
  FaultKind kind = FaultKind::OpenProbe;
  int channel = 0;             // 1..5 for probe faults, 0 otherwise
  double start_s = 0.0;        // s, fault active from this simulated time
  double end_s = std::numeric_limits<double>::infinity();  // s, active until (exclusive)
  double heat_w = 0.0;         // W, BearingHeat only
  BearingPlace place = BearingPlace::Rear;  // BearingHeat only
  bool active_at(double t_s) const { return t_s >= start_s && t_s < end_s; }
};

FaultSpec parse_fault(const std::string& spec);
std::string to_string(const FaultSpec& f);

}  // namespace btsm::sim
