// The seventh hostile-input probe's P3 findings on input files and options: what named a
// symptom (or the wrong cause, or nothing) now names the cause, the file, the line or the option,
// and an option's error comes before any work (exit 2).
#include "cli_run.hpp"
#include "model_fixture.hpp"
#include "refusals.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <string>

namespace btsm::test {
namespace {

bool mentions(const CliResult& r, const std::string& s) { return r.err.find(s) != std::string::npos; }

std::string key_hex() { return std::string(63, '0') + "5\n"; }

// P3-k: the key was read after connecting, so a bad --key-file with no module there was exit 3
// (link) instead of 2. Now it is read and checked first.
TEST(Probe7P3, ABadKeyFileIsExitTwoBeforeAnyModuleIsAsked) {
  ScratchDir d;
  (void)reduced_spindle4_json(d);  // m.bin: a valid blob, so the key file is what is refused
  write_text(d.file("0000de70.key"), "not hex at all\n");
  ::chmod(d.file("0000de70.key").c_str(), 0600);
  write_text(d.file("0000de71.key"), key_hex());
  ::chmod(d.file("0000de71.key").c_str(), 0644);
  write_text(d.file("0000de72.key"), std::string(20, 'a') + "\n");
  ::chmod(d.file("0000de72.key").c_str(), 0600);
  expect_refusals(d, {{"flash-model m.bin --port /nonexistent/tty --key-file 0000de70.key", "0000de70.key"},
                      {"flash-model m.bin --port /nonexistent/tty --key-file 0000de71.key", "has permissions 0644"},
                      {"flash-model m.bin --port /nonexistent/tty --key-file 0000de72.key", "expected 32"},
                      {"flash-model m.bin --port /nonexistent/tty --key-file 0000de73.key", "no key for device 0000de73"}});
  // A good key file gets as far as the link: the missing port is exit 3, as before.
  write_text(d.file("0000de74.key"), key_hex());
  ::chmod(d.file("0000de74.key").c_str(), 0600);
  const CliResult good = run_btsm(d, "flash-model m.bin --port /nonexistent/tty --key-file 0000de74.key");
  EXPECT_EQ(good.code, 3) << good.err;
}

}  // namespace
}  // namespace btsm::test
