// Capped file reading with POSIX calls: fstat tells a regular file's size before anything is read,
// and a loop of bounded reads handles devices and pipes, whose size is unknown.
#include "host/io/input_file.hpp"

#include "host/io/input_error.hpp"
#include "host/io/utf8_text.hpp"

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

[[noreturn]] void too_large(const std::string& path, std::size_t max_bytes, const std::string& what) {
  throw InputError(path + ": larger than " + size_text(max_bytes) + ", the limit for a " + what);
}

// The encoding the first bytes of a text file say, when it is UTF-16 or UTF-32 ("" otherwise):
// spreadsheets and PowerShell save "Unicode" text as UTF-16, with or without a byte order mark.
// Without a mark only NULs tell (`nul`: the first chunk holds one): every other byte of ASCII in
// UTF-16, three of four in UTF-32. The UTF-32 LE mark starts with the UTF-16 LE one: tested first.
std::string utf16_or_32(const char* buf, std::size_t got, bool nul) {
  const auto b = [&](std::size_t i) { return i < got ? static_cast<unsigned char>(buf[i]) : 0x100u; };
  const bool n0 = b(0) == 0, n1 = b(1) == 0, n2 = b(2) == 0, n3 = b(3) == 0, all4 = got >= 4;
  if (b(0) == 0xFF && b(1) == 0xFE && n2 && n3) return "UTF-32 text (little-endian, byte order mark FF FE 00 00)";
  if (n0 && n1 && b(2) == 0xFE && b(3) == 0xFF) return "UTF-32 text (big-endian, byte order mark 00 00 FE FF)";
  if (b(0) == 0xFF && b(1) == 0xFE) return "UTF-16 text (little-endian, byte order mark FF FE)";
  if (b(0) == 0xFE && b(1) == 0xFF) return "UTF-16 text (big-endian, byte order mark FE FF)";
  if (!nul || !all4) return "";
  if (!n0 && n1 && n2 && n3) return "UTF-32 text (little-endian, no byte order mark)";
  if (n0 && n1 && n2 && !n3) return "UTF-32 text (big-endian, no byte order mark)";
  if (!n0 && n1 && !n2 && n3) return "UTF-16 text (little-endian, no byte order mark)";
  if (n0 && !n1 && n2 && !n3) return "UTF-16 text (big-endian, no byte order mark)";
  return "";
}

}  // namespace

std::string file_type_name(mode_t mode) {
  if (S_ISREG(mode)) return "";
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a named pipe";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISLNK(mode)) return "a symbolic link";
  return "no regular file";
}

std::string open_failure_reason(const std::string& path, int err) {
  switch (err) {
    case ENOENT: {
      struct stat st {};
      if (::lstat(path.c_str(), &st) == 0 && S_ISLNK(st.st_mode)) {
        char target[4096];
        const ssize_t n = ::readlink(path.c_str(), target, sizeof target - 1);
        return "a symbolic link to '" + (n > 0 ? std::string(target, static_cast<std::size_t>(n)) : std::string("?")) +
               "', which does not exist (a dangling link)";
      }
      return "no such file or directory";
    }
    case ELOOP: return "a symbolic-link loop (ELOOP: the links lead back to each other, or more than 40 deep)";
    case EACCES: return "permission denied (EACCES): this user may not read it, or may not enter a directory on its path";
    case ENOTDIR: return "a part of the path before the last is not a directory (ENOTDIR)";
    case EISDIR: return "a directory";
    case ENAMETOOLONG: return "the path is too long (ENAMETOOLONG)";
    default: return std::strerror(err);
  }
}

InputFile::InputFile(const std::string& path, const std::string& what, int extra_flags) : path_(path), what_(what) {
  // O_NONBLOCK: opening a named pipe no program writes to would wait for a writer for ever; so
  // opened, the pipe reads as empty at once. Reads block again once the file is open.
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | extra_flags);
  if (fd_ < 0) {
    const int err = errno;
    // O_NOFOLLOW fails a symbolic link with ELOOP: it is a link, not a loop.
    struct stat st {};
    if (err == ELOOP && (extra_flags & O_NOFOLLOW) != 0 && ::lstat(path.c_str(), &st) == 0 && S_ISLNK(st.st_mode))
      throw InputError(path + ": is a symbolic link (a " + what + " must be a regular file)");
    throw InputError(path + ": cannot open " + what + ": " + open_failure_reason(path, err));
  }
  const auto fail = [&](const std::string& why) {
    ::close(fd_);
    throw InputError(path + ": " + why);
  };
  if (::fstat(fd_, &st_) != 0) fail("cannot stat " + what + ": " + std::strerror(errno));
  if (S_ISDIR(st_.st_mode)) fail("is a directory, not a " + what);
  if (const int flags = ::fcntl(fd_, F_GETFL); flags < 0 || ::fcntl(fd_, F_SETFL, flags & ~O_NONBLOCK) < 0)
    fail("cannot read " + what + ": " + std::strerror(errno));
}

InputFile::~InputFile() { ::close(fd_); }

std::string InputFile::read_all(std::size_t max_bytes, FileKind kind) {
  if (S_ISREG(st_.st_mode) && static_cast<unsigned long long>(st_.st_size) > max_bytes) too_large(path_, max_bytes, what_);
  std::string out;
  char buf[64 * 1024];
  for (;;) {
    const ssize_t n = ::read(fd_, buf, sizeof buf);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw InputError(path_ + ": cannot read " + what_ + ": " + std::strerror(errno));
    }
    if (n == 0) {
      if (out.empty() && S_ISFIFO(st_.st_mode)) throw InputError(path_ + ": a named pipe with no program writing to it, not a " + what_);
      break;
    }
    const auto got = static_cast<std::size_t>(n);
    if (kind == FileKind::Text) {
      const void* nul = std::memchr(buf, '\0', got);
      if (out.empty())
        if (const std::string wide = utf16_or_32(buf, got, nul != nullptr); !wide.empty())
          throw InputError(path_ + ": " + wide + ", expected a " + what_ + " in UTF-8 (or ASCII): save it as UTF-8");
      if (nul)
        throw InputError(path_ + ": not a text file (NUL byte at offset " +
                         std::to_string(out.size() + static_cast<std::size_t>(static_cast<const char*>(nul) - buf)) +
                         "), expected a " + what_);
    }
    if (got > max_bytes - out.size()) too_large(path_, max_bytes, what_);
    out.append(buf, got);
  }
  // A Latin-1 or CP1252 file ("°C" as the one byte 0xB0) passed here, and its bytes went on into
  // names and messages. A UTF-8 byte order mark is UTF-8 and passes (the readers skip it).
  if (kind == FileKind::Text)
    if (const std::string problem = utf8_problem(out); !problem.empty())
      throw InputError(path_ + ": " + problem + ", expected a " + what_ + " in UTF-8 (or ASCII): save it as UTF-8");
  return out;
}

std::string read_input_file(const std::string& path, std::size_t max_bytes, const std::string& what, FileKind kind) {
  return InputFile(path, what).read_all(max_bytes, kind);
}

}  // namespace btsm::io
