#pragma once
// ATT protocol data units (Bluetooth Core Vol 3 Part F) for the GATT client: opcodes, error
// codes, UUIDs, and codecs in checked pairs (request encoder + server-side decoder, response
// encoder + client-side decoder) so the in-process fake peripheral of the tests speaks exactly
// the bytes the client parses. All multi-byte fields are little-endian.
//
// BlueZ keeps these constants in its internal src/shared/att-types.h, not in the public
// libbluetooth headers, so they are defined here.
#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace btsm::link::att {

using Pdu = std::vector<uint8_t>;
using Bytes = std::vector<uint8_t>;

constexpr uint16_t kAttCid = 4;          // L2CAP fixed channel of ATT on LE
constexpr uint16_t kDefaultLeMtu = 23;   // until an MTU exchange says otherwise
constexpr uint16_t kMaxMtu = 517;

enum Opcode : uint8_t {
  kErrorRsp = 0x01,
  kMtuReq = 0x02,
  kMtuRsp = 0x03,
  kFindInfoReq = 0x04,
  kFindInfoRsp = 0x05,
  kFindByTypeValueReq = 0x06,
  kFindByTypeValueRsp = 0x07,
  kReadByTypeReq = 0x08,
  kReadByTypeRsp = 0x09,
  kReadReq = 0x0A,
  kReadRsp = 0x0B,
  kReadBlobReq = 0x0C,
  kReadBlobRsp = 0x0D,
  kReadByGroupTypeReq = 0x10,
  kReadByGroupTypeRsp = 0x11,
  kWriteReq = 0x12,
  kWriteRsp = 0x13,
  kHandleValueNotification = 0x1B,
  kHandleValueIndication = 0x1D,
  kHandleValueConfirmation = 0x1E,
  kWriteCmd = 0x52,
};

enum ErrorCode : uint8_t {
  kInvalidHandle = 0x01,
  kReadNotPermitted = 0x02,
  kWriteNotPermitted = 0x03,
  kInvalidPdu = 0x04,
  kInsufficientAuthentication = 0x05,
  kRequestNotSupported = 0x06,
  kInvalidOffset = 0x07,
  kAttributeNotFound = 0x0A,
  kAttributeNotLong = 0x0B,
  kInvalidAttributeValueLength = 0x0D,
  kUnlikelyError = 0x0E,
  kInsufficientEncryption = 0x0F,
  kUnsupportedGroupType = 0x10,
};
const char* error_name(uint8_t code);
const char* opcode_name(uint8_t opcode);
// True for opcodes a server must answer (requests); the client answers unexpected ones with
// kRequestNotSupported so the peer's ATT bearer does not stall.
bool is_request(uint8_t opcode);

// Characteristic property bits (the first byte of a 0x2803 declaration value).
enum Property : uint8_t {
  kPropRead = 0x02,
  kPropWriteWithoutResponse = 0x04,
  kPropWrite = 0x08,
  kPropNotify = 0x10,
  kPropIndicate = 0x20,
};

// A UUID kept as 16 bytes little-endian (the ATT byte order). 16-bit UUIDs are expanded with
// the Bluetooth base UUID 0000xxxx-0000-1000-8000-00805F9B34FB and shrink back when encoded.
class Uuid {
 public:
  Uuid() = default;
  static Uuid from16(uint16_t short_uuid);
  // "180a", "0x2A24" or "6e400001-b5a3-f393-e0a9-e50e24dcca9e"; nullopt when malformed.
  static std::optional<Uuid> parse(const std::string& text);
  // From 2 or 16 little-endian bytes; nullopt for other sizes.
  static std::optional<Uuid> from_le(std::span<const uint8_t> bytes);
  bool is16() const;
  uint16_t short16() const;           // valid when is16()
  Bytes to_le() const;                // 2 bytes if is16(), else 16
  std::string str() const;            // "0x2a24" or the canonical 36-character form
  bool operator==(const Uuid& o) const = default;

 private:
  std::array<uint8_t, 16> le_{};
};

