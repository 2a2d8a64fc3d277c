// Network JSON reader: text -> depth-capped JSON -> Network. Any input parses or throws
// std::invalid_argument (io::InputError for text that is not JSON). A network that parses is
// valid, within the reader's size limits, and survives its own writer: network_to_json() reads
// back into the same JSON (the codec pair is checked, not only the reader).
#include "fuzz_check.hpp"
#include "host/io/json_input.hpp"
#include "host/thermal/network.hpp"

#include <stdexcept>
#include <string_view>

using namespace btsm;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  thermal::Network net;
  try {
    net = thermal::network_from_json(io::parse_json_text(text, "fuzz.json"), "fuzz.json");
  } catch (const std::invalid_argument&) {
    return 0;
  }
  net.validate();  // must not throw: the reader validated it
  FUZZ_CHECK(net.nodes.size() <= thermal::kMaxNetworkNodes && net.params.size() <= thermal::kMaxNetworkParameters);
  const nlohmann::json once = thermal::network_to_json(net);
  const thermal::Network again = thermal::network_from_json(once, "fuzz.json (written back)");
  FUZZ_CHECK(thermal::network_to_json(again) == once);
  return 0;
}
