#pragma once
// Size-capped reads of input files. Every file the tool takes is read through here, so a device
// (/dev/zero, /dev/urandom), a pipe that never ends or a file far beyond any sensible size fails
// fast with the limit in the message instead of growing memory without bound.
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

// Reads the whole file. Throws InputError naming `path` and `what` ("network JSON", "recording")
// when it cannot be opened, is a directory, holds more than max_bytes (regular files are refused
// from their size before reading), or, for Text, is UTF-16 or UTF-32, contains a NUL byte or is
// not valid UTF-8 (a UTF-8 byte order mark is UTF-8 and passes).
std::string read_input_file(const std::string& path, std::size_t max_bytes, const std::string& what,
                            FileKind kind = FileKind::Text);

}  // namespace btsm::io
