#pragma once
// Intel HEX images and the per-device key record of common/device_key.hpp: parse, patch the
// 64-byte record at device_key::kFlashAddress, write the patched image, and build the avrdude
// command line for the Bluno (programmed like an Arduino Uno through Optiboot).
#include "host/link/device_keys.hpp"

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace btsm::link {

// Where a data record of the HEX file put its bytes: [first, first + count) from line `line`.
struct HexRecordSpan {
  uint32_t first = 0;
  uint32_t count = 0;
  size_t line = 0;
};

// Sparse byte image: address -> byte, as the HEX file describes it.
struct HexImage {
  std::map<uint32_t, uint8_t> bytes;
  std::vector<HexRecordSpan> records;  // of a parsed file, in file order (empty for a built image)
  size_t size() const { return bytes.size(); }
  // The line of the first data record that wrote `address`; 0 when unknown.
  size_t line_of(uint32_t address) const;
};

// Limits of the reader (stated in its errors): the ATmega328P image is 32 KiB, about 90 kB of HEX.
constexpr size_t kMaxHexFileBytes = size_t{4} << 20;
constexpr size_t kMaxHexImageBytes = size_t{1} << 20;

// Parses Intel HEX (record types 00, 01, 02, 04; 03/05 start addresses are ignored). Throws
// io::InputError("<source>:<line>: ...") on bad characters, lengths, checksums or more than
// kMaxHexImageBytes of data.
HexImage parse_intel_hex(const std::string& text, const std::string& source);
HexImage read_intel_hex(const std::string& path);
// 16 data bytes per record, extended linear address records above 64 KiB, EOF record.
std::string format_intel_hex(const HexImage& image);

struct KeyPatchResult {
  bool had_key = false;          // the image already held a valid record (now replaced)
  uint32_t previous_device_id = 0;
};

// Writes a valid key record for (device_id, key). The image must contain the 64-byte record
// region, either erased (all 0xFF, as built) or a valid record; anything else means this is
// not a BTSM image (or another layout) and is refused.
KeyPatchResult patch_device_key(HexImage& image, uint32_t device_id, const DeviceKey& key);

// Reads the record back (nullopt when absent or invalid).
struct KeyRecord {
  uint32_t device_id = 0;
  DeviceKey key{};
};
std::optional<KeyRecord> read_device_key(const HexImage& image);

// avrdude -p atmega328p -c arduino -b 115200 -P PORT -D -U flash:w:FILE:i
std::vector<std::string> avrdude_command(const std::string& port, const std::string& hex_path,
                                         const std::string& avrdude = "avrdude");

// Runs a command, inheriting stdio; returns its exit status. Throws if it cannot be started.
int run_command(const std::vector<std::string>& argv);

// Writes text to path with mode 0600 (the patched image contains the device key), through
// io::write_output_file: a failed write leaves an image that was there as it was.
void write_private_file(const std::string& path, const std::string& text);

}  // namespace btsm::link
