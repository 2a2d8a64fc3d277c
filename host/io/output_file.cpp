// POSIX calls throughout: rename(2) is the atomic replace, fstat/stat tell a device from a regular
// file, and close(2)'s result is the last chance to see a delayed write error (NFS, quota).
#include "host/io/output_file.hpp"

#include "host/io/input_error.hpp"
#include "host/io/input_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
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

// "a named pipe, not a file to write the plot to"
std::string not_a_file(const std::string& kind, const std::string& what) {
  return kind + ", not a file to write the " + what + " to" + (kind == "a directory" ? ": give a file name in it" : "");
}

// At the write: the place was checked before the work (exit 2), so one that is no regular file now
// was changed during the run; the write fails (exit 1) instead of opening it.
void refuse_special_file(const std::string& path, const std::string& what) {
  if (const std::string kind = special_file_kind(path); !kind.empty()) throw std::runtime_error(path + ": " + not_a_file(kind, what));
}

mode_t current_umask() {
  const mode_t mask = ::umask(0);
  ::umask(mask);
  return mask;
}

// A complete copy of `f.content` in a new file beside `f.path` (the same directory, so the rename
// over it is atomic); returns its name. Removes it and throws on any failure.
std::string write_beside(const OutputFile& f, FileAccess access) {
  std::string tmp = f.path + ".tmp.XXXXXX";
  const int fd = ::mkstemp(tmp.data());
  if (fd < 0) write_failed(f.path, f.what, "cannot create a file beside it: " + errno_text());
  bool ok = write_all(fd, f.content);
  std::string why = ok ? "" : errno_text();
  if (::close(fd) != 0 && ok) {
    ok = false;
    why = errno_text();
  }
  // mkstemp makes the file 0600, right for a key; any other output is as readable as any file the user creates
  if (ok && access == FileAccess::Shared && ::chmod(tmp.c_str(), 0666 & ~current_umask()) != 0) {
    ok = false;
    why = errno_text();
  }
  if (!ok) {
    ::unlink(tmp.c_str());
    write_failed(f.path, f.what, why);
  }
  return tmp;
}

// Why no file can be created in the existing directory `dir` ("" when one can). Tried with a file
// made and removed at once: root passes every permission check, yet a read-only or immutable
// directory, or /proc, takes no file.
std::string no_new_file_in(const std::string& dir) {
  std::string probe = dir + "/.btsm-check.XXXXXX";
  const int fd = ::mkstemp(probe.data());
  if (fd >= 0) {
    ::close(fd);
    ::unlink(probe.c_str());
    return "";
  }
  // /proc answers "No such file or directory" for a directory that is there
  return errno == ENOENT ? "a file system that takes no new files" : errno_text();
}

// The directory a file goes in: "d/a.json" -> "d", "a.json" -> ".", "/a" -> "/".
std::string directory_of(const std::string& path) {
  const auto slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  return slash == 0 ? "/" : path.substr(0, slash);
}

// Why the output file `path` cannot be written ("" when it can).
std::string output_file_problem(const std::string& path, const std::string& what) {
  // Taken as stdout by other tools: here "-" would be a file of that name, /dev/stdout whatever
  // stdout is (a pipe, a terminal), mixed with the command's report.
  if (path == "-" || path == "/dev/stdout")
    return "stdout is no output file here: give a file name (a command's --json prints to stdout)";
  if (const std::string kind = special_file_kind(path); !kind.empty()) return not_a_file(kind, what);
  const std::string dir = directory_of(path);
  struct stat st {};
  if (::stat(dir.c_str(), &st) != 0) return "its directory " + dir + " does not exist (" + errno_text() + ")";
  if (!S_ISDIR(st.st_mode)) return dir + " is not a directory";
  if (const std::string why = no_new_file_in(dir); !why.empty()) return "no file can be created in its directory " + dir + " (" + why + ")";
  return "";
}

// The nearest directory above `dir` that exists, where `dir` would be made ("." for a relative
// path none of whose parts exists); `st` is what stat said of it.
std::string nearest_existing_parent(const std::string& dir, struct stat& st) {
  std::filesystem::path p(dir);
  for (;;) {
    const std::filesystem::path up = p.parent_path();
    const std::string s = up.empty() ? "." : up.string();
    if (::stat(s.c_str(), &st) == 0 || up.empty() || up == p) return s;
    p = up;
  }
}

