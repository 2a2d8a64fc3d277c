#include "host/link/ble_profile.hpp"

#include <cctype>

namespace btsm::link {

using att::Uuid;

const char* to_string(BleProfileKind k) {
  switch (k) {
    case BleProfileKind::kBluno: return "Bluno (DFRobot 0xDFB0)";
    case BleProfileKind::kNordicUart: return "Nordic UART Service";
    case BleProfileKind::kHm10: return "HM-10 (0xFFE0)";
  }
  return "?";
}

namespace {

const Uuid& nus_service() {
  static const Uuid u = *Uuid::parse("6e400001-b5a3-f393-e0a9-e50e24dcca9e");
  return u;
}

[[noreturn]] void unsupported(const GattDatabase& db, const std::string& peer, const std::string& why) {
  std::string services;
  for (const auto& s : db.services) services += (services.empty() ? "" : ", ") + s.uuid.str();
  throw LinkError(LinkErrorKind::kUnsupported,
                  peer + ": " + why + " (services found: " + (services.empty() ? "none" : services) +
                      "; supported: Bluno 0xdfb0, Nordic UART 6e400001-..., HM-10 0xffe0)");
}

void fill_serial(BleSerialProfile& p, const GattCharacteristic& tx, const GattCharacteristic& rx,
                 const GattDatabase& db, const std::string& peer) {
  if (!tx.can(att::kPropWrite) && !tx.can(att::kPropWriteWithoutResponse))
    unsupported(db, peer, "characteristic " + tx.uuid.str() + " is not writable");
  if (!rx.can(att::kPropNotify) && !rx.can(att::kPropIndicate))
    unsupported(db, peer, "characteristic " + rx.uuid.str() + " does not notify");
  if (rx.cccd_handle() == 0)
    unsupported(db, peer, "characteristic " + rx.uuid.str() + " has no CCCD (0x2902)");
  p.tx_handle = tx.value_handle;
  p.tx_with_response = !tx.can(att::kPropWriteWithoutResponse);
  p.rx_handle = rx.value_handle;
  p.rx_cccd = rx.cccd_handle();
}

}  // namespace

BleSerialProfile choose_profile(const GattDatabase& db, const std::string& peer) {
  BleSerialProfile p;
  if (const auto* mn = db.find(att::gatt::model_number())) p.model_number_handle = mn->value_handle;

  const Uuid bluno = Uuid::from16(0xDFB0);
  if (db.has_service(bluno)) {
    const auto* serial = db.find(Uuid::from16(0xDFB1), &bluno);
    const auto* command = db.find(Uuid::from16(0xDFB2), &bluno);
    if (serial == nullptr) unsupported(db, peer, "Bluno service without serial characteristic 0xdfb1");
    p.kind = BleProfileKind::kBluno;
    fill_serial(p, *serial, *serial, db, peer);
    p.command_handle = command ? command->value_handle : 0;
    p.command_with_response = command ? !command->can(att::kPropWriteWithoutResponse) : true;
    return p;
  }
  if (db.has_service(nus_service())) {
    const GattCharacteristic* tx = nullptr;
    const GattCharacteristic* rx = nullptr;
    for (const auto& c : db.characteristics) {
      if (!(c.service == nus_service())) continue;
      if (!tx && (c.can(att::kPropWrite) || c.can(att::kPropWriteWithoutResponse))) tx = &c;
      if (!rx && (c.can(att::kPropNotify) || c.can(att::kPropIndicate))) rx = &c;
    }
    if (!tx || !rx) unsupported(db, peer, "Nordic UART service lacks a write or a notify characteristic");
    p.kind = BleProfileKind::kNordicUart;
    fill_serial(p, *tx, *rx, db, peer);
    return p;
  }
  const Uuid hm10 = Uuid::from16(0xFFE0);
  if (db.has_service(hm10)) {
    const auto* serial = db.find(Uuid::from16(0xFFE1), &hm10);
    if (serial == nullptr) unsupported(db, peer, "HM-10 service without characteristic 0xffe1");
    p.kind = BleProfileKind::kHm10;
    fill_serial(p, *serial, *serial, db, peer);
    return p;
  }
  unsupported(db, peer, "no known BLE serial service");
}

void setup_profile(GattClient& client, const BleSerialProfile& p, const std::string& peer,
                   const BlunoSetup& bluno) {
  if (p.kind == BleProfileKind::kBluno) {
    if (p.model_number_handle == 0)
      throw LinkError(LinkErrorKind::kUnsupported,
                      peer + ": Bluno service found but no Model Number (0x2a24) to confirm it is a Bluno");
    const auto value = client.read(p.model_number_handle);
    const std::string model(value.begin(), value.end());
    // BlunoLibrary compares the upper-cased value: firmware versions differ in case.
    std::string upper = model;
    for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    if (upper.rfind("DF BLUNO", 0) != 0)
      throw LinkError(LinkErrorKind::kUnsupported,
                      peer + ": Model Number is '" + model + "', not a DFRobot Bluno (expected 'DF BLUNO...')");
    if (p.command_handle != 0) {
      // The DFRobot connect sequence: unlock with the password, then set the bridge's UART
      // rate. Each line ends with CR LF.
      const std::string pass = "AT+PASSWOR=" + bluno.password + "\r\n";
      const std::string baud = "AT+CURRUART=" + std::to_string(bluno.uart_baud) + "\r\n";
      for (const std::string* line : {&pass, &baud}) {
        const auto* b = reinterpret_cast<const uint8_t*>(line->data());
        client.write_chunked(p.command_handle, std::span<const uint8_t>(b, line->size()), p.command_with_response);
      }
    }
  }
  client.enable_notifications(p.rx_cccd);
}

}  // namespace btsm::link
