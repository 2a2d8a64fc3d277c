#pragma once
// Runs the built `btsm` in a temporary directory and captures exit code, stdout and stderr.
#include <string>

namespace btsm::test {

struct CliResult {
  int code = -1;       // exit status; 128 + signal when killed (139 = SIGSEGV, 137 = timeout kill)
  std::string out, err;
};

// A fresh directory, removed with everything in it at the end.
struct ScratchDir {
  ScratchDir();
  ~ScratchDir();
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  std::string file(const std::string& name) const { return path + "/" + name; }
  std::string path;
};

// `CLI ARGS` with HOME=home and XDG_CONFIG_HOME unset (so the key store is the test's own), in
// `workdir` when it is not empty, killed after timeout_s (0: no limit): a hang fails the test instead
// of stopping the suite. stdout and stderr pass through files in `home`. The one way the CLI tests (exit codes,
// link commands, the README workflow) run a `btsm` process.
inline constexpr const char* kCliStdout = "stdout.txt";
inline constexpr const char* kCliStderr = "stderr.txt";
CliResult run_cli(const std::string& cli, const std::string& home, const std::string& args, int timeout_s,
                  const std::string& workdir = "");

// The `btsm` the tests run: $BTSM_TEST_CLI, else the one this build made.
std::string btsm_cli();

// `btsm ARGS` in `dir` (HOME there too), killed after timeout_s.
CliResult run_btsm(const ScratchDir& dir, const std::string& args, int timeout_s = 60);

void write_text(const std::string& path, const std::string& text);
std::string read_text(const std::string& path);  // "" when it cannot be read
bool file_exists(const std::string& path);

}  // namespace btsm::test
