#pragma once
// Hex text of the host's files (blobs in reduced-model JSON, key files): std::string and error
// messages around the one codec, common/hex_text.hpp. Lower-case out; either case in.
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace btsm::io {

// Two lower-case digits per byte, no separators.
std::string to_hex(std::span<const uint8_t> bytes);

// Result of decode_hex: the bytes, or where and why the text is not hex.
struct HexDecode {
  std::vector<uint8_t> bytes;
  std::size_t bad_offset = 0;  // 0-based offset of the first character that is not a hex digit
  bool bad_char = false;
  bool odd_digits = false;     // an odd number of hex digits
  bool ok() const { return !bad_char && !odd_digits; }
  // "'g' at character 17 is not a hex digit", "an odd number of hex digits (63)"; "" when ok.
  std::string problem(std::string_view text) const;
};

// Decodes pairs of hex digits; ASCII whitespace between digits is ignored.
HexDecode decode_hex(std::string_view text);

// decode_hex or InputError("<where>: <problem>").
std::vector<uint8_t> hex_to_bytes(std::string_view text, const std::string& where);

}  // namespace btsm::io
