#pragma once
// The input of `btsm flash-model`: a model blob file, raw or inside the JSON of `btsm reduce`,
// and the local check of the blob before anything is sent to a module.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace btsm::link {

// Size caps, stated in the errors: a blob is 464 bytes and a reduced-model JSON a few tens of kB.
constexpr std::size_t kMaxModelFileBytes = std::size_t{16} << 20;  // the FILE argument (raw or JSON)
constexpr std::size_t kMaxBlobFileBytes = std::size_t{64} << 10;   // a file a JSON names in "blob_file"

// Loads a model blob: a raw .bin, or the JSON of `btsm reduce` holding the blob as hex
// ("blob_hex" or "blob") or a path to it ("blob_file"/"blob_path", relative to the JSON).
// Throws io::InputError (a std::invalid_argument: exit code 2) naming the file and what is wrong:
// unreadable, larger than its cap, not valid JSON, hex that is not hex, no blob at all.
std::vector<uint8_t> load_model_blob(const std::string& path);

// The same from the file's content; `read_blob_file` reads a path named by "blob_file" (already
// made absolute); load_model_blob passes a capped read of the file system.
std::vector<uint8_t> model_blob_from_content(std::string_view content, const std::string& path,
                                             const std::function<std::vector<uint8_t>(const std::string&)>& read_blob_file);

// Checks the blob like the firmware will (length, CRC, magic, version, values); returns an
// empty string when valid, else the reason.
std::string check_model_blob(std::span<const uint8_t> blob);

// The speeds a model knows, for `flash-model` and `info`: "running breakpoints 500, 2000, ..., 8000
// rpm (0 rpm = stopped; ...)". `speeds` holds n entries, entry 0 the stop (blob layout).
std::string describe_model_speeds(const uint16_t* speeds, uint8_t n);
// The same from a blob (empty when it is too short to hold them).
std::string describe_model_speeds(std::span<const uint8_t> blob);

}  // namespace btsm::link
