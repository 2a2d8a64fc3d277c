#pragma once
// Text from a user's file or command line, as the tool checks it and as it shows it again. A name,
// a cell or a path echoed raw into a message can rewrite the terminal (ESC [ 2 J clears it, a CR
// or newline forges a line of output) and, when it is not UTF-8, garble it; every message built
// from such text shows it through printable().
#include <cstddef>
#include <string>
#include <string_view>

namespace btsm::io {

// The offset of the first byte that does not belong to well-formed UTF-8 (a Latin-1 or CP1252
// byte such as 0xB0 for '°', a cut-off sequence, an overlong form, a surrogate), or npos.
std::size_t invalid_utf8_at(std::string_view text);

// "" for UTF-8 text, else "not valid UTF-8 at byte 17 (0xB0, line 2)" for a reader's message:
// which 8-bit encoding such a byte comes from cannot be told, so the byte is named, not a guess.
std::string utf8_problem(std::string_view text);

// `text` with what a terminal would act on made visible: \n, \r, \t, other control characters
// and DEL as \xNN (ESC is \x1b), the C1 controls U+0080..U+009F as \u0080..\u009f, characters
// shown as nothing or as a plain space or that reorder the line (BOM, no-break and other spaces,
// zero-width space and joiners, direction marks and overrides, tags, ...) as \u{feff}, and bytes
// that are not UTF-8 as \xNN. Everything else, backslashes included, is kept as it is.
std::string printable(std::string_view text);

}  // namespace btsm::io
