// The one number reader for numbers a person types (CLI arguments, list entries, speed and
// ambient profiles, fault and effect specifications): one finite decimal number and nothing else,
// blanks around it allowed. strtod alone also reads hex ("0x3e8" = 1000), "inf", "nan" and a
// prefix ("12x" = 12); a value beyond a double's range is refused rather than read as infinity or 0.
// Callers name what and where in their own message.
#pragma once

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <string>
#include <string_view>

namespace btsm::io {

// What a number too small for a double (1e-400) is: refused (the default), or the nearest double,
// 0 or subnormal, as a recording's cell reads it (host/thermal/recording.cpp) -- `btsm rtd` takes it
// so, since its values are the same kind of reading ("rtd r2t 1e-400" was "not a number").
enum class TinyNumber { Refused, ReadAsNearest };

inline std::optional<double> decimal_number(std::string_view text, TinyNumber tiny = TinyNumber::Refused) {
  const auto first = text.find_first_not_of(" \t");
  if (first == std::string_view::npos) return std::nullopt;
  const auto last = text.find_last_not_of(" \t");
  const std::string t(text.substr(first, last - first + 1));
  if (t.find_first_not_of("0123456789+-.eE") != std::string::npos) return std::nullopt;
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  const bool underflow = errno == ERANGE && std::abs(v) <= 1.0;  // strtod gives 0 or a subnormal
  if ((errno == ERANGE && !(underflow && tiny == TinyNumber::ReadAsNearest)) || end != t.c_str() + t.size() || !std::isfinite(v))
    return std::nullopt;
  return v;
}

}  // namespace btsm::io
