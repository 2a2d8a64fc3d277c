// The one number reader of the plant's text specifications (profiles, faults, hidden effects):
// the whole text must be one finite number, so "12x", "", "nan" or "1e999" are refused rather than
// read as a prefix or an infinity. Callers add their own message naming what and where.
#pragma once

#include <cmath>
#include <cstddef>
#include <optional>
#include <stdexcept>
#include <string>

namespace btsm::sim {

inline std::optional<double> strict_number(const std::string& text) {
  if (text.empty()) return std::nullopt;
  std::size_t used = 0;
  double v = 0.0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (used != text.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

}  // namespace btsm::sim
