// btsm — host tool of the Bluetooth Temperature Sensor Module.
#include "cli_support.hpp"
#include "commands.hpp"
#include "host/io/input_error.hpp"
#include "host/io/json_input.hpp"
#include "host/io/utf8_text.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cstdio>
#include <exception>
#include <iostream>

int main(int argc, char** argv) {
  CLI::App app{"btsm — host tool of the Bluetooth Temperature Sensor Module (spindle thermal monitoring)"};
  app.set_version_flag("--version", std::string("btsm ") + BTSM_VERSION);
  app.require_subcommand(1);
  app.fallthrough();
  // The parser's errors quote what was typed ("--effects: The value X is not allowed"): a value
  // holding an ESC sequence must not reach the terminal as one. Before the registrations, which
  // copy it into every subcommand.
  app.failure_message([](const CLI::App* a, const CLI::Error& e) {
    const std::string text = CLI::FailureMessage::simple(a, e), what = e.what();
    return btsm::io::printable(what) + text.substr(std::min(what.size(), text.size()));
  });
  btsm::cli::register_rtd_commands(app);
  btsm::cli::register_link_commands(app);
  btsm::cli::register_sysid_commands(app);
  btsm::cli::register_heat_commands(app);
  btsm::cli::register_residual_commands(app);
  btsm::cli::register_sim_commands(app);
  btsm::cli::register_demo_commands(app);
  btsm::cli::register_suite_commands(app);
  btsm::cli::refuse_non_finite_numbers(app);  // after every registration: it walks them all
  // "btsm <command>:" in front of every error, as the user typed the command
  const auto command = [&app] { return app.get_subcommands().empty() ? std::string() : app.get_subcommands().front()->get_name(); };
  // Library messages often start with their own stage name, which may be the command's: say it once
  // ("btsm reduce: at 4000 rpm ...", not "btsm reduce: reduce: at 4000 rpm ...").
  // Every message is one line, and the text it quotes from files and arguments (names, cells, paths,
  // JSON strings) is shown escaped: a CSV header with ESC [ 2 J cleared the terminal, a newline in
  // a parameter name forged a line of output.
  const auto said = [&command](const char* what) {
    const std::string text = what, own = command() + ": ";
    return btsm::io::printable(
        btsm::io::without_json_exception_ids(text.compare(0, own.size(), own) == 0 ? text.substr(own.size()) : text));
  };
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // The parser's own codes (105 missing required option, 106 file does not exist, 114 value out
    // of range, ...) are all "bad arguments": README promises 2. --help and --version are 0.
    return app.exit(e) == 0 ? btsm::cli::kExitOk : btsm::cli::kExitUsage;
  } catch (const btsm::cli::CommandError& e) {
    std::cerr << "btsm " << command() << ": " << said(e.what()) << "\n";
    return e.code;
  } catch (const btsm::io::InputError& e) {  // a reader's error no command translated: bad input
    std::cerr << "btsm " << command() << ": " << said(e.what()) << "\n";
    return btsm::cli::kExitUsage;
  } catch (const nlohmann::json::exception& e) {  // a JSON input of the wrong shape no reader named
    std::cerr << "btsm " << command() << ": a JSON input has the wrong shape: "
              << btsm::io::printable(btsm::io::without_json_exception_ids(e.what())) << "\n";
    return btsm::cli::kExitUsage;
  } catch (const std::exception& e) {
    std::cerr << "btsm " << command() << ": error: " << btsm::io::printable(btsm::io::without_json_exception_ids(e.what()))
              << "\n";
    return btsm::cli::kExitFailure;
  }
  // Tables and --json go to stdout: a full disk or closed pipe there is a failed run, not exit 0.
  std::cout.flush();
  if (!std::cout || std::fflush(stdout) != 0 || std::ferror(stdout)) {
    std::cerr << "btsm: error: writing the output to stdout failed\n";
    return btsm::cli::kExitFailure;
  }
  return 0;
}