// Why the output directory `dir` cannot take the outputs ("" when it can).
std::string output_dir_problem(const std::string& dir) {
  struct stat st {};
  if (::stat(dir.c_str(), &st) == 0) {
    if (!S_ISDIR(st.st_mode))
      return "exists and is not a directory (the outputs are files written into it): choose a directory, or a new name";
    if (const std::string why = no_new_file_in(dir); !why.empty()) return "no file can be created in it (" + why + ")";
    return "";
  }
  const std::string parent = nearest_existing_parent(dir, st);
  if (!S_ISDIR(st.st_mode)) return parent + " is not a directory";
  if (const std::string why = no_new_file_in(parent); !why.empty()) return "it cannot be made in " + parent + " (" + why + ")";
  return "";
}

}  // namespace

std::string special_file_kind(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 ? file_type_name(st.st_mode) : "";
}

void write_output_file(const std::string& path, std::string_view content, const std::string& what, FileAccess access) {
  write_output_files({{path, content, what}}, access);
}

void write_output_files(const std::vector<OutputFile>& files, FileAccess access) {
  for (const auto& f : files) refuse_special_file(f.path, f.what);
  std::vector<std::string> written;
  const auto remove_from = [&](std::size_t i) {
    for (; i < written.size(); ++i) ::unlink(written[i].c_str());
  };
  try {
    for (const auto& f : files) written.push_back(write_beside(f, access));
  } catch (...) {
    remove_from(0);
    throw;
  }
  // Renames in one directory do not fail for want of space; one fails only when the directory
  // changed under the command, and the outputs renamed before it stay.
  for (std::size_t i = 0; i < files.size(); ++i)
    if (::rename(written[i].c_str(), files[i].path.c_str()) != 0) {
      const std::string why = errno_text();
      remove_from(i);
      write_failed(files[i].path, files[i].what, why);
    }
}

void write_new_output_file(const std::string& path, std::string_view content, const std::string& what, FileAccess access) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOCTTY,
                        access == FileAccess::Private ? 0600 : 0666);
  if (fd < 0) write_failed(path, what, errno == EEXIST ? "it exists already" : errno_text());
  if (access == FileAccess::Private) (void)::fchmod(fd, 0600);  // whatever the umask said
  bool ok = write_all(fd, content);
  std::string why = ok ? "" : errno_text();
  if (::close(fd) != 0 && ok) {
    ok = false;
    why = errno_text();
  }
  if (!ok) {
    ::unlink(path.c_str());
    write_failed(path, what, why);
  }
}

std::FILE* open_output_stream(const std::string& path, const std::string& what, bool append) {
  refuse_special_file(path, what);
  // O_NONBLOCK: a named pipe put there since the check fails the open (ENXIO) instead of waiting
  // for a reader for ever; on the regular file it must be, the flag changes nothing.
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC | O_NOCTTY | O_NONBLOCK | (append ? O_APPEND : 0), 0666);
  if (fd < 0 && errno == ENXIO) throw std::runtime_error(path + ": " + not_a_file("a named pipe", what));
  if (fd < 0) write_failed(path, what, errno_text());
  struct stat st {};
  std::string why;
  if (::fstat(fd, &st) != 0) why = errno_text();
  else if (!S_ISREG(st.st_mode)) why = not_a_file(file_type_name(st.st_mode), what);
  else if (!append && ::ftruncate(fd, 0) != 0) why = errno_text();  // emptied only once known to be a regular file
  std::FILE* f = why.empty() ? ::fdopen(fd, append ? "a" : "w") : nullptr;
  if (f == nullptr) {
    if (why.empty()) why = errno_text();
    ::close(fd);
    write_failed(path, what, why);
  }
  return f;
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

void refuse_output_file_that_cannot_be_made(const std::string& path, const std::string& option, const std::string& what) {
  if (path.empty()) return;  // the option not given
  if (const std::string why = output_file_problem(path, what); !why.empty()) throw InputError(option + " " + path + ": " + why);
}

void refuse_output_dir_that_cannot_be_made(const std::string& dir, const std::string& option, const std::vector<OutputName>& files) {
  if (dir.empty()) return;  // the option not given
  if (const std::string why = output_dir_problem(dir); !why.empty()) throw InputError(option + " " + dir + ": " + why);
  for (const auto& f : files) {
    const std::string path = (std::filesystem::path(dir) / f.name).string();
    if (const std::string kind = special_file_kind(path); !kind.empty())
      throw InputError(option + " " + dir + ": " + path + " is " + not_a_file(kind, f.what));
  }
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
