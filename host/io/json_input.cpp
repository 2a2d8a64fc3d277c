// Depth scan + parse. The scan follows JSON's string syntax (quotes and backslash escapes), so
// brackets inside strings do not count; anything else malformed is left to the parser.
#include "host/io/json_input.hpp"

#include "host/io/input_error.hpp"
#include "host/io/input_file.hpp"
#include "host/io/utf8_text.hpp"

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <set>
#include <vector>

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

// Notes the first key given twice in one object, as a path ("network.parameters[].name"). JSON
// leaves duplicates undefined and the parser keeps the last, so {"name":"one","name":"two"} would
// silently be "two" -- whichever a person editing the file meant.
class DuplicateKeyWatch {
 public:
  bool operator()(int, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using E = nlohmann::json::parse_event_t;
    switch (event) {
      case E::object_start: frames_.push_back({{}, "", true}); break;
      case E::array_start: frames_.push_back({{}, "", false}); break;
      case E::object_end:
      case E::array_end:
        if (!frames_.empty()) frames_.pop_back();
        break;
      case E::key: {
        if (frames_.empty()) break;
        const std::string key = parsed.get<std::string>();
        if (!frames_.back().keys.insert(key).second && first_.empty()) first_ = path_to(key);
        frames_.back().last_key = key;
        break;
      }
      default: break;
    }
    return true;
  }
  const std::string& first_duplicate() const { return first_; }
  // The path of the value being parsed ("parameters[].max"; "" at the top level): the parser
  // reports the key before it reads the value, so after a failure this is where it failed.
  std::string current_path() const {
    std::string path;
    for (const Frame& f : frames_)
      path += f.object ? (f.last_key.empty() ? "" : (path.empty() ? "" : ".") + f.last_key) : "[]";
    return path;
  }

 private:
  struct Frame {
    std::set<std::string> keys;
    std::string last_key;
    bool object;
  };
  std::string path_to(const std::string& key) const {
    std::string path;
    for (std::size_t i = 0; i + 1 < frames_.size(); ++i)
      path += frames_[i].object ? (path.empty() ? "" : ".") + frames_[i].last_key : "[]";
    return path + (path.empty() ? "" : ".") + key;
  }
  std::vector<Frame> frames_;
  std::string first_;
};

// "line 30, column 11" of the first number in `text` (outside strings) beyond double range, as
// the parser's own messages place an error; "" when none is found. The parser's out_of_range
// error for 1e400 names the number only ("number overflow parsing '1e400'"), not where it is.
std::string overflowing_number_place(std::string_view text, std::string* number) {
  bool in_string = false, escaped = false;
  std::size_t line = 1, line_start = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '\n') { ++line; line_start = i + 1; }
    if (in_string) {
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') in_string = false;
      continue;
    }
    if (c == '"') { in_string = true; continue; }
    if (c != '-' && (c < '0' || c > '9')) continue;
    std::size_t end = i;
    while (end < text.size() && std::strchr("0123456789+-.eE", text[end]) != nullptr) ++end;
    const std::string token(text.substr(i, end - i));
    const double v = std::strtod(token.c_str(), nullptr);
    if (std::isinf(v)) {
      *number = token;
      return "line " + std::to_string(line) + ", column " + std::to_string(i - line_start + 1);
    }
    i = end - 1;
  }
  return "";
}

}  // namespace

nlohmann::json parse_json_text(std::string_view text, const std::string& source, int max_depth) {
  // JSON is UTF-8 (RFC 8259); the parser's own word for a Latin-1 byte quotes it raw. Text from
  // read_input_file is checked already; flash-model reads its file as bytes (it may be a blob).
  if (const std::string problem = utf8_problem(text); !problem.empty())
    throw InputError(source + ": " + problem + ", expected JSON in UTF-8: save it as UTF-8");
  check_depth(text, source, max_depth);
  DuplicateKeyWatch watch;
  nlohmann::json value;
  try {
    value = nlohmann::json::parse(text.begin(), text.end(), std::ref(watch));
  } catch (const nlohmann::json::out_of_range& e) {
    // a number beyond double range (1e400): placed as a parse error is, with the key it is the value of
    std::string number;
    const std::string place = overflowing_number_place(text, &number);
    if (place.empty()) throw InputError(source + ": not valid JSON: " + without_json_exception_ids(e.what()));
    const std::string path = watch.current_path();
    throw InputError(source + ": not valid JSON: at " + place + (path.empty() ? "" : " (" + printable(path) + ")") + ": number '" +
                     printable(number.size() > 40 ? number.substr(0, 40) + "..." : number) +
                     "' is beyond the range of a number (+-1.8e308)");
  } catch (const nlohmann::json::exception& e) {
    // parse_error: its message places the error at a line and column already
    throw InputError(source + ": not valid JSON: " + without_json_exception_ids(e.what()));
  }
  if (!watch.first_duplicate().empty())
    throw InputError(source + ": key " + json_excerpt(watch.first_duplicate(), 120) +
                     " is given twice in one object; JSON keeps only one of them silently: delete the one you did not mean");
  return value;
}

nlohmann::json read_json_file(const std::string& path, std::size_t max_bytes, const std::string& what) {
  return parse_json_text(read_input_file(path, max_bytes, what), path);
}

std::string without_json_exception_ids(std::string_view text) {
  static constexpr std::string_view kId = "[json.exception.";
  std::string out;
  std::size_t at = 0;
  for (std::size_t id; (id = text.find(kId, at)) != std::string_view::npos;) {
    const std::size_t close = text.find(']', id);
    if (close == std::string_view::npos) break;
    out.append(text.substr(at, id - at));
    at = close + 1;
    if (at < text.size() && text[at] == ' ') ++at;
  }
  return out.append(text.substr(at));
}

std::string json_excerpt(const nlohmann::json& value, std::size_t max_chars) {
  std::string s = value.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  if (s.size() > max_chars) s = s.substr(0, max_chars) + "...";
  return s;
}

}  // namespace btsm::io
