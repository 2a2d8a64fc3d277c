#pragma once
// Writing the tool's output files without ever losing what was there: an output is written in
// full beside its destination and renamed over it only when complete, every write is checked
// (a full disk must not leave a truncated file reported as written), and an output that names one
// of the command's own inputs is refused before anything is computed.
#include <string>
#include <string_view>
#include <vector>

namespace btsm::io {

// Writes `content` to `path`. A regular file (or a new path) is written to a temporary file in the
// same directory, flushed, closed and renamed over `path`, so `path` holds either its old content
// or the complete new one. A device, FIFO or socket (/dev/stdout, /dev/full) is written in place.
// Throws std::runtime_error naming `what` and `path` on any failure (open, write, close, rename);
// the temporary file is removed then.
void write_output_file(const std::string& path, std::string_view content, const std::string& what);

// Throws InputError when `output` (given with option `option`, "--out") is the same file as one of
// `inputs` (same device and inode: "./a.csv", "a.csv" and hard links all count). Paths that do not
// exist yet cannot be an input.
void refuse_output_over_input(const std::string& output, const std::string& option, const std::vector<std::string>& inputs);

// True when two output paths name one file, whether or not it exists yet: compared after
// resolving ".", "..", symlinks and the current directory ("./out/../out/a.json" = "out/a.json").
bool same_output_file(const std::string& a, const std::string& b);

// Throws InputError when `dir` (an output directory given with `option`, "--report") exists and
// is not a directory: checked before the work, which would otherwise run to the end and fail there.
void refuse_output_dir_that_is_no_directory(const std::string& dir, const std::string& option);

// Throws InputError when `path` (an output file given with `option`) is a directory or its directory
// is missing, no directory or not writable: for a command that would first connect to a module or
// run for long and only then find it cannot write.
void refuse_output_file_that_cannot_be_made(const std::string& path, const std::string& option);

// For an output that is rewritten from its first byte as the command goes (a recording): when
// `path` is a non-empty regular file, renames it to the first free "<path>.~N~" (N = 1, 2, ...) and
// returns that name; otherwise returns "". Throws std::runtime_error when the rename fails.
std::string keep_existing_as_backup(const std::string& path);

}  // namespace btsm::io
