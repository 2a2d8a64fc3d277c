#include "cli_run.hpp"

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace btsm::test {

namespace {
std::string slurp(const std::string& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
}  // namespace

ScratchDir::ScratchDir() {
  std::string tmpl = (std::filesystem::temp_directory_path() / "btsm-cli-XXXXXX").string();
  if (::mkdtemp(tmpl.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
  path = tmpl;
}

ScratchDir::~ScratchDir() {
  std::error_code ec;
  std::filesystem::remove_all(path, ec);
}

CliResult run_btsm(const ScratchDir& dir, const std::string& args, int timeout_s) {
  const char* override_cli = std::getenv("BTSM_TEST_CLI");
  const std::string cli = override_cli != nullptr && override_cli[0] != '\0' ? override_cli : BTSM_CLI;
  const std::string out = dir.file(".stdout"), err = dir.file(".stderr");
  const std::string cmd = "cd '" + dir.path + "' && env -u XDG_CONFIG_HOME HOME='" + dir.path + "' timeout -s KILL " +
                          std::to_string(timeout_s) + " " + cli + " " + args + " >'" + out + "' 2>'" + err + "' </dev/null";
  const int st = std::system(cmd.c_str());
  CliResult r;
  r.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
  if (!f) throw std::runtime_error("cannot write " + path);
}

bool file_exists(const std::string& path) { return std::filesystem::exists(path); }

}  // namespace btsm::test
