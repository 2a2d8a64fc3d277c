#pragma once
// BLE serial profiles: which characteristic carries host->module bytes, which one notifies
// module->host bytes, and what setup the device needs. Chosen from the discovered GATT
// database, never from hard-coded handles (they differ between CC2540 firmware versions).
//   Bluno (DFRobot)  service 0xDFB0, serial 0xDFB1 (write + notify), command 0xDFB2 (AT),
//                    Device Information Model Number 0x2A24 starting with "DF BLUNO"
//   Nordic UART      service 6E400001-..., one write characteristic and one notify
//                    characteristic (picked by properties: vendors disagree on RX/TX naming)
//   HM-10 / CC2541   service 0xFFE0, serial 0xFFE1 (write + notify)
#include "host/link/gatt_client.hpp"

namespace btsm::link {

enum class BleProfileKind { kBluno, kNordicUart, kHm10 };
const char* to_string(BleProfileKind k);

struct BleSerialProfile {
  BleProfileKind kind = BleProfileKind::kBluno;
  uint16_t tx_handle = 0;        // value handle the host writes
  bool tx_with_response = false; // Write Request (only when write-without-response is missing)
  uint16_t rx_handle = 0;        // value handle the module notifies
  uint16_t rx_cccd = 0;          // its Client Characteristic Configuration descriptor
  uint16_t command_handle = 0;   // Bluno 0xDFB2 (AT commands), 0 otherwise
  bool command_with_response = true;
  uint16_t model_number_handle = 0;  // 0x2A24 if present
};

// Picks the profile from a discovered database. Throws LinkError(kUnsupported) listing the
// services found when none matches or a required characteristic/CCCD is missing.
BleSerialProfile choose_profile(const GattDatabase& db, const std::string& peer);

struct BlunoSetup {
  std::string password = "DFRobot";  // AT+PASSWOR (sic) of the DFRobot firmware
  unsigned uart_baud = 115200;       // AT+CURRUART: CC2540 <-> ATmega UART rate
};

// Runs the profile's connect sequence: Bluno: read 0x2A24 and check the "DF BLUNO" prefix,
// write the AT password and UART rate to 0xDFB2; then enable notifications on the RX
// characteristic. Throws LinkError with the reason.
void setup_profile(GattClient& client, const BleSerialProfile& p, const std::string& peer,
                   const BlunoSetup& bluno = {});

}  // namespace btsm::link
