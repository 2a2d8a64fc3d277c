// The module's temperature channel count: five Pt1000 probes on AIN1..AIN5 of the AD7794. The
// wire format, the model blob, the firmware and the host all size their per-channel arrays with
// this one constant, so a board with another probe count changes one line.
#ifndef BTSM_COMMON_CHANNELS_HPP
#define BTSM_COMMON_CHANNELS_HPP

#include <stdint.h>

namespace btsm {

const uint8_t kChannels = 5;

}  // namespace btsm

#endif
