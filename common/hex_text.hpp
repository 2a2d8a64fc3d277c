// Bytes <-> hexadecimal text, the one codec for every hex string the project reads or writes
// (the model blob in a reduction's JSON, device keys, UUIDs, Intel HEX records). A checked pair:
// hex_encode writes lowercase digits, the first byte first; hex_decode reads either case and says
// where the text stopped being hex. C++14, no standard library, so any layer may include it.
#ifndef BTSM_COMMON_HEX_TEXT_HPP
#define BTSM_COMMON_HEX_TEXT_HPP

#include <stddef.h>
#include <stdint.h>

namespace btsm {

// Value 0..15 of one hexadecimal digit (either case), -1 if c is not one.
inline int hex_digit_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// Writes 2 * n lowercase digits to out (no terminator): byte i becomes characters 2i (high
// nibble) and 2i + 1 (low nibble).
inline void hex_encode(const uint8_t* bytes, size_t n, char* out) {
  static const char kDigits[] = "0123456789abcdef";
  for (size_t i = 0; i < n; ++i) {
    out[2 * i] = kDigits[bytes[i] >> 4];
    out[2 * i + 1] = kDigits[bytes[i] & 0x0F];
  }
}

enum class HexStatus : uint8_t {
  kOk,
  kBadCharacter,  // a character that is neither a digit nor (when allowed) white space
  kOddDigits,     // the digits end in the middle of a byte
  kTooLong,       // more bytes than the output holds
};

struct HexDecodeResult {
  HexStatus status;
  size_t bytes;   // bytes written to out
  size_t at;      // index in the text of the offending character (kBadCharacter, kTooLong)
};

// Reads len characters of text into at most capacity bytes. With skip_space, ASCII white space
// between (and inside) byte pairs is ignored, so wrapped or grouped text reads the same.
inline HexDecodeResult hex_decode(const char* text, size_t len, uint8_t* out, size_t capacity,
                                  bool skip_space) {
  HexDecodeResult r = {HexStatus::kOk, 0, 0};
  int high = -1;
  for (size_t i = 0; i < len; ++i) {
    const char c = text[i];
    if (skip_space && (c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v'))
      continue;
    const int v = hex_digit_value(c);
    if (v < 0) {
      r.status = HexStatus::kBadCharacter;
      r.at = i;
      return r;
    }
    if (high < 0) {
      if (r.bytes == capacity) {
        r.status = HexStatus::kTooLong;
        r.at = i;
        return r;
      }
      high = v;
    } else {
      out[r.bytes++] = static_cast<uint8_t>(high * 16 + v);
      high = -1;
    }
  }
  if (high >= 0) r.status = HexStatus::kOddDigits;
  return r;
}

}  // namespace btsm

#endif
