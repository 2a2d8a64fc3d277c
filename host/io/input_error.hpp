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

}  // namespace btsm::io
