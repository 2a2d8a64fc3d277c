// Capped file reading with POSIX calls: fstat tells a regular file's size before anything is read,
// and a loop of bounded reads handles devices and pipes, whose size is unknown.
#include "host/io/input_file.hpp"

#include "host/io/input_error.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace btsm::io {

std::string size_text(std::size_t bytes) {
  if (bytes >= kMiB && bytes % kMiB == 0) return std::to_string(bytes / kMiB) + " MiB";
  if (bytes >= kKiB && bytes % kKiB == 0) return std::to_string(bytes / kKiB) + " KiB";
  return std::to_string(bytes) + " bytes";
}

namespace {

// Closes the descriptor on every path out of read_input_file.
struct Fd {
  int fd;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

[[noreturn]] void too_large(const std::string& path, std::size_t max_bytes, const std::string& what) {
  throw InputError(path + ": larger than " + size_text(max_bytes) + ", the limit for a " + what);
}

}  // namespace

std::string read_input_file(const std::string& path, std::size_t max_bytes, const std::string& what, FileKind kind) {
  // O_NONBLOCK: opening a named pipe no program writes to would wait for a writer for ever; so
  // opened, the pipe reads as empty at once. Reads block again once the file is open.
  const Fd f{::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK)};
  if (f.fd < 0) throw InputError(path + ": cannot open " + what + ": " + std::strerror(errno));
  struct stat st {};
  if (::fstat(f.fd, &st) != 0) throw InputError(path + ": cannot stat " + what + ": " + std::strerror(errno));
  if (S_ISDIR(st.st_mode)) throw InputError(path + ": is a directory, not a " + what);
  if (const int flags = ::fcntl(f.fd, F_GETFL); flags < 0 || ::fcntl(f.fd, F_SETFL, flags & ~O_NONBLOCK) < 0)
    throw InputError(path + ": cannot read " + what + ": " + std::strerror(errno));
  if (S_ISREG(st.st_mode) && static_cast<unsigned long long>(st.st_size) > max_bytes) too_large(path, max_bytes, what);
  std::string out;
  char buf[64 * 1024];
  for (;;) {
    const ssize_t n = ::read(f.fd, buf, sizeof buf);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw InputError(path + ": cannot read " + what + ": " + std::strerror(errno));
    }
    if (n == 0) {
      if (out.empty() && S_ISFIFO(st.st_mode)) throw InputError(path + ": a named pipe with no program writing to it, not a " + what);
      break;
    }
    const auto got = static_cast<std::size_t>(n);
    if (kind == FileKind::Text) {
      if (const void* nul = std::memchr(buf, '\0', got)) {
        // Spreadsheets and PowerShell save "Unicode" text as UTF-16: every other byte NUL.
        const auto b = [&](std::size_t i) { return i < got ? static_cast<unsigned char>(buf[i]) : 0x100; };
        const bool utf16 = out.empty() && ((b(0) == 0xFF && b(1) == 0xFE) || (b(0) == 0xFE && b(1) == 0xFF) ||
                                           (b(0) != 0 && b(1) == 0 && b(2) != 0 && b(3) == 0));
        if (utf16) throw InputError(path + ": UTF-16 text, expected a " + what + " in UTF-8 (or ASCII): save it as UTF-8");
        throw InputError(path + ": not a text file (NUL byte at offset " +
                         std::to_string(out.size() + static_cast<std::size_t>(static_cast<const char*>(nul) - buf)) +
                         "), expected a " + what);
      }
    }
    if (got > max_bytes - out.size()) too_large(path, max_bytes, what);
    out.append(buf, got);
  }
  return out;
}

}  // namespace btsm::io
