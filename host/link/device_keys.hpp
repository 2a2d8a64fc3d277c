#pragma once
// Per-device HMAC keys on the host: one file per module, <dir>/<device_id>.key, holding the
// 32-byte key as 64 hex characters. <dir> = $XDG_CONFIG_HOME/btsm/keys (default
// ~/.config/btsm/keys). The directory is created 0700 and files 0600; a key file readable or
// writable by group/others is refused, as ssh does, because whoever reads it can flash models.
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace btsm::link {

constexpr size_t kDeviceKeySize = 32;  // = device_key::kKeySize in common/device_key.hpp
using DeviceKey = std::array<uint8_t, kDeviceKeySize>;

// Device ids are the u32 of INFO / the firmware key record, written as 8 lowercase hex digits.
std::string device_id_text(uint32_t device_id);
// Accepts "0000de70", "0xDE70", "de70"; nullopt when not hex or too long.
std::optional<uint32_t> parse_device_id(const std::string& text);

std::string key_to_hex(const DeviceKey& key);
// 64 hex characters (whitespace ignored); nullopt otherwise.
std::optional<DeviceKey> key_from_hex(const std::string& text);

// A key file holds 64 hex digits and a newline; this cap (stated in the error) bounds the read.
constexpr size_t kMaxKeyFileBytes = 4096;
// The key in a key file's content; throws io::InputError naming `path` and what is wrong.
DeviceKey key_from_file_content(std::string_view content, const std::string& path);

class KeyStore {
 public:
  // Directory from the environment ($XDG_CONFIG_HOME, else $HOME/.config) + "/btsm/keys".
  static KeyStore from_environment();
  explicit KeyStore(std::string dir) : dir_(std::move(dir)) {}

  const std::string& dir() const { return dir_; }
  std::string path_for(uint32_t device_id) const;

  // Loads a key; throws io::InputError (exit code 2) naming the file when it is missing, not a
  // regular file, has wider permissions than 0600, is larger than kMaxKeyFileBytes or malformed.
  DeviceKey load(uint32_t device_id) const;
  bool exists(uint32_t device_id) const;
  // Writes a key (creating the directory 0700, the file 0600). Refuses to overwrite unless told.
  void save(uint32_t device_id, const DeviceKey& key, bool overwrite = false) const;
  // Random key from the kernel CSPRNG (getrandom).
  static DeviceKey generate();
  // Device ids with a key file, sorted.
  std::vector<uint32_t> list() const;

 private:
  std::string dir_;
};

}  // namespace btsm::link
