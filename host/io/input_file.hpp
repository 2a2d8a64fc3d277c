#pragma once
// Size-capped reads of input files. Every file the tool takes is read through here, so a device
// (/dev/zero, /dev/urandom), a pipe that never ends or a file far beyond any sensible size fails
// fast with the limit in the message instead of growing memory without bound.
#include <sys/stat.h>

#include <cstddef>
#include <string>

namespace btsm::io {

constexpr std::size_t kKiB = 1024;
constexpr std::size_t kMiB = 1024 * kKiB;

// Text files may not contain NUL bytes: a binary file or a device given by mistake is refused at
// its first NUL, long before the size cap. Text is UTF-8.
enum class FileKind { Text, Binary };

// "16 MiB", "4 KiB", "464 bytes".
std::string size_text(std::size_t bytes);

// What a file of `mode` is when it is no regular file: "a directory", "a named pipe", "a socket",
// "a character device", "a block device", "a symbolic link"; "" for a regular file.
std::string file_type_name(mode_t mode);

// Why `path` could not be opened or examined, from the errno of open(2)/stat(2): the cause in
// words, not strerror's alone ("a symbolic-link loop (ELOOP)", "a symbolic link to 'x', which does
// not exist", "permission denied (EACCES): ..."). A symbolic-link loop read as "File does not exist".
std::string open_failure_reason(const std::string& path, int err);

// An input opened for reading without waiting: opening a named pipe no program writes to waited
// for a writer for ever (so opened, it reads as empty at once; reads block again once it is open).
// Throws InputError naming `path` and `what` when it cannot be opened or is a directory.
// `extra_flags` go to open(2): O_NOFOLLOW for a key file. For a reader that checks what the open
// file is (a key file: a regular file, mode 0600) before it reads; the others use read_input_file.
class InputFile {
 public:
  InputFile(const std::string& path, const std::string& what, int extra_flags = 0);
  ~InputFile();
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;
  const struct stat& status() const { return st_; }  // of the open file: no window between a check and the read
  // The whole content, as read_input_file below.
  std::string read_all(std::size_t max_bytes, FileKind kind);

 private:
  std::string path_, what_;
  int fd_ = -1;
  struct stat st_ {};
};

// Reads the whole file. Throws InputError naming `path` and `what` ("network JSON", "recording")
// when it cannot be opened, is a directory, holds more than max_bytes (regular files are refused
// from their size before reading), or, for Text, is UTF-16 or UTF-32, contains a NUL byte or is
// not valid UTF-8 (a UTF-8 byte order mark is UTF-8 and passes).
std::string read_input_file(const std::string& path, std::size_t max_bytes, const std::string& what,
                            FileKind kind = FileKind::Text);

}  // namespace btsm::io
