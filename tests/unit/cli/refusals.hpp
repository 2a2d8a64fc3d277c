#pragma once
// The table-driven check of the CLI tests: each command is refused with `code` and says what.
#include "cli_run.hpp"
#include "model_fixture.hpp"

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

// `btsm reduce` of the spindle4 model (model_fixture.hpp) written to d/model.json, as r.json (and
// m.bin): the reduced-model JSON the flash-model tests edit. Fails the test when reduce does.
inline nlohmann::json reduced_spindle4_json(const ScratchDir& d) {
  write_text(d.file("model.json"), spindle4_model_json());
  const CliResult r = run_btsm(d, "reduce model.json --speeds 4000,6000 --force --out r.json --blob m.bin", 300);
  EXPECT_EQ(r.code, 0) << r.err;
  return nlohmann::json::parse(read_text(d.file("r.json")));
}

}  // namespace btsm::test
