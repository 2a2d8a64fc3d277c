#pragma once
// Plumbing shared by the link command groups (cmd_link_*.cpp): opening a session from the link
// options, turning link-library exceptions into exit codes, Ctrl-C handling, and the JSON shapes
// that several commands print.
#include "cli_support.hpp"
#include "host/link/link_error.hpp"
#include "host/link/link_open.hpp"
#include "host/link/recorder.hpp"
#include "host/link/session.hpp"

#include <nlohmann/json.hpp>

#include <atomic>
#include <memory>
#include <stdexcept>
#include <string>

namespace btsm::cli {

// Set by SIGINT/SIGTERM once install_interrupt_handler() ran; monitor and record poll it.
extern std::atomic<bool> g_link_stop;
// Ctrl-C ends monitor/record cleanly (the CSV gets its summary) instead of killing the process.
void install_interrupt_handler();

int exit_code_for(link::LinkErrorKind kind);

// Runs a command body, turning library exceptions into CommandErrors with exit codes.
template <class F>
void guarded(F&& body) {
  try {
    body();
  } catch (const CommandError&) {
    throw;
  } catch (const link::NackError& e) {
    throw CommandError(kExitFailure, e.what());
  } catch (const link::LinkError& e) {
    throw CommandError(exit_code_for(e.kind()), e.what());
  } catch (const std::invalid_argument& e) {
    throw CommandError(kExitUsage, e.what());
  } catch (const std::runtime_error& e) {
    throw CommandError(kExitFailure, e.what());
  }
}

link::LinkSpec spec_from(const LinkOptions& o);
// A malformed --ble/--rfcomm/--usb is a bad argument (exit 2), found before anything is opened.
void check_link_syntax(const LinkOptions& o);

// An open transport and the session that speaks the protocol over it (the session borrows it).
struct Connection {
  link::TransportPtr transport;
  std::unique_ptr<link::Session> session;
};
Connection connect(const LinkOptions& o);

nlohmann::json info_json(const link::ModuleIdentity& id);
nlohmann::json sample_json(const wire::Sample& s, const link::SampleEvent* ev);

// "0000de71" -> 0x0000de71, or a usage error naming the text.
uint32_t parse_device_id_or_throw(const std::string& text);

// The per-group registration functions; register_link_commands() calls them all.
void register_link_discovery_commands(CLI::App& app);  // list scan info
void register_link_live_commands(CLI::App& app);       // monitor record
void register_link_control_commands(CLI::App& app);    // set-speed set-config get-config ack-alarm
void register_link_model_commands(CLI::App& app);      // flash-model
void register_link_firmware_commands(CLI::App& app);   // flash-firmware keys

}  // namespace btsm::cli
