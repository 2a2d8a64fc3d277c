#pragma once
// Small helpers shared by the parts of the fit (fit.cpp and the fit_*.cpp files it is made of).
#include <chrono>
#include <limits>
#include <sstream>
#include <string>

namespace btsm::thermal::fitting {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// A number in messages and notes, `prec` significant digits.
inline std::string fmt_double(double v, int prec = 6) {
  std::ostringstream os;
  os.precision(prec);
  os << v;
  return os.str();
}

}  // namespace btsm::thermal::fitting
