#pragma once
// The error of every reader of a user's file: the file is missing, unreadable, too large, or its
// content is malformed. It is a std::invalid_argument, which the CLI reports with exit code 2
// ("bad arguments or unreadable input"), never 1 ("the operation ran and failed").
#include <stdexcept>
#include <string>

namespace btsm::io {

struct InputError : std::invalid_argument {
  explicit InputError(const std::string& what) : std::invalid_argument(what) {}
};

// A name read from a file with a control character (an ESC, a newline) would be printed raw into
// the terminal and every table naming it: readers refuse such names.
inline bool has_control_char(const std::string& s) {
  for (const char c : s)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return true;
  return false;
}

}  // namespace btsm::io
