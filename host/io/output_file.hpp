#pragma once
// Writing the tool's output files without ever losing what was there: an output is written in
// full beside its destination and renamed over it only when complete, every write is checked
// (a full disk must not leave a truncated file reported as written), and an output that names one
// of the command's own inputs is refused before anything is computed.
//
// An output is a regular file or a path that does not exist yet, nothing else: a named pipe, a
// socket, a device or a directory is refused, before the work by the refuse_* checks (exit 2) and
// again by every writer, which never opens one (a named pipe no program reads blocked the write for
// ever, after all the work). stdout is not an output file: `--json` prints to it.
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

namespace btsm::io {

// What `path` is when it exists and is no regular file, symbolic links followed: "a directory",
// "a named pipe", "a socket", "a character device", "a block device"; "" for a regular file or a
// path that does not exist.
std::string special_file_kind(const std::string& path);

// Shared: the mode a new file of the user's gets (0666 less the umask). Private: 0600 whatever the
// umask, for a file holding a device key.
enum class FileAccess { Shared, Private };

// Writes `content` to `path` through a temporary file in the same directory, flushed, closed and
// renamed over `path`, so `path` holds either its old content or the complete new one. Throws
// std::runtime_error naming `what` and `path` on any failure (no regular file there, open, write,
// close, rename); the temporary file is removed then.
void write_output_file(const std::string& path, std::string_view content, const std::string& what,
                       FileAccess access = FileAccess::Shared);

// Writes `content` to `path`, which must not exist: created with O_EXCL, so two commands at once
// cannot both create it and nothing that stands there (a named pipe) is ever opened. Throws
// std::runtime_error on any failure ("it exists already" when it does); a file it created and could
// not fill is removed. For an output never replaced unless told (a device key).
void write_new_output_file(const std::string& path, std::string_view content, const std::string& what,
                           FileAccess access = FileAccess::Shared);

struct OutputFile {
  std::string path;
  std::string_view content;
  std::string what;
};

// Writes outputs that belong together (reduce's JSON and its blob) as one: every one is written
// to its temporary file first, and only when all of them are complete are they renamed over their
// destinations. A failure before that leaves every destination as it was.
void write_output_files(const std::vector<OutputFile>& files, FileAccess access = FileAccess::Shared);

// For an output written as the command goes (a recording, row by row): opens `path` to write from
// its first byte, or at its end with `append`, without waiting (a named pipe put there is refused,
// not waited on). Throws std::runtime_error naming `what` and `path` when it is no regular file or
// cannot be created. The caller fcloses the stream.
std::FILE* open_output_stream(const std::string& path, const std::string& what, bool append = false);

// Throws InputError when `output` (given with option `option`, "--out") is the same file as one of
// `inputs` (same device and inode: "./a.csv", "a.csv" and hard links all count). Paths that do not
// exist yet cannot be an input.
void refuse_output_over_input(const std::string& output, const std::string& option, const std::vector<std::string>& inputs);

// True when two output paths name one file, whether or not it exists yet: compared after
// resolving ".", "..", symlinks and the current directory ("./out/../out/a.json" = "out/a.json").
bool same_output_file(const std::string& a, const std::string& b);

// Throws InputError "OPTION PATH: why" when `path` (an output file holding the `what`, "model
// JSON") cannot be written: it is "-" (no stdout here), exists and is no regular file, or its
// directory is missing, no directory or takes no new file (tried, not judged from the permission
// bits, which root passes: a read-only or immutable directory, /proc). For every output file,
// before the work, which may last minutes and found it only at the end.
void refuse_output_file_that_cannot_be_made(const std::string& path, const std::string& option, const std::string& what);

// A file a command writes into its output directory, and what it holds ("plot").
struct OutputName {
  std::string name, what;
};

// Throws InputError when `dir` (an output directory given with `option`, "--report") cannot take
// the outputs: it exists and is not a directory, it takes no new file, or (not there yet) the
// directory it would be made in takes none; or one of `files` exists in it and is no regular file.
// Before the work, as refuse_output_file_that_cannot_be_made.
void refuse_output_dir_that_cannot_be_made(const std::string& dir, const std::string& option,
                                           const std::vector<OutputName>& files = {});

// For an output that is rewritten from its first byte as the command goes (a recording): when
// `path` is a non-empty regular file, renames it to the first free "<path>.~N~" (N = 1, 2, ...) and
// returns that name; otherwise returns "". Throws std::runtime_error when the rename fails.
std::string keep_existing_as_backup(const std::string& path);

}  // namespace btsm::io
