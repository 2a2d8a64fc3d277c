#include "host/link/device_keys.hpp"

#include "common/hex_text.hpp"

#include <fcntl.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
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
    if (!std::isxdigit(static_cast<unsigned char>(c))) return std::nullopt;
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

DeviceKey KeyStore::load(uint32_t id) const {
  const std::string path = path_for(id);
  // Open first, then fstat the open file: no window between the check and the read.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
  if (fd < 0) {
    if (errno == ENOENT)
      throw std::runtime_error("no key for device " + device_id_text(id) + " (" + path +
                               "): create one with `btsm keys generate " + device_id_text(id) +
                               "` or `btsm keys import " + device_id_text(id) + " HEX`");
    throw std::runtime_error("cannot open key file " + path + ": " + std::strerror(errno));
  }
  struct stat st {};
  ::fstat(fd, &st);
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    throw std::runtime_error("key file " + path + " is not a regular file");
  }
  if ((st.st_mode & 077) != 0) {
    ::close(fd);
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", st.st_mode & 07777);
    throw std::runtime_error("key file " + path + " has permissions " + mode +
                             ", readable or writable by others: refusing to use it (run `chmod 600 " + path +
                             "` if the key was not exposed, otherwise generate a new key and reflash)");
  }
  std::string text(256, '\0');
  const ssize_t n = ::read(fd, text.data(), text.size());
  ::close(fd);
  if (n < 0) throw std::runtime_error("cannot read key file " + path + ": " + std::strerror(errno));
  text.resize(static_cast<size_t>(n));
  const auto key = key_from_hex(text);
  if (!key) throw std::runtime_error("key file " + path + ": expected 64 hex characters (a 32-byte key)");
  return *key;
}

void KeyStore::save(uint32_t id, const DeviceKey& key, bool overwrite) const {
  std::error_code ec;
  if (!fs::exists(dir_, ec)) {
    fs::create_directories(dir_, ec);
    if (ec) throw std::runtime_error("cannot create key directory " + dir_ + ": " + ec.message());
    ::chmod(dir_.c_str(), 0700);
  }
  const std::string path = path_for(id);
  const int flags = O_WRONLY | O_CREAT | O_CLOEXEC | O_NOFOLLOW | (overwrite ? O_TRUNC : O_EXCL);
  const int fd = ::open(path.c_str(), flags, 0600);
  if (fd < 0) {
    if (errno == EEXIST)
      throw std::runtime_error("key file " + path + " already exists: refusing to overwrite a device key "
                               "(a module flashed with it would no longer accept models)");
    throw std::runtime_error("cannot write key file " + path + ": " + std::strerror(errno));
  }
  ::fchmod(fd, 0600);
  const std::string text = key_to_hex(key) + "\n";
  const ssize_t n = ::write(fd, text.data(), text.size());
  const int err = errno;
  ::close(fd);
  if (n != static_cast<ssize_t>(text.size()))
    throw std::runtime_error("cannot write key file " + path + ": " + std::strerror(err));
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
