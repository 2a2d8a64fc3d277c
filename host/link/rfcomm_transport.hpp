#pragma once
// Classic Bluetooth SPP (HC-05 style modules) through an RFCOMM socket of libbluetooth.
// No D-Bus and no /dev/rfcommN binding needed; the device must be paired (PIN) if it asks.
#include "host/link/fd_stream.hpp"

namespace btsm::link {

struct RfcommOptions {
  int channel = 1;                 // RFCOMM channel (SPP is usually 1)
  Millis connect_timeout{10000};   // page + connect; classic connects can take several seconds
};

class RfcommTransport : public FdStreamTransport {
 public:
  RfcommTransport(std::string address, RfcommOptions opts = {});  // connects; throws LinkError
  std::string describe() const override;

 protected:
  int open_fd() override;

 private:
  std::string address_;
  RfcommOptions opts_;
};

// Parses "AA:BB:CC:DD:EE:FF" strictly; throws LinkError(kNoDevice) naming the text otherwise.
void parse_bdaddr_or_throw(const std::string& text, uint8_t out_le[6]);

}  // namespace btsm::link
