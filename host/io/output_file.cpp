// POSIX calls throughout: rename(2) is the atomic replace, fstat/stat tell a device from a regular
// file, and close(2)'s result is the last chance to see a delayed write error (NFS, quota).
#include "host/io/output_file.hpp"

#include "host/io/input_error.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

namespace btsm::io {

namespace {

std::string errno_text() { return std::strerror(errno); }

[[noreturn]] void write_failed(const std::string& path, const std::string& what, const std::string& why) {
  throw std::runtime_error(path + ": cannot write the " + what + ": " + why);
}

// Writes all of `content` to `fd`; false (errno set) on the first failed or zero-length write.
bool write_all(int fd, std::string_view content) {
  while (!content.empty()) {
    const ssize_t n = ::write(fd, content.data(), content.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      if (n == 0) errno = EIO;
      return false;
    }
    content.remove_prefix(static_cast<std::size_t>(n));
  }
  return true;
}

bool is_special_file(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode);
}

}  // namespace

void write_output_file(const std::string& path, std::string_view content, const std::string& what) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) write_failed(path, what, "it is a directory");
  if (is_special_file(path)) {  // a device or pipe: no rename over it, write in place
    // Non-blocking open: a named pipe that no program reads blocked here for ever (after all the
    // command's work); it fails at once with ENXIO instead. Writes block again once it is open.
    const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd < 0 && errno == ENXIO) write_failed(path, what, "a named pipe that no program reads");
    if (fd < 0) write_failed(path, what, errno_text());
    const int flags = ::fcntl(fd, F_GETFL);
    if (flags >= 0) (void)::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
    const bool ok = write_all(fd, content);
    const std::string why = errno_text();
    if (::close(fd) != 0 && ok) write_failed(path, what, errno_text());
    if (!ok) write_failed(path, what, why);
    return;
  }
  std::string tmp = path + ".tmp.XXXXXX";
  const int fd = ::mkstemp(tmp.data());
  if (fd < 0) write_failed(path, what, "cannot create a file beside it: " + errno_text());
  bool ok = write_all(fd, content);
  std::string why = ok ? "" : errno_text();
  if (::close(fd) != 0 && ok) {
    ok = false;
    why = errno_text();
  }
  // mkstemp makes the file 0600; an output is as readable as any file the user creates
  const mode_t mask = ::umask(0);
  ::umask(mask);
  if (ok && ::chmod(tmp.c_str(), 0666 & ~mask) != 0) {
    ok = false;
    why = errno_text();
  }
  if (ok && ::rename(tmp.c_str(), path.c_str()) != 0) {
    ok = false;
    why = errno_text();
  }
  if (!ok) {
    ::unlink(tmp.c_str());
    write_failed(path, what, why);
  }
}

void refuse_output_over_input(const std::string& output, const std::string& option, const std::vector<std::string>& inputs) {
  struct stat out {};
  if (output.empty() || ::stat(output.c_str(), &out) != 0) return;
  for (const auto& in : inputs) {
    struct stat st {};
    if (::stat(in.c_str(), &st) == 0 && st.st_dev == out.st_dev && st.st_ino == out.st_ino)
      throw InputError(option + " " + output + " is the input " + in + ": refusing to overwrite it (choose another output)");
  }
}

bool same_output_file(const std::string& a, const std::string& b) {
  if (a.empty() || b.empty()) return false;
  const auto resolved = [](const std::string& p) {
    std::error_code ec;
    std::filesystem::path r = std::filesystem::weakly_canonical(std::filesystem::absolute(p, ec), ec);
    return ec ? std::filesystem::absolute(p).lexically_normal() : r;
  };
  return resolved(a) == resolved(b);
}

void refuse_output_dir_that_is_no_directory(const std::string& dir, const std::string& option) {
  struct stat st {};
  if (dir.empty() || ::stat(dir.c_str(), &st) != 0 || S_ISDIR(st.st_mode)) return;
  throw InputError(option + " " + dir + ": exists and is not a directory (the outputs are files written into it): "
                   "choose a directory, or a new name");
}

void refuse_output_file_that_cannot_be_made(const std::string& path, const std::string& option) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode))
    throw InputError(option + " " + path + ": is a directory; give a file name (e.g. " + path + "/rec.csv)");
  const auto slash = path.find_last_of('/');
  if (slash == std::string::npos) return;  // the current directory
  const std::string dir = slash == 0 ? "/" : path.substr(0, slash);
  if (::stat(dir.c_str(), &st) != 0)
    throw InputError(option + " " + path + ": its directory " + dir + " does not exist (" + errno_text() + ")");
  if (!S_ISDIR(st.st_mode)) throw InputError(option + " " + path + ": " + dir + " is not a directory");
  if (::access(dir.c_str(), W_OK) != 0)
    throw InputError(option + " " + path + ": its directory " + dir + " is not writable (" + errno_text() + ")");
}

std::string keep_existing_as_backup(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode) || st.st_size == 0) return "";
  for (int n = 1; n < 10000; ++n) {
    const std::string backup = path + ".~" + std::to_string(n) + "~";
    struct stat b {};
    if (::lstat(backup.c_str(), &b) == 0) continue;
    if (::rename(path.c_str(), backup.c_str()) != 0)
      throw std::runtime_error(path + ": exists and cannot be kept as " + backup + ": " + errno_text());
    return backup;
  }
  throw std::runtime_error(path + ": exists and every backup name " + path + ".~1~ .. .~9999~ is taken");
}

}  // namespace btsm::io
