#include "host/link/device_keys.hpp"

#include "common/hex_text.hpp"
#include "host/io/hex.hpp"
#include "host/io/input_error.hpp"
#include "host/io/input_file.hpp"
#include "host/io/output_file.hpp"

#include <fcntl.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace btsm::link {
namespace fs = std::filesystem;

std::string device_id_text(uint32_t id) {
  char buf[9];
  std::snprintf(buf, sizeof buf, "%08x", id);
  return buf;
}

std::optional<uint32_t> parse_device_id(const std::string& text) {
  std::string t = text;
  if (t.size() > 2 && t[0] == '0' && (t[1] == 'x' || t[1] == 'X')) t = t.substr(2);
  if (t.empty() || t.size() > 8) return std::nullopt;
  for (char c : t)
    if (hex_digit_value(c) < 0) return std::nullopt;
  return static_cast<uint32_t>(std::stoul(t, nullptr, 16));
}

std::string key_to_hex(const DeviceKey& key) {
  std::string s(2 * key.size(), '0');
  hex_encode(key.data(), key.size(), s.data());
  return s;
}

std::optional<DeviceKey> key_from_hex(const std::string& text) {
  DeviceKey key{};
  const HexDecodeResult r = hex_decode(text.data(), text.size(), key.data(), key.size(), true);
  if (r.status != HexStatus::kOk || r.bytes != key.size()) return std::nullopt;
  return key;
}

DeviceKey key_from_file_content(std::string_view content, const std::string& path) {
  const io::HexDecode d = io::decode_hex(content);
  if (!d.ok()) throw io::InputError("key file " + path + ": " + d.problem(content) + " (expected 64 hex digits, a 32-byte key)");
  if (d.bytes.size() != kDeviceKeySize)
    throw io::InputError("key file " + path + ": " + std::to_string(d.bytes.size()) +
                         " bytes of hex, expected 32 (64 hex digits)");
  DeviceKey key{};
  std::copy(d.bytes.begin(), d.bytes.end(), key.begin());
  return key;
}

KeyStore KeyStore::from_environment() {
  const char* xdg = std::getenv("XDG_CONFIG_HOME");
  if (xdg != nullptr && xdg[0] == '/') return KeyStore(std::string(xdg) + "/btsm/keys");
  const char* home = std::getenv("HOME");
  if (home == nullptr || home[0] == '\0')
    throw std::runtime_error("cannot locate the key directory: neither XDG_CONFIG_HOME nor HOME is set");
  return KeyStore(std::string(home) + "/.config/btsm/keys");
}

std::string KeyStore::path_for(uint32_t id) const { return dir_ + "/" + device_id_text(id) + ".key"; }

bool KeyStore::exists(uint32_t id) const {
  std::error_code ec;
  return fs::exists(path_for(id), ec);
}

namespace {

// Before the file is opened, what lstat says: no key at all, or a symbolic link (which O_NOFOLLOW
// would refuse as "Too many levels of symbolic links").
void refuse_missing_or_linked_key(uint32_t id, const std::string& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0 && errno == ENOENT)
    throw io::InputError("no key for device " + device_id_text(id) + " (" + path + "): create one with `btsm keys generate " +
                         device_id_text(id) + "` or `btsm keys import " + device_id_text(id) + " HEX`");
  if (S_ISLNK(st.st_mode)) throw io::InputError("key file " + path + " is a symbolic link (key files must be regular files)");
}

}  // namespace

DeviceKey KeyStore::load(uint32_t id) const {
  const std::string path = path_for(id);
  refuse_missing_or_linked_key(id, path);
  // Opened without waiting (a named pipe in the key store hung `keys list` for ever), then the
  // open file is checked: no window between the check and the read.
  io::InputFile file(path, "key file", O_NOFOLLOW);
  const struct stat& st = file.status();
  if (!S_ISREG(st.st_mode)) throw io::InputError("key file " + path + " is " + io::file_type_name(st.st_mode) + ", not a regular file");
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", st.st_mode & 07777);
    throw io::InputError("key file " + path + " has permissions " + mode +
                         ", readable or writable by others: refusing to use it (run `chmod 600 " + path +
                         "` if the key was not exposed, otherwise generate a new key and reflash)");
  }
  // A key file holds 64 hex digits and a newline; anything after them is an error, not ignored.
  return key_from_file_content(file.read_all(kMaxKeyFileBytes, io::FileKind::Binary), path);
}

void KeyStore::save(uint32_t id, const DeviceKey& key, bool overwrite) const {
  const std::string path = path_for(id);
  // A named pipe there blocked `keys generate --force` for ever: refused as bad input, at once.
  if (const std::string kind = io::special_file_kind(path); !kind.empty())
    throw io::InputError("key file " + path + " is " + kind + ", not a file to write the key to");
  std::error_code ec;
  if (!fs::exists(dir_, ec)) {
    fs::create_directories(dir_, ec);
    if (ec) throw std::runtime_error("cannot create key directory " + dir_ + ": " + ec.message());
    ::chmod(dir_.c_str(), 0700);
  }
  const std::string text = key_to_hex(key) + "\n";
  // Replaced beside and renamed over it: a failed write leaves the old key as it was.
  if (overwrite) return io::write_output_file(path, text, "key", io::FileAccess::Private);
  try {
    io::write_new_output_file(path, text, "key", io::FileAccess::Private);
  } catch (const std::runtime_error&) {
    struct stat st {};
    if (::lstat(path.c_str(), &st) != 0) throw;  // not there: the write itself failed
    throw std::runtime_error("key file " + path + " already exists: refusing to overwrite a device key "
                             "(a module flashed with it would no longer accept models)");
  }
}

DeviceKey KeyStore::generate() {
  DeviceKey key{};
  size_t got = 0;
  while (got < key.size()) {
    const ssize_t n = ::getrandom(key.data() + got, key.size() - got, 0);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw std::runtime_error(std::string("getrandom: ") + std::strerror(errno));
    }
    got += static_cast<size_t>(n);
  }
  return key;
}

std::vector<uint32_t> KeyStore::list() const {
  std::vector<uint32_t> ids;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir_, ec)) {
    const auto name = e.path().filename().string();
    if (e.path().extension() != ".key") continue;
    if (auto id = parse_device_id(name.substr(0, name.size() - 4))) ids.push_back(*id);
  }
  std::sort(ids.begin(), ids.end());
  return ids;
}

}  // namespace btsm::link
