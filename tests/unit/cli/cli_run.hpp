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

// `btsm ARGS` in `dir` (HOME there too), killed after timeout_s: a hang fails the test instead of
// stopping the suite. The binary is $BTSM_TEST_CLI, else the one this build made.
CliResult run_btsm(const ScratchDir& dir, const std::string& args, int timeout_s = 60);

void write_text(const std::string& path, const std::string& text);
bool file_exists(const std::string& path);

}  // namespace btsm::test
