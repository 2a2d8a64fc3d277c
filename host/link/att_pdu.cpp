#include "host/link/att_pdu.hpp"

#include "common/hex_text.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>

namespace btsm::link::att {
namespace {

// Bluetooth base UUID 00000000-0000-1000-8000-00805F9B34FB, little-endian; bytes 12..13 take
// the 16-bit value.
constexpr std::array<uint8_t, 16> kBase = {0xFB, 0x34, 0x9B, 0x5F, 0x80, 0x00, 0x00, 0x80,
                                           0x00, 0x10, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00};

void put16(Pdu& p, uint16_t v) {
  p.push_back(static_cast<uint8_t>(v));
  p.push_back(static_cast<uint8_t>(v >> 8));
}
uint16_t get16(std::span<const uint8_t> p, size_t at) {
  return static_cast<uint16_t>(p[at] | (p[at + 1] << 8));
}
void append(Pdu& p, const Bytes& b) { p.insert(p.end(), b.begin(), b.end()); }

}  // namespace

const char* error_name(uint8_t code) {
  switch (code) {
    case kInvalidHandle: return "invalid handle";
    case kReadNotPermitted: return "read not permitted";
    case kWriteNotPermitted: return "write not permitted";
    case kInvalidPdu: return "invalid PDU";
    case kInsufficientAuthentication: return "insufficient authentication (pair the device)";
    case kRequestNotSupported: return "request not supported";
    case kInvalidOffset: return "invalid offset";
    case kAttributeNotFound: return "attribute not found";
    case kAttributeNotLong: return "attribute not long";
    case kInvalidAttributeValueLength: return "invalid attribute value length";
    case kUnlikelyError: return "unlikely error";
    case kInsufficientEncryption: return "insufficient encryption (pair the device)";
    case kUnsupportedGroupType: return "unsupported group type";
    default: return "ATT error";
  }
}

const char* opcode_name(uint8_t op) {
  switch (op) {
    case kErrorRsp: return "Error Response";
    case kMtuReq: return "Exchange MTU Request";
    case kMtuRsp: return "Exchange MTU Response";
    case kFindInfoReq: return "Find Information Request";
    case kFindInfoRsp: return "Find Information Response";
    case kFindByTypeValueReq: return "Find By Type Value Request";
    case kFindByTypeValueRsp: return "Find By Type Value Response";
    case kReadByTypeReq: return "Read By Type Request";
    case kReadByTypeRsp: return "Read By Type Response";
    case kReadReq: return "Read Request";
    case kReadRsp: return "Read Response";
    case kReadBlobReq: return "Read Blob Request";
    case kReadBlobRsp: return "Read Blob Response";
    case kReadByGroupTypeReq: return "Read By Group Type Request";
    case kReadByGroupTypeRsp: return "Read By Group Type Response";
    case kWriteReq: return "Write Request";
    case kWriteRsp: return "Write Response";
    case kHandleValueNotification: return "Handle Value Notification";
    case kHandleValueIndication: return "Handle Value Indication";
    case kHandleValueConfirmation: return "Handle Value Confirmation";
    case kWriteCmd: return "Write Command";
    default: return "unknown opcode";
  }
}

bool is_request(uint8_t op) {
  // Requests are the even opcodes below 0x1B plus the other request PDUs of the spec; commands
  // (bit 6 set) and notifications/indications/confirmations are not answered.
  if (op & 0x40) return false;
  switch (op) {
    case kMtuReq: case kFindInfoReq: case kFindByTypeValueReq: case kReadByTypeReq: case kReadReq:
    case kReadBlobReq: case 0x0E /* Read Multiple */: case kReadByGroupTypeReq: case kWriteReq:
    case 0x16 /* Prepare Write */: case 0x18 /* Execute Write */: case 0x20 /* Read Multiple Variable */:
      return true;
    default:
      return false;
  }
}

// --- Uuid ----------------------------------------------------------------------------------
Uuid Uuid::from16(uint16_t s) {
  Uuid u;
  u.le_ = kBase;
  u.le_[12] = static_cast<uint8_t>(s);
  u.le_[13] = static_cast<uint8_t>(s >> 8);
  return u;
}

std::optional<Uuid> Uuid::from_le(std::span<const uint8_t> b) {
  if (b.size() == 2) return from16(static_cast<uint16_t>(b[0] | (b[1] << 8)));
  if (b.size() != 16) return std::nullopt;
  Uuid u;
  for (size_t i = 0; i < 16; ++i) u.le_[i] = b[i];
  return u;
}

std::optional<Uuid> Uuid::parse(const std::string& text) {
  std::string hex;
  std::string t = text;
  if (t.size() > 2 && t[0] == '0' && (t[1] == 'x' || t[1] == 'X')) t = t.substr(2);
  for (char c : t) {
    if (c == '-') continue;
    if (hex_digit_value(c) < 0) return std::nullopt;
    hex.push_back(c);
  }
  if (hex.size() == 4) {
    return from16(static_cast<uint16_t>(std::stoul(hex, nullptr, 16)));
  }
  if (hex.size() != 32) return std::nullopt;
  if (t.find('-') != std::string::npos &&
      (t.size() != 36 || t[8] != '-' || t[13] != '-' || t[18] != '-' || t[23] != '-'))
    return std::nullopt;
  Uuid u;
  hex_decode(hex.data(), hex.size(), u.le_.data(), u.le_.size(), false);  // all digits: checked above
  std::reverse(u.le_.begin(), u.le_.end());  // text is big-endian, storage little-endian
  return u;
}

bool Uuid::is16() const {
  for (size_t i = 0; i < 16; ++i)
    if (i != 12 && i != 13 && le_[i] != kBase[i]) return false;
  return true;
}

uint16_t Uuid::short16() const { return static_cast<uint16_t>(le_[12] | (le_[13] << 8)); }

Bytes Uuid::to_le() const {
  if (is16()) return {le_[12], le_[13]};
  return Bytes(le_.begin(), le_.end());
}

std::string Uuid::str() const {
  char buf[40];
  if (is16()) {
    std::snprintf(buf, sizeof buf, "0x%04x", short16());
    return buf;
  }
  std::string s;
  for (int i = 15; i >= 0; --i) {
    std::snprintf(buf, sizeof buf, "%02x", le_[static_cast<size_t>(i)]);
    s += buf;
    if (i == 12 || i == 10 || i == 8 || i == 6) s += '-';
  }
  return s;
}

// --- Requests ----------------------------------------------------------------------------------
Pdu encode_mtu(uint8_t opcode, uint16_t mtu) {
  Pdu p{opcode};
  put16(p, mtu);
  return p;
}
bool decode_mtu(std::span<const uint8_t> p, uint8_t opcode, uint16_t& mtu) {
  if (p.size() != 3 || p[0] != opcode) return false;
  mtu = get16(p, 1);
  return mtu >= kDefaultLeMtu;
}

Pdu encode_typed_range(uint8_t opcode, const TypedRangeReq& r) {
  Pdu p{opcode};
  put16(p, r.range.start);
  put16(p, r.range.end);
  append(p, r.type.to_le());
  return p;
}
bool decode_typed_range(std::span<const uint8_t> p, uint8_t opcode, TypedRangeReq& r) {
  if ((p.size() != 7 && p.size() != 21) || p[0] != opcode) return false;
  r.range = {get16(p, 1), get16(p, 3)};
  auto u = Uuid::from_le(p.subspan(5));
  if (!u) return false;
  r.type = *u;
  return true;
}

Pdu encode_find_info_req(HandleRange r) {
  Pdu p{kFindInfoReq};
  put16(p, r.start);
  put16(p, r.end);
  return p;
}
bool decode_find_info_req(std::span<const uint8_t> p, HandleRange& r) {
  if (p.size() != 5 || p[0] != kFindInfoReq) return false;
  r = {get16(p, 1), get16(p, 3)};
  return true;
}

Pdu encode_read_req(uint16_t handle) {
  Pdu p{kReadReq};
  put16(p, handle);
  return p;
}
bool decode_read_req(std::span<const uint8_t> p, uint16_t& handle) {
  if (p.size() != 3 || p[0] != kReadReq) return false;
  handle = get16(p, 1);
  return true;
}

Pdu encode_read_blob_req(const ReadBlobReq& r) {
  Pdu p{kReadBlobReq};
  put16(p, r.handle);
  put16(p, r.offset);
  return p;
}
bool decode_read_blob_req(std::span<const uint8_t> p, ReadBlobReq& r) {
  if (p.size() != 5 || p[0] != kReadBlobReq) return false;
  r = {get16(p, 1), get16(p, 3)};
  return true;
}

Pdu encode_write(uint8_t opcode, const WriteReq& w) {
  Pdu p{opcode};
  put16(p, w.handle);
  append(p, w.value);
  return p;
}
bool decode_write(std::span<const uint8_t> p, uint8_t opcode, WriteReq& w) {
  if (p.size() < 3 || p[0] != opcode) return false;
  w.handle = get16(p, 1);
  w.value.assign(p.begin() + 3, p.end());
  return true;
}

// --- Responses -------------------------------------------------------------------------------
Pdu encode_error_rsp(const ErrorRsp& e) {
  Pdu p{kErrorRsp, e.request_opcode};
  put16(p, e.handle);
  p.push_back(e.code);
  return p;
}
bool decode_error_rsp(std::span<const uint8_t> p, ErrorRsp& e) {
  if (p.size() != 5 || p[0] != kErrorRsp) return false;
  e = {p[1], get16(p, 2), p[4]};
  return true;
}

Pdu encode_read_by_group_rsp(std::span<const GroupRecord> recs, uint16_t mtu, size_t& taken) {
  taken = 0;
  if (recs.empty()) return {};
  const size_t uuid_len = recs[0].uuid.to_le().size();
  const size_t rec_len = 4 + uuid_len;
  Pdu p{kReadByGroupTypeRsp, static_cast<uint8_t>(rec_len)};
  for (const auto& r : recs) {
    if (r.uuid.to_le().size() != uuid_len || p.size() + rec_len > mtu) break;
    put16(p, r.start);
    put16(p, r.end);
    append(p, r.uuid.to_le());
    ++taken;
  }
  return p;
}
bool decode_read_by_group_rsp(std::span<const uint8_t> p, std::vector<GroupRecord>& recs) {
  recs.clear();
  if (p.size() < 2 || p[0] != kReadByGroupTypeRsp) return false;
  const size_t len = p[1];
  if ((len != 6 && len != 20) || (p.size() - 2) % len != 0 || p.size() == 2) return false;
  for (size_t at = 2; at < p.size(); at += len) {
    GroupRecord r;
    r.start = get16(p, at);
    r.end = get16(p, at + 2);
    r.uuid = *Uuid::from_le(p.subspan(at + 4, len - 4));
    if (r.start == 0 || r.end < r.start) return false;
    recs.push_back(r);
  }
  return true;
}

Pdu encode_read_by_type_rsp(std::span<const TypeRecord> recs, uint16_t mtu, size_t& taken) {
  taken = 0;
  if (recs.empty()) return {};
  // A value longer than the room left is truncated to fit, as the spec allows for the first one.
  const size_t room = static_cast<size_t>(std::min<int>(mtu - 4, 253));
  const size_t vlen = std::min(recs[0].value.size(), room);
  const size_t rec_len = 2 + vlen;
  Pdu p{kReadByTypeRsp, static_cast<uint8_t>(rec_len)};
  for (const auto& r : recs) {
    if (std::min(r.value.size(), room) != vlen || p.size() + rec_len > mtu) break;
    put16(p, r.handle);
    p.insert(p.end(), r.value.begin(), r.value.begin() + static_cast<long>(vlen));
    ++taken;
  }
  return p;
}
bool decode_read_by_type_rsp(std::span<const uint8_t> p, std::vector<TypeRecord>& recs) {
  recs.clear();
  if (p.size() < 2 || p[0] != kReadByTypeRsp) return false;
  const size_t len = p[1];
  if (len < 2 || p.size() == 2 || (p.size() - 2) % len != 0) return false;
  for (size_t at = 2; at < p.size(); at += len) {
    TypeRecord r;
    r.handle = get16(p, at);
    if (r.handle == 0) return false;
    r.value.assign(p.begin() + static_cast<long>(at + 2), p.begin() + static_cast<long>(at + len));
    recs.push_back(std::move(r));
  }
  return true;
}

Pdu encode_find_info_rsp(std::span<const InfoRecord> recs, uint16_t mtu, size_t& taken) {
  taken = 0;
  if (recs.empty()) return {};
  const bool short_form = recs[0].type.is16();
  const size_t rec_len = short_form ? 4 : 18;
  Pdu p{kFindInfoRsp, static_cast<uint8_t>(short_form ? 0x01 : 0x02)};
  for (const auto& r : recs) {
    if (r.type.is16() != short_form || p.size() + rec_len > mtu) break;
    put16(p, r.handle);
    append(p, r.type.to_le());
    ++taken;
  }
  return p;
}
bool decode_find_info_rsp(std::span<const uint8_t> p, std::vector<InfoRecord>& recs) {
  recs.clear();
  if (p.size() < 2 || p[0] != kFindInfoRsp || (p[1] != 1 && p[1] != 2)) return false;
  const size_t len = p[1] == 1 ? 4 : 18;
  if (p.size() == 2 || (p.size() - 2) % len != 0) return false;
  for (size_t at = 2; at < p.size(); at += len) {
    InfoRecord r;
    r.handle = get16(p, at);
    if (r.handle == 0) return false;
    r.type = *Uuid::from_le(p.subspan(at + 2, len - 2));
    recs.push_back(r);
  }
  return true;
}

Pdu encode_value_rsp(uint8_t opcode, std::span<const uint8_t> value) {
  // Sized once and copied into: inserting into a one-byte vector made GCC 12 warn of a memcpy out
  // of bounds (-Warray-bounds, a false positive of its inlined reallocation).
  Pdu p(1 + value.size());
  p[0] = opcode;
  std::copy(value.begin(), value.end(), p.begin() + 1);
  return p;
}

Pdu encode_handle_value(uint8_t opcode, const HandleValue& hv) {
  Pdu p{opcode};
  put16(p, hv.handle);
  append(p, hv.value);
  return p;
}
bool decode_handle_value(std::span<const uint8_t> p, HandleValue& hv) {
  if (p.size() < 3 || (p[0] != kHandleValueNotification && p[0] != kHandleValueIndication)) return false;
  hv.handle = get16(p, 1);
  hv.value.assign(p.begin() + 3, p.end());
  return hv.handle != 0;
}

Bytes encode_char_declaration(const CharDeclaration& d) {
  Pdu p{d.properties};
  put16(p, d.value_handle);
  append(p, d.uuid.to_le());
  return p;
}
bool decode_char_declaration(std::span<const uint8_t> v, CharDeclaration& d) {
  if (v.size() != 5 && v.size() != 19) return false;
  d.properties = v[0];
  d.value_handle = get16(v, 1);
  d.uuid = *Uuid::from_le(v.subspan(3));
  return d.value_handle != 0;
}

}  // namespace btsm::link::att