namespace gatt {
inline Uuid primary_service() { return Uuid::from16(0x2800); }
inline Uuid characteristic() { return Uuid::from16(0x2803); }
inline Uuid cccd() { return Uuid::from16(0x2902); }
inline Uuid device_information() { return Uuid::from16(0x180A); }
inline Uuid model_number() { return Uuid::from16(0x2A24); }
}  // namespace gatt

// --- Requests (client encodes, server decodes) ----------------------------------------------
struct HandleRange {
  uint16_t start = 1, end = 0xFFFF;
};
struct TypedRangeReq {   // Read By Group Type / Read By Type
  HandleRange range;
  Uuid type;
};
struct WriteReq {         // Write Request / Write Command
  uint16_t handle = 0;
  Bytes value;
};
struct ReadBlobReq {
  uint16_t handle = 0;
  uint16_t offset = 0;
};

Pdu encode_mtu(uint8_t opcode, uint16_t mtu);  // kMtuReq or kMtuRsp
bool decode_mtu(std::span<const uint8_t> pdu, uint8_t opcode, uint16_t& mtu);
Pdu encode_typed_range(uint8_t opcode, const TypedRangeReq& req);  // kReadByGroupTypeReq/kReadByTypeReq
bool decode_typed_range(std::span<const uint8_t> pdu, uint8_t opcode, TypedRangeReq& req);
Pdu encode_find_info_req(HandleRange range);
bool decode_find_info_req(std::span<const uint8_t> pdu, HandleRange& range);
Pdu encode_read_req(uint16_t handle);
bool decode_read_req(std::span<const uint8_t> pdu, uint16_t& handle);
Pdu encode_read_blob_req(const ReadBlobReq& req);
bool decode_read_blob_req(std::span<const uint8_t> pdu, ReadBlobReq& req);
Pdu encode_write(uint8_t opcode, const WriteReq& req);  // kWriteReq or kWriteCmd
bool decode_write(std::span<const uint8_t> pdu, uint8_t opcode, WriteReq& req);

// --- Responses (server encodes, client decodes) ---------------------------------------------
struct ErrorRsp {
  uint8_t request_opcode = 0;
  uint16_t handle = 0;
  uint8_t code = 0;
};
struct GroupRecord {      // one primary service
  uint16_t start = 0, end = 0;
  Uuid uuid;
};
struct TypeRecord {       // Read By Type: handle + value
  uint16_t handle = 0;
  Bytes value;
};
struct InfoRecord {       // Find Information: handle + type
  uint16_t handle = 0;
  Uuid type;
};
struct HandleValue {      // notification / indication
  uint16_t handle = 0;
  Bytes value;
};

Pdu encode_error_rsp(const ErrorRsp& e);
bool decode_error_rsp(std::span<const uint8_t> pdu, ErrorRsp& e);
// Response encoders take as many records as fit `mtu` and all of the same size class (the
// protocol demands one length per response); they return how many they took in `taken`.
Pdu encode_read_by_group_rsp(std::span<const GroupRecord> recs, uint16_t mtu, size_t& taken);
bool decode_read_by_group_rsp(std::span<const uint8_t> pdu, std::vector<GroupRecord>& recs);
Pdu encode_read_by_type_rsp(std::span<const TypeRecord> recs, uint16_t mtu, size_t& taken);
bool decode_read_by_type_rsp(std::span<const uint8_t> pdu, std::vector<TypeRecord>& recs);
Pdu encode_find_info_rsp(std::span<const InfoRecord> recs, uint16_t mtu, size_t& taken);
bool decode_find_info_rsp(std::span<const uint8_t> pdu, std::vector<InfoRecord>& recs);
Pdu encode_value_rsp(uint8_t opcode, std::span<const uint8_t> value);  // kReadRsp / kReadBlobRsp
Pdu encode_handle_value(uint8_t opcode, const HandleValue& hv);       // notification / indication
bool decode_handle_value(std::span<const uint8_t> pdu, HandleValue& hv);

// Characteristic declaration value: properties, value handle, UUID.
struct CharDeclaration {
  uint8_t properties = 0;
  uint16_t value_handle = 0;
  Uuid uuid;
};
Bytes encode_char_declaration(const CharDeclaration& d);
bool decode_char_declaration(std::span<const uint8_t> value, CharDeclaration& d);

}  // namespace btsm::link::att
