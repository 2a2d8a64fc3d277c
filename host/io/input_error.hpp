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

// A name that becomes a CSV column (a recording's header, heat's NODE_W) or an entry of a list or
// spec the tool reads back (--nodes a,b, --channels, --column NODE=COLUMN, # channel_roles:
// COLUMN=ROLE) cannot hold ',' or '=', nor blanks at its ends, which CSV cells lose: such a name
// was accepted, then could never be named again. "" when `s` is fine, else what is wrong with it.
inline std::string name_problem(const std::string& s) {
  if (has_control_char(s)) return "contains a control character";
  if (s.find(',') != std::string::npos)
    return "contains ',' (it would split the name in a CSV header and in lists such as --nodes)";
  if (s.find('=') != std::string::npos)
    return "contains '=' (it would split the name in NAME=VALUE specs: --column NODE=COLUMN, # channel_roles)";
  if (!s.empty() && (s.front() == ' ' || s.back() == ' '))
    return "starts or ends with a blank (a CSV header or a list entry loses it)";
  return "";
}

}  // namespace btsm::io
