#include "host/link/firmware_image.hpp"

#include "common/hex_text.hpp"
#include "common/device_key.hpp"
#include "host/io/hex.hpp"
#include "host/io/input_error.hpp"
#include "host/io/input_file.hpp"
#include "host/io/output_file.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

extern char** environ;

namespace btsm::link {

size_t HexImage::line_of(uint32_t address) const {
  for (const HexRecordSpan& r : records)
    if (address >= r.first && address - r.first < r.count) return r.line;
  return 0;
}

HexImage parse_intel_hex(const std::string& text, const std::string& source) {
  HexImage img;
  std::istringstream in(text);
  std::string line;
  size_t line_no = 0;
  uint32_t base = 0;
  bool eof = false;
  auto fail = [&](const std::string& why) { throw io::InputError(fmt::format("{}:{}: {}", source, line_no, why)); };
  while (std::getline(in, line)) {
    ++line_no;
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (line.empty()) continue;
    if (eof) fail("data after the end-of-file record");
    if (line_no == 1 && line.compare(0, 3, "\xEF\xBB\xBF") == 0)
      fail("starts with a UTF-8 byte order mark; an Intel HEX file is plain ASCII (save it without the BOM)");
    if (line[0] != ':') fail("record does not start with ':'");
    if (line.size() < 11 || (line.size() - 1) % 2 != 0) fail("record too short or odd length");
    std::vector<uint8_t> rec((line.size() - 1) / 2);
    const HexDecodeResult hex = hex_decode(line.data() + 1, line.size() - 1, rec.data(), rec.size(), false);
    if (hex.status != HexStatus::kOk) fail(fmt::format("bad hex digit at column {}", hex.at + 2));
    const size_t len = rec[0];
    if (rec.size() != len + 5) fail(fmt::format("length field {} does not match the record", len));
    uint8_t sum = 0;
    for (uint8_t b : rec) sum = static_cast<uint8_t>(sum + b);
    if (sum != 0) fail("checksum mismatch");
    const uint32_t addr = (static_cast<uint32_t>(rec[1]) << 8) | rec[2];
    switch (rec[3]) {
      case 0x00:
        if (len > 0) img.records.push_back({base + addr, static_cast<uint32_t>(len), line_no});
        for (size_t i = 0; i < len; ++i) {
          // a second record over the same byte with other data: which one the programmer writes
          // depends on the tool, so the image means two things
          const uint32_t at = base + addr + static_cast<uint32_t>(i);
          const auto [it, fresh] = img.bytes.emplace(at, rec[4 + i]);
          if (!fresh && it->second != rec[4 + i])
            fail(fmt::format("address 0x{:04X} written twice with different data (0x{:02X}, then 0x{:02X})", at, it->second,
                             rec[4 + i]));
        }
        if (img.bytes.size() > kMaxHexImageBytes)
          fail(fmt::format("more than {} bytes of data, the limit for a firmware image", kMaxHexImageBytes));
        break;
      case 0x01:
        if (len != 0) fail(fmt::format("end-of-file record with {} data bytes (it has none: a corrupt line?)", len));
        eof = true;
        break;
      case 0x02:
        if (len != 2) fail("extended segment address record must have 2 bytes");
        base = ((static_cast<uint32_t>(rec[4]) << 8) | rec[5]) << 4;
        break;
      case 0x04:
        if (len != 2) fail("extended linear address record must have 2 bytes");
        base = ((static_cast<uint32_t>(rec[4]) << 8) | rec[5]) << 16;
        break;
      case 0x03: case 0x05: break;  // start address: irrelevant for flash
      default: fail(fmt::format("unknown record type 0x{:02x}", rec[3]));
    }
  }
  if (!eof) throw io::InputError(source + ": no end-of-file record (truncated file?)");
  return img;
}

HexImage read_intel_hex(const std::string& path) {
  return parse_intel_hex(io::read_input_file(path, kMaxHexFileBytes, "firmware image (Intel HEX)"), path);
}

std::string format_intel_hex(const HexImage& image) {
  std::string out;
  auto record = [&](uint8_t type, uint16_t addr, const std::vector<uint8_t>& data) {
    uint8_t sum = static_cast<uint8_t>(data.size() + (addr >> 8) + (addr & 0xFF) + type);
    out += fmt::format(":{:02X}{:04X}{:02X}", data.size(), addr, type);
    for (uint8_t b : data) {
      out += fmt::format("{:02X}", b);
      sum = static_cast<uint8_t>(sum + b);
    }
    out += fmt::format("{:02X}\n", static_cast<uint8_t>(-sum));
  };
  uint32_t upper = 0;
  auto it = image.bytes.begin();
  while (it != image.bytes.end()) {
    const uint32_t start = it->first;
    if ((start >> 16) != upper) {
      upper = start >> 16;
      record(0x04, 0, {static_cast<uint8_t>(upper >> 8), static_cast<uint8_t>(upper)});
    }
    std::vector<uint8_t> data;
    uint32_t addr = start;
    // Up to 16 contiguous bytes, not crossing a 16-byte line or a 64 KiB boundary.
    while (it != image.bytes.end() && it->first == addr && data.size() < 16 && (data.empty() || (addr & 0xF) != 0) &&
           (addr >> 16) == upper) {
      data.push_back(it->second);
      ++addr;
      ++it;
    }
    record(0x00, static_cast<uint16_t>(start & 0xFFFF), data);
  }
  record(0x01, 0, {});
  return out;
}

std::optional<KeyRecord> read_device_key(const HexImage& image) {
  uint8_t rec[device_key::kRecordSize];
  for (uint16_t i = 0; i < device_key::kRecordSize; ++i) {
    auto it = image.bytes.find(device_key::kFlashAddress + i);
    if (it == image.bytes.end()) return std::nullopt;
    rec[i] = it->second;
  }
  if (!device_key::record_valid(rec)) return std::nullopt;
  KeyRecord k;
  k.device_id = get_le32(rec + device_key::kOffsetDeviceId);
  std::copy(rec + device_key::kOffsetKey, rec + device_key::kOffsetKey + device_key::kKeySize, k.key.begin());
  return k;
}

KeyPatchResult patch_device_key(HexImage& image, uint32_t device_id, const DeviceKey& key) {
  static_assert(kDeviceKeySize == device_key::kKeySize, "host and firmware key sizes differ");
  KeyPatchResult r;
  uint8_t cur[device_key::kRecordSize];
  bool erased = true;
  for (uint16_t i = 0; i < device_key::kRecordSize; ++i) {
    auto it = image.bytes.find(device_key::kFlashAddress + i);
    if (it == image.bytes.end())
      throw io::InputError(fmt::format(
          "the image has no key record at 0x{:04X}..0x{:04X} (not a BTSM firmware image, or built without "
          "the .btsm_key section)", device_key::kFlashAddress, device_key::kFlashAddress + device_key::kRecordSize - 1));
    cur[i] = it->second;
    erased = erased && cur[i] == 0xFF;
  }
  if (!erased) {
    if (!device_key::record_valid(cur))
      throw io::InputError(fmt::format("the image holds unexpected bytes at the key record 0x{:04X} (neither "
                                       "erased nor a valid record): refusing to patch", device_key::kFlashAddress));
    r.had_key = true;
    r.previous_device_id = get_le32(cur + device_key::kOffsetDeviceId);
  }
  uint8_t rec[device_key::kRecordSize];
  device_key::build_record(rec, device_id, key.data());
  for (uint16_t i = 0; i < device_key::kRecordSize; ++i) image.bytes[device_key::kFlashAddress + i] = rec[i];
  return r;
}

std::vector<std::string> avrdude_command(const std::string& port, const std::string& hex_path,
                                         const std::string& avrdude) {
  return {avrdude, "-p", "atmega328p", "-c", "arduino", "-b", "115200", "-P", port, "-D",
          "-U", "flash:w:" + hex_path + ":i"};
}

int run_command(const std::vector<std::string>& argv) {
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, args[0], nullptr, nullptr, args.data(), environ);
  if (rc != 0) throw std::runtime_error(fmt::format("cannot start {}: {}", argv[0], std::strerror(rc)));
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) throw std::runtime_error(std::string("waitpid: ") + std::strerror(errno));
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  return 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
}

void write_private_file(const std::string& path, const std::string& text) {
  io::write_output_file(path, text, "patched firmware image", io::FileAccess::Private);
}

}  // namespace btsm::link
