#pragma once
// The table-driven check of the CLI tests: each command is refused with `code` and says what.
#include "cli_run.hpp"

#include <gtest/gtest.h>

#include <initializer_list>
#include <string>

namespace btsm::test {

struct Refusal {
  std::string args;  // btsm arguments
  std::string says;  // text stderr must hold (the option, file or reason named)
};

inline void expect_refusals(const ScratchDir& d, std::initializer_list<Refusal> cases, int code = 2, int timeout_s = 60) {
  for (const auto& c : cases) {
    const CliResult r = run_btsm(d, c.args, timeout_s);
    EXPECT_EQ(r.code, code) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << c.args << "\n" << r.err;
  }
}

}  // namespace btsm::test
