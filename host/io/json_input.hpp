#pragma once
// JSON input with a nesting cap. nlohmann's parser itself is iterative, but much of what follows
// a parse is recursive (dump() in an error message, comparisons, copies): a file of 70,000
// nested '[' used to overflow the stack. The text is scanned for its nesting depth first, so a
// document deeper than the cap is refused before any value is built.
#include <nlohmann/json.hpp>

#include <cstddef>
#include <string>
#include <string_view>

namespace btsm::io {

// Deeper than any BTSM document needs (a network JSON nests 5 levels).
constexpr int kMaxJsonDepth = 64;

// Parses `text`; throws InputError naming `source`: nested deeper than max_depth (with the byte
// offset), not valid JSON, a number beyond double range, or a key given twice in one object
// (named by its path, e.g. "network.parameters[].name").
nlohmann::json parse_json_text(std::string_view text, const std::string& source, int max_depth = kMaxJsonDepth);

// Reads (read_input_file, Text) and parses a JSON file of at most max_bytes.
nlohmann::json read_json_file(const std::string& path, std::size_t max_bytes, const std::string& what);

// `text` without the JSON library's exception ids ("[json.exception.type_error.302] type must be
// string, but is number" -> "type must be string, but is number"): the id means nothing to a user
// and hides the human part at the start of the message. Everything else is kept.
std::string without_json_exception_ids(std::string_view text);

// A value for an error message: its compact dump, cut to max_chars with "..." (a file's bad field
// may be megabytes long).
std::string json_excerpt(const nlohmann::json& value, std::size_t max_chars = 80);

}  // namespace btsm::io
