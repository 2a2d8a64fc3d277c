#include "host/io/hex.hpp"

#include "common/hex_text.hpp"
#include "host/io/input_error.hpp"

namespace btsm::io {

std::string to_hex(std::span<const uint8_t> bytes) {
  std::string s(2 * bytes.size(), '0');
  hex_encode(bytes.data(), bytes.size(), s.data());
  return s;
}

std::string HexDecode::problem(std::string_view text) const {
  if (bad_char) {
    const unsigned char c = static_cast<unsigned char>(text[bad_offset]);
    const std::string shown = c >= 0x20 && c < 0x7F ? std::string("'") + static_cast<char>(c) + "'"
                                                    : "byte 0x" + to_hex(std::span<const uint8_t>(&c, 1));
    return shown + " at character " + std::to_string(bad_offset + 1) + " is not a hex digit";
  }
  if (odd_digits) return "an odd number of hex digits (" + std::to_string(2 * bytes.size() + 1) + ")";
  return {};
}

HexDecode decode_hex(std::string_view text) {
  HexDecode r;
  r.bytes.resize((text.size() + 1) / 2);  // room for every digit: an odd count ends as kOddDigits, never kTooLong
  const HexDecodeResult d = hex_decode(text.data(), text.size(), r.bytes.data(), r.bytes.size(), true);
  r.bytes.resize(d.bytes);
  r.bad_char = d.status == HexStatus::kBadCharacter;
  r.bad_offset = d.at;
  r.odd_digits = d.status == HexStatus::kOddDigits;
  return r;
}

std::vector<uint8_t> hex_to_bytes(std::string_view text, const std::string& where) {
  HexDecode r = decode_hex(text);
  if (!r.ok()) throw InputError(where + ": " + r.problem(text));
  return std::move(r.bytes);
}

}  // namespace btsm::io
