// Fitted-model JSON reader. Any input parses or throws std::invalid_argument. A model that loads
// has finite values inside its network's bounds and passes model_problems() -- the promise
// validate, reduce, heat and residual rely on.
#include "fuzz_check.hpp"
#include "host/io/json_input.hpp"
#include "host/thermal/model_file.hpp"

#include <stdexcept>
#include <string_view>

using namespace btsm;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  thermal::FittedModel m;
  try {
    m = thermal::model_from_json(io::parse_json_text(text, "fuzz.json"), "fuzz.json");
  } catch (const std::invalid_argument&) {
    return 0;
  }
  FUZZ_CHECK(m.params.size() == m.network.param_count());
  for (int i = 0; i < m.network.param_count(); ++i) {
    const auto& p = m.network.params[static_cast<size_t>(i)];
    FUZZ_CHECK(std::isfinite(m.params[i]) && m.params[i] >= p.min && m.params[i] <= p.max);
  }
  FUZZ_CHECK(thermal::model_problems(m.network, m.params).empty());
  return 0;
}
