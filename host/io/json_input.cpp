// Depth scan + parse. The scan follows JSON's string syntax (quotes and backslash escapes), so
// brackets inside strings do not count; anything else malformed is left to the parser.
#include "host/io/json_input.hpp"

#include "host/io/input_error.hpp"
#include "host/io/input_file.hpp"

namespace btsm::io {
namespace {

void check_depth(std::string_view text, const std::string& source, int max_depth) {
  int depth = 0;
  bool in_string = false, escaped = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') in_string = false;
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > max_depth)
        throw InputError(source + ": JSON nested deeper than " + std::to_string(max_depth) + " levels (at byte " +
                         std::to_string(i) + ")");
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
}

}  // namespace

nlohmann::json parse_json_text(std::string_view text, const std::string& source, int max_depth) {
  check_depth(text, source, max_depth);
  try {
    return nlohmann::json::parse(text.begin(), text.end());
  } catch (const nlohmann::json::exception& e) {
    // parse_error, and out_of_range for a number beyond double range (1e400)
    throw InputError(source + ": not valid JSON: " + e.what());
  }
}

nlohmann::json read_json_file(const std::string& path, std::size_t max_bytes, const std::string& what) {
  return parse_json_text(read_input_file(path, max_bytes, what), path);
}

std::string json_excerpt(const nlohmann::json& value, std::size_t max_chars) {
  std::string s = value.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  if (s.size() > max_chars) s = s.substr(0, max_chars) + "...";
  return s;
}

}  // namespace btsm::io
