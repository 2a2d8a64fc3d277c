// btsm sim-module: a simulated BTSM module on a pty.
#include "host/sim/runner/sim_module.hpp"
#include "cli_support.hpp"
#include "commands.hpp"
#include "host/io/input_error.hpp"
#include "host/io/output_file.hpp"

#include <fmt/core.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <thread>
#include <unistd.h>

namespace btsm::cli {
namespace {

// Whole seconds as before; a run under 100 s keeps its fraction ("100ms@6000" said "0 s simulated").
std::string seconds_text(double s) { return s < 100.0 ? fmt::format("{:.3g}", s) : fmt::format("{:.0f}", s); }

std::atomic<bool> g_interrupted{false};
extern "C" void on_sigint(int) { g_interrupted = true; }

std::string default_elf_path() {
  char buf[4096] = {};
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 1);
  if (n <= 0) return "btsm-fw-bluno.elf";
  return (std::filesystem::path(std::string(buf, size_t(n))).parent_path() / "btsm-fw-bluno.elf").string();
}

struct SimArgs {
  std::string board = "native";
  std::string pty;
  std::string elf;
  std::string profile, profile_file, ambient = "20";
  std::string time_scale = "max";
  std::string truth_out;
  double truth_period_s = 1.0;
  std::vector<std::string> faults, effects;
  std::string eeprom;
  std::string duration;
  bool no_wait = false;
  double host_gone_exit_s = 60.0;
  uint64_t seed = 1;
  double noise = 1.0;
  std::string ch5 = "surface";
  double ch5_fraction = 0.5;
  double start_steady_rpm = -1.0;
  bool json = false;
};

void run_sim(const SimArgs& a) {
  sim::SimModuleOptions o;
  try {
    o.board = sim::parse_board_kind(a.board);
    if (!a.profile.empty()) o.plant.speed = sim::SpeedProfile::parse(a.profile);
    if (!a.profile_file.empty()) o.plant.speed = sim::SpeedProfile::load_file(a.profile_file);
    o.plant.ambient = sim::AmbientProfile::parse(a.ambient);
    for (const auto& f : a.faults) o.plant.faults.push_back(sim::parse_fault(f));
    for (const auto& e : a.effects) sim::parse_effect(e, o.plant.effects);
    if (a.ch5 == "surface") o.plant.ch5 = sim::Ch5Mode::HousingSurface;
    else if (a.ch5 == "shaft") o.plant.ch5 = sim::Ch5Mode::ShaftEnd;
    else if (a.ch5 == "disabled") o.plant.ch5 = sim::Ch5Mode::Disabled;
    else throw std::invalid_argument("--ch5 '" + a.ch5 + "': expected surface, shaft or disabled");
    o.plant.ch5_surface_fraction = a.ch5_fraction;
    if (a.start_steady_rpm >= 0.0) {
      o.plant.start_steady = true;
      o.plant.start_steady_rpm = a.start_steady_rpm;
    }
    if (a.time_scale == "max") o.time_scale = 0.0;
    else if (!parse_decimal(a.time_scale, o.time_scale) || !(o.time_scale > 0.0))
      throw std::invalid_argument("--time-scale '" + a.time_scale + "': expected a number > 0 (1 = real time) or max");
    o.duration_s = a.duration.empty() ? o.plant.speed.total_duration_s()
                                      : sim::parse_duration_s(a.duration, "--duration");
    if (!(o.duration_s > 0.0)) throw std::invalid_argument("--duration must be > 0");
    if (!(o.duration_s <= sim::kMaxDurationS))  // a profile of many long segments
      throw std::invalid_argument("the run would last " + fmt::format("{:.6g}", o.duration_s) + " s, more than the " +
                                  fmt::format("{:.0f}", sim::kMaxDurationS) + " s (31 years) a simulated run may last; give --duration");
  } catch (const std::invalid_argument& e) {
    throw CommandError(kExitUsage, e.what());
  }
  if (a.pty.find_first_not_of(" \t") == std::string::npos)
    throw CommandError(kExitUsage, "--pty: an empty path (give where the module's pty link goes, e.g. /tmp/btsm-sim)");
  // The truth CSV and the EEPROM image are written; neither may be a file this run reads or writes otherwise.
  try {
    io::refuse_output_over_input(a.truth_out, "--truth-out", {a.profile_file, a.eeprom, a.elf, a.pty});
    io::refuse_output_over_input(a.eeprom, "--eeprom", {a.profile_file, a.elf, a.pty});
    // before the run: a missing directory of --eeprom was found only after it (probe 5), and a
    // --truth-out that is a named pipe blocked for ever (probe 7)
    io::refuse_output_file_that_cannot_be_made(a.eeprom, "--eeprom", "module EEPROM image");
    io::refuse_output_file_that_cannot_be_made(a.truth_out, "--truth-out", "truth CSV");
    if (io::same_output_file(a.truth_out, a.eeprom))
      throw io::InputError("--truth-out and --eeprom name the same file " + a.eeprom + ": each needs its own");
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  o.pty_path = a.pty;
  o.elf_path = a.elf.empty() ? default_elf_path() : a.elf;
  if (o.board == sim::BoardKind::Avr)
    if (const std::string why = sim::avr_elf_problem(o.elf_path); !why.empty()) throw CommandError(kExitUsage, "--elf " + o.elf_path + ": " + why);
  o.truth_csv = a.truth_out;
  o.truth_period_s = a.truth_period_s;
  o.eeprom_path = a.eeprom;
  o.wait_for_host = !a.no_wait;
  if (a.host_gone_exit_s < 0) throw CommandError(kExitUsage, "--host-gone-exit must be >= 0 s (0 = wait for ever)");
  if (a.host_gone_exit_s > 0) o.host_gone_exit_s = a.host_gone_exit_s;
  o.adc.seed = a.seed;
  o.adc.noise_scale = a.noise;
  o.log = [](const std::string& s) { std::cerr << s << "\n"; };

  std::unique_ptr<sim::SimModule> m;
  try {
    m = std::make_unique<sim::SimModule>(o);
  } catch (const std::invalid_argument& e) {
    throw CommandError(kExitUsage, e.what());
  } catch (const std::runtime_error& e) {
    throw CommandError(kExitFailure, e.what());
  }
  std::cerr << fmt::format("sim-module: {} board, pty {} -> {}, {} s simulated, time scale {}\n",
                           m->board_kind(), a.pty, m->pty_slave(), seconds_text(o.duration_s), a.time_scale);
  g_interrupted = false;
  auto old = std::signal(SIGINT, on_sigint);
  auto old_term = std::signal(SIGTERM, on_sigint);
  m->start();
  auto last = std::chrono::steady_clock::now();
  double last_progress_s = -1;
  while (m->running()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (g_interrupted) {
      std::cerr << "sim-module: interrupted, stopping\n";
      m->stop();
      break;
    }
    const auto now = std::chrono::steady_clock::now();
    if (now - last > std::chrono::seconds(10)) {
      last = now;
      const auto s = m->stats();
      // While it waits for a host the simulated time stands still: one line for it, not one every 10 s.
      if (s.sim_time_s == last_progress_s) continue;
      last_progress_s = s.sim_time_s;
      const auto t = m->truth();
      std::cerr << fmt::format("sim-module: t = {:.0f} s ({:.1f} %), {:.0f} rpm, T1 {:.3f} degC, speed-up {:.0f}x\n",
                               s.sim_time_s, 100.0 * s.sim_time_s / o.duration_s, t.speed_rpm,
                               t.probe_c[0], s.wall_time_s > 0 ? s.sim_time_s / s.wall_time_s : 0.0);
    }
  }
  m->wait();
  std::signal(SIGINT, old);
  std::signal(SIGTERM, old_term);
  // The module's EEPROM (models flashed, configuration set) is the run's result: a failed save
  // was logged and the run ended 0 (probe 5).
  try {
    m->save_eeprom_now();
  } catch (const std::exception& e) {
    throw CommandError(kExitFailure, std::string("the run ended but its EEPROM was not saved: ") + e.what());
  }
  const auto s = m->stats();
  const std::string err = m->error();
  if (a.json) {
    nlohmann::json j;
    j["board"] = m->board_kind();
    j["sim_time_s"] = s.sim_time_s;
    j["wall_time_s"] = s.wall_time_s;
    j["waited_for_host_s"] = s.waited_s;
    j["speedup"] = s.wall_time_s > 0 ? s.sim_time_s / s.wall_time_s : 0.0;
    j["bytes_to_host"] = s.bytes_to_host;
    j["bytes_from_host"] = s.bytes_from_host;
    j["bytes_dropped"] = s.bytes_dropped;
    j["mcu_resets"] = s.board.mcu_resets;
    j["ended_host_gone"] = s.ended_host_gone;
    if (s.board.cycles) {
      j["cpu_cycles"] = s.board.cycles;
      j["cpu_active_cycles"] = s.board.active_cycles;
      j["cpu_duty"] = double(s.board.active_cycles) / double(s.board.cycles);
    }
    if (!err.empty()) j["error"] = err;
    print_json(j);
  } else {
    // wall_time_s is computing only (not the waits for a host, nor the sleeps that pace a
    // --time-scale run): "in 0.0 s (8611x)" of a run paced at 50x read as a broken pace.
    std::cerr << fmt::format("sim-module: done, {} s simulated with {:.1f} s of computing ({:.0f}x real time while "
                             "computing){}, {:.1f} s waiting for a host, {} bytes to host\n",
                             seconds_text(s.sim_time_s), s.wall_time_s, s.wall_time_s > 0 ? s.sim_time_s / s.wall_time_s : 0.0,
                             o.time_scale > 0 ? fmt::format(", paced to {:g}x", o.time_scale) : std::string(), s.waited_s,
                             s.bytes_to_host);
  }
  if (!err.empty()) throw CommandError(kExitFailure, err);
}

}  // namespace

void register_sim_commands(CLI::App& app) {
  auto a = std::make_shared<SimArgs>();
  auto* cmd = app.add_subcommand(
      "sim-module",
      "Run a simulated BTSM module (spindle plant, AD7794, firmware) on a pty.\n"
      "The module speaks the real wire protocol on PATH (a symlink to a pseudo-terminal), so every\n"
      "btsm device command works with --port PATH. Simulated time runs faster than real time;\n"
      "by default the simulation waits while no host has the pty open or the host does not read,\n"
      "so nothing is lost. The module's SAMPLE time_ms is its own clock (simulated uptime).\n"
      "Durations take units s, m, h (default s). Examples:\n"
      "  btsm sim-module --pty /tmp/btsm-sim --profile 6h@6000,4h@0,2h@3000 --truth-out truth.csv\n"
      "  btsm sim-module --board avr --pty /tmp/btsm-avr --fault open:ch2@1h --duration 2h");
  cmd->add_option("--board", a->board, "native (firmware core built for the host) or avr (real image in simavr)")
      ->check(CLI::IsMember({"native", "avr"}))
      ->capture_default_str();
  cmd->add_option("--pty", a->pty, "path of the symlink to the module's pty (the port a host opens)")->required();
  cmd->add_option("--elf", a->elf, "AVR firmware image for --board avr (default: btsm-fw-bluno.elf next to btsm)");
  auto* prof = cmd->add_option("--profile", a->profile,
                               "speed profile DURATION@RPM,... e.g. 6h@6000,4h@0 (last speed holds after the end; default 1h@0)");
  auto* pfile = cmd->add_option("--profile-file", a->profile_file,
                                "file with speed segments (DURATION@RPM separated by commas/lines, # comments)");
  prof->excludes(pfile);
  cmd->add_option("--ambient", a->ambient,
                  "ambient degC: constant (20) or START,DURATION@DEGC ramps (20,2h@22,4h@22)")
      ->capture_default_str();
  cmd->add_option("--time-scale", a->time_scale, "simulated seconds per wall second, or max")->capture_default_str();
  cmd->add_option("--truth-out", a->truth_out,
                  "write the plant's true temperatures (recording CSV: T1..T5 at the probes, node temperatures, extra heat)");
  // Not below the plant's 0.25 s step: shorter periods repeat time stamps (which btsm's readers
  // refuse) and 1e-9 s wrote 13 GB in minutes.
  cmd->add_option("--truth-period", a->truth_period_s, "seconds between truth rows (0.25 .. 86400)")
      ->check(CLI::Range(0.25, 86400.0))
      ->capture_default_str();
  cmd->add_option("--fault", a->faults,
                  "fault KIND[:ARG]@START[-END], repeatable: open:ch2@3600, openchain:ch3@1h, short:ch1@100, "
                  "noadc@0, noref@50, bearing:25W@2h (rear bearing), bearing:front:25W@2h");
  cmd->add_option("--effect", a->effects,
                  "hidden effect (not announced to the host), repeatable; NODES = node names joined by '+', "
                  "w0 = 5000 rpm: bearing-tc:K (rear-bearing heat x (1 + K theta1), 1/K), "
                  "run-in:W/TAU (= transient:W/TAU@rear_bearing+front_bearing), "
                  "transient:W/TAU@NODES (W per 1000 rpm of speed increase, decaying with TAU), "
                  "transient-gain:A/TAU@NODES (friction source x (1 + A e^-t/TAU) after each start or speed change), "
                  "transient-start:W/TAU@NODES, transient-gain-start:A/TAU@NODES (the same, restarted by starts from standstill only), "
                  "temp-heat:K@NODES (friction source x (1 + K theta), 1/K, may be < 0), "
                  "coupled-heat:G@NODE/HOT-COLD[^E] (G (w/w0)^E (T_HOT - T_COLD) W while running, G in W/K), "
                  "speed-heat:W@NODE[^E] (W (w/w0)^E while running), sensor-lag:TAU@chN, sensor-drift:RATE@chN (K/h), "
                  "ambient-lag:TAU (the air follows the measured ambient), "
                  "coolant:G@NODE=PROFILE (second boundary, W/K, column coolant_c in --truth-out), "
                  "event:G@NODES=START-END,... (W/K more to ambient while on, column lid_open), "
                  "latent:C/G@NODE[/GA] (missing mass C J/K tied by G W/K, GA W/K to ambient)");
  cmd->add_option("--eeprom", a->eeprom, "EEPROM image file (1024 bytes), loaded at start and saved at exit");
  cmd->add_option("--duration", a->duration, "simulated run time (default: the profile's length)");
  cmd->add_flag("--no-wait", a->no_wait, "free-running: drop output while no host listens instead of waiting");
  cmd->add_option("--host-gone-exit", a->host_gone_exit_s,
                  "once a host has opened the port and closed it again, end when none reopens it within this many "
                  "wall seconds (0 = wait for ever)")
      ->capture_default_str();
  cmd->add_option("--seed", a->seed, "AD7794 noise seed")->capture_default_str();
  cmd->add_option("--noise", a->noise, "AD7794 noise scale (1 = datasheet model, 0 = noiseless)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1000.0));
  cmd->add_option("--ch5", a->ch5, "spare probe: surface (housing surface), shaft (on the stationary shaft end, reads the shaft node) or disabled (AIN5 open)")->capture_default_str();
  cmd->add_option("--ch5-fraction", a->ch5_fraction, "share of the housing rise seen by the surface probe")
      ->capture_default_str();
  cmd->add_option("--start-steady", a->start_steady_rpm, "start in thermal steady state at this speed (rpm) instead of cold")
      ->check(CLI::Range(0.0, 65534.0));  // the profiles' speed limit
  cmd->add_flag("--json", a->json, "print run statistics as JSON on stdout at the end");
  cmd->callback([a] { run_sim(*a); });
}

}  // namespace btsm::cli
