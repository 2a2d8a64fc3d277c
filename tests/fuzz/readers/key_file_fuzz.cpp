// Key files (the content of <device_id>.key) and device ids. A key file's content gives a key or
// throws io::InputError naming the file; an accepted key is exactly the file's 64 hex digits
// (whitespace dropped, case ignored). parse_device_id accepts exactly 1..8 hex digits with an
// optional 0x, and device_id_text reads back to the same id.
#include "fuzz_check.hpp"
#include "host/io/input_error.hpp"
#include "host/link/device_keys.hpp"

#include <cctype>
#include <string>

using namespace btsm;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const link::DeviceKey key = link::key_from_file_content(text, "fuzz.key");
    std::string digits;
    for (char c : text)
      if (!std::isspace(static_cast<unsigned char>(c))) digits += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    FUZZ_CHECK(link::key_to_hex(key) == digits);
    FUZZ_CHECK(link::key_from_hex(text).has_value());
  } catch (const io::InputError& e) {
    FUZZ_CHECK(std::string(e.what()).find("fuzz.key") != std::string::npos);
    FUZZ_CHECK(!link::key_from_hex(text).has_value());
  }
  if (const auto id = link::parse_device_id(text)) {
    FUZZ_CHECK(link::parse_device_id(link::device_id_text(*id)) == id);
  }
  return 0;
}
