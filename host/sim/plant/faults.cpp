#include "host/sim/plant/faults.hpp"

#include "host/sim/plant/profile.hpp"
#include "host/io/decimal_number.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace btsm::sim {
namespace {

double number(const std::string& t, const std::string& what) {
  const auto v = io::decimal_number(t);
  if (!v) throw std::invalid_argument(what + ": '" + t + "' is not a number");
  return *v;
}

int channel(const std::string& arg, const std::string& spec) {
  if (arg.size() != 3 || arg.compare(0, 2, "ch") != 0 || arg[2] < '1' || arg[2] > '5')
    throw std::invalid_argument("fault '" + spec + "': channel must be ch1..ch5, got '" + arg + "'");
  return arg[2] - '0';
}

}  // namespace

FaultSpec parse_fault(const std::string& spec) {
  const auto at = spec.find('@');
  if (at == std::string::npos)
    throw std::invalid_argument("fault '" + spec + "': missing @START (e.g. open:ch2@3600)");
  const std::string head = spec.substr(0, at), when = spec.substr(at + 1);
  const auto colon = head.find(':');
  const std::string kind = head.substr(0, colon);
  const std::string arg = colon == std::string::npos ? std::string() : head.substr(colon + 1);

  FaultSpec f;
  if (kind == "open" || kind == "openchain" || kind == "short") {
    f.kind = kind == "open" ? FaultKind::OpenProbe
                            : (kind == "short" ? FaultKind::ShortedProbe : FaultKind::OpenChain);
    f.channel = channel(arg, spec);
  } else if (kind == "noadc" || kind == "noref") {
    if (!arg.empty()) throw std::invalid_argument("fault '" + spec + "': " + kind + " takes no argument");
    f.kind = kind == "noadc" ? FaultKind::MissingAdc : FaultKind::LostReference;
  } else if (kind == "bearing") {
    f.kind = FaultKind::BearingHeat;
    std::string w = arg;
    const auto place = w.find(':');
    if (place != std::string::npos) {
      const std::string where = w.substr(0, place);
      if (where == "front") f.place = BearingPlace::Front;
      else if (where != "rear")
        throw std::invalid_argument("fault '" + spec + "': bearing place must be rear or front, got '" + where + "'");
      w = w.substr(place + 1);
    }
    if (!w.empty() && (w.back() == 'W' || w.back() == 'w')) w.pop_back();
    f.heat_w = number(w, "fault '" + spec + "' heat (W)");
    if (f.heat_w < 0.0 || f.heat_w > 1000.0)
      throw std::invalid_argument("fault '" + spec + "': heat must be within 0..1000 W");
  } else {
    throw std::invalid_argument("fault '" + spec + "': unknown kind '" + kind +
                                "' (open, openchain, short, noadc, noref, bearing)");
  }
  // START[-END]; a leading '-' would be a negative time, which is rejected by the parser.
  const auto dash = when.find('-', 1);
  f.start_s = parse_duration_s(when.substr(0, dash), "fault '" + spec + "' start");
  if (dash != std::string::npos) {
    f.end_s = parse_duration_s(when.substr(dash + 1), "fault '" + spec + "' end");
    if (f.end_s <= f.start_s) throw std::invalid_argument("fault '" + spec + "': end must be after start");
  }
  return f;
}

std::string to_string(const FaultSpec& f) {
  std::ostringstream os;
  switch (f.kind) {
    case FaultKind::OpenProbe: os << "open:ch" << f.channel; break;
    case FaultKind::OpenChain: os << "openchain:ch" << f.channel; break;
    case FaultKind::ShortedProbe: os << "short:ch" << f.channel; break;
    case FaultKind::MissingAdc: os << "noadc"; break;
    case FaultKind::LostReference: os << "noref"; break;
    case FaultKind::BearingHeat:
      os << "bearing:" << (f.place == BearingPlace::Front ? "front:" : "") << f.heat_w << "W";
      break;
  }
  os << '@' << f.start_s;
  if (std::isfinite(f.end_s)) os << '-' << f.end_s;
  return os.str();
}

}  // namespace btsm::sim
