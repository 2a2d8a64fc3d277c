// Blob and hex readers: the first byte picks one, the rest is the input.
//  0: the model blob codec (check_model_blob = common decode + validate, what the module does):
//     an accepted blob re-encodes to the same bytes.
//  1: the hex codec: decoded bytes re-encode to the input's digits (lower-cased, whitespace
//     dropped); a refusal names a character that is not a hex digit or an odd digit count.
//  2: Intel HEX: a parsed image, written out and parsed again, is the same image; errors are
//     io::InputError only.
#include "common/hex_text.hpp"
#include "common/model_blob.hpp"
#include "fuzz_check.hpp"
#include "host/io/hex.hpp"
#include "host/io/input_error.hpp"
#include "host/link/firmware_image.hpp"
#include "host/link/model_blob_file.hpp"

#include <cctype>
#include <string>

using namespace btsm;

namespace {

void blob_codec(std::span<const uint8_t> bytes) {
  if (!link::check_model_blob(bytes).empty()) return;
  ReducedModel m;
  FUZZ_CHECK(decode(bytes.data(), bytes.size(), m).ok());
  std::vector<uint8_t> again(kReducedModelBlobSize);
  encode(m, again.data());
  FUZZ_CHECK(std::equal(again.begin(), again.end(), bytes.begin(), bytes.end()));
}

void hex_codec(const std::string& text) {
  const io::HexDecode d = io::decode_hex(text);
  if (!d.ok()) {
    FUZZ_CHECK(d.bad_char ? hex_digit_value(text[d.bad_offset]) < 0 : d.odd_digits);
    FUZZ_CHECK(!d.problem(text).empty());
    return;
  }
  std::string digits;
  for (char c : text)
    if (hex_digit_value(c) >= 0) digits += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  FUZZ_CHECK(io::to_hex(d.bytes) == digits);
}

void intel_hex(const std::string& text) {
  link::HexImage img;
  try {
    img = link::parse_intel_hex(text, "fuzz.hex");
  } catch (const io::InputError&) {
    return;
  }
  FUZZ_CHECK(img.size() <= link::kMaxHexImageBytes);
  const link::HexImage again = link::parse_intel_hex(link::format_intel_hex(img), "written back");
  FUZZ_CHECK(again.bytes == img.bytes);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::span<const uint8_t> rest(data + 1, size - 1);
  const std::string text(rest.begin(), rest.end());
  switch (data[0] % 3) {
    case 0: blob_codec(rest); break;
    case 1: hex_codec(text); break;
    default: intel_hex(text); break;
  }
  return 0;
}
