#include "cli_run.hpp"

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace btsm::test {

std::string read_text(const std::string& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

ScratchDir::ScratchDir() {
  std::string tmpl = (std::filesystem::temp_directory_path() / "btsm-cli-XXXXXX").string();
  if (::mkdtemp(tmpl.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
  path = tmpl;
}

ScratchDir::~ScratchDir() {
  std::error_code ec;
  std::filesystem::remove_all(path, ec);
}

CliResult run_cli(const std::string& cli, const std::string& home, const std::string& args, int timeout_s,
                  const std::string& workdir) {
  const std::string out = home + "/" + kCliStdout, err = home + "/" + kCliStderr;
  const std::string cd = workdir.empty() ? "" : "cd '" + workdir + "' && ";
  // `timeout` runs its command in a process group of its own, which the link tests that stop the
  // module under a running `btsm` do not want: 0 runs the command as it is.
  // BTSM_TEST_TIMEOUT_SCALE (the asan test preset: 20) stretches every limit for a build that runs
  // many times slower; the limits are there to stop a hang, not to time anything.
  const char* scale_text = std::getenv("BTSM_TEST_TIMEOUT_SCALE");
  const int scale = scale_text != nullptr && std::atoi(scale_text) > 1 ? std::atoi(scale_text) : 1;
  const std::string limit = timeout_s > 0 ? "timeout -s KILL " + std::to_string(timeout_s * scale) + " " : "";
  const std::string cmd = cd + "env -u XDG_CONFIG_HOME HOME='" + home + "' " + limit + cli + " " + args + " >'" + out + "' 2>'" +
                          err + "' </dev/null";
  const int st = std::system(cmd.c_str());
  CliResult r;
  r.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  r.out = read_text(out);
  r.err = read_text(err);
  return r;
}

std::string btsm_cli() {
  const char* override_cli = std::getenv("BTSM_TEST_CLI");
  return override_cli != nullptr && override_cli[0] != '\0' ? override_cli : BTSM_CLI;
}

CliResult run_btsm(const ScratchDir& dir, const std::string& args, int timeout_s) {
  return run_cli(btsm_cli(), dir.path, args, timeout_s, dir.path);
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
  if (!f) throw std::runtime_error("cannot write " + path);
}

bool file_exists(const std::string& path) { return std::filesystem::exists(path); }

}  // namespace btsm::test
