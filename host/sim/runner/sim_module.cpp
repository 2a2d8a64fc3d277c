#include "host/sim/runner/sim_module.hpp"

#include "common/channels.hpp"

#include "host/sim/plant/probes.hpp"
#include "host/sim/runner/pty_bridge.hpp"
#include "host/thermal/recording.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

namespace btsm::sim {

using Clock = std::chrono::steady_clock;

BoardKind parse_board_kind(const std::string& s) {
  if (s == "native") return BoardKind::Native;
  if (s == "avr") return BoardKind::Avr;
  throw std::invalid_argument("board '" + s + "': expected native or avr");
}

// What the fifth probe measures in the truth file's channel list (--ch5).
const char* ch5_description(Ch5Mode mode) {
  switch (mode) {
    case Ch5Mode::HousingSurface: return "housing surface";
    case Ch5Mode::ShaftEnd: return "shaft end (reads the shaft node)";
    case Ch5Mode::Disabled: return "not connected (AIN5 open)";
  }
  return "unknown";
}

struct SimModule::Pty {
  explicit Pty(const std::string& path) : bridge(path) {}
  PtyBridge bridge;
};

struct SimModule::Truth {
  thermal::RecordingWriter writer;
  size_t nodes = 0;
};

SimModule::SimModule(SimModuleOptions opts) : opts_(std::move(opts)) {
  if (!(opts_.io_chunk_s > 0.0) || opts_.io_chunk_s > 1.0)
    throw std::invalid_argument("sim-module: io chunk must be within (0, 1] s");
  if (opts_.time_scale < 0.0 || !std::isfinite(opts_.time_scale))
    throw std::invalid_argument("sim-module: time scale must be >= 0 (0 = max)");
  if (!(opts_.duration_s > 0.0)) throw std::invalid_argument("sim-module: duration must be > 0 s");
  if (!(opts_.truth_period_s > 0.0)) throw std::invalid_argument("sim-module: truth period must be > 0 s");
  plant_ = std::make_unique<SpindlePlant>(opts_.plant);
  ModuleBoardOptions b;
  b.adc = opts_.adc;
  b.elf_path = opts_.elf_path;
  b.eeprom_path = opts_.eeprom_path;
  b.tach_pulses_per_rev = opts_.tach_pulses_per_rev;
  b.avr_dev_key = opts_.avr_dev_key;
  b.key_record = opts_.key_record;
  board_ = opts_.board == BoardKind::Avr ? make_avr_board(b) : make_native_board(b);
  // The pty first: a start that fails there must not have truncated an existing --truth-out file.
  if (!opts_.pty_path.empty()) pty_ = std::make_unique<Pty>(opts_.pty_path);
  // Two modules on one link path: a command typed while the new one started reached the old one
  // (a README walk: set-config acknowledged by the previous module, the recording without the role).
  if (pty_ && !pty_->bridge.replaced_live_target().empty())
    log("sim-module: WARNING: " + opts_.pty_path + " led to " + pty_->bridge.replaced_live_target() +
        ", a pty still open (another sim-module still running?); it now leads to this module, but a host that "
        "opened the old one keeps talking to that one (end it first, or give each module its own --pty)");
  if (!opts_.truth_csv.empty()) {
    truth_ = std::make_unique<Truth>();
    std::vector<std::string> cols;
    for (int ch = 1; ch <= kChannels; ++ch) cols.push_back("T" + std::to_string(ch));
    const auto& net = plant_->network();
    truth_->nodes = size_t(net.node_count());
    for (const auto& n : net.nodes) cols.push_back("node_" + n.name);
    for (const auto& n : net.nodes) cols.push_back("extra_heat_W_" + n.name);
    for (const auto& c : plant_->declared_columns()) cols.push_back(c);
    truth_->writer.open(opts_.truth_csv, cols, 5);
    auto& w = truth_->writer;
    w.write_meta("source", "btsm sim-module (simulated truth, not a measurement)");
    w.write_meta("board", board_->kind());
    w.write_meta("network", opts_.plant.network);
    w.write_meta("speed_profile", opts_.plant.speed.to_string());
    w.write_meta("channels", std::string("T1 rear bearing, T2 housing, T3 front bearing, T4 ambient, T5 ") +
                                 ch5_description(opts_.plant.ch5));
    // Where each probe sits, in the recording's own words: without it `fit --preset spindle4` took
    // T4 (the ambient probe) for the shaft (probe 5). The spare surface probe is no node.
    w.write_meta("channel_roles", std::string("T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=") +
                                      (opts_.plant.ch5 == Ch5Mode::ShaftEnd ? "shaft"
                                       : opts_.plant.ch5 == Ch5Mode::Disabled ? "disabled"
                                                                               : "spare"));
    for (const auto& f : opts_.plant.faults) w.write_meta("fault", to_string(f));
    for (const auto& e : opts_.plant.effects.specs) w.write_meta("effect", e);
    const auto join = [](const std::vector<std::string>& v) {
      std::string s;
      for (const auto& x : v) s += (s.empty() ? "" : ",") + x;
      return s;
    };
    if (!opts_.plant.effects.boundaries.empty()) w.write_meta("boundary_columns", join(opts_.plant.effects.boundary_columns()));
    if (!opts_.plant.effects.events.empty()) w.write_meta("event_columns", join(opts_.plant.effects.event_columns()));
    w.write_meta("columns", "T*, node_* in degC; extra_heat_W_* = heat beyond the paper's model in W");
  }
  write_truth_row();
}

SimModule::~SimModule() {
  stop();
  try {
    std::lock_guard<std::mutex> lk(mu_);
    board_->save_eeprom();
    if (truth_) truth_->writer.close();
  } catch (const std::exception& e) {
    log(std::string("sim-module: ") + e.what());
  }
}

void SimModule::save_eeprom_now() {
  std::lock_guard<std::mutex> lk(mu_);
  board_->save_eeprom();
}

const char* SimModule::board_kind() const { return board_->kind(); }

void SimModule::log(const std::string& s) const {
  if (opts_.log) opts_.log(s);
}

void SimModule::start() {
  if (running_) return;
  stop_ = false;
  running_ = true;
  thread_ = std::thread([this] { thread_main(); });
}

void SimModule::stop() {
  stop_ = true;
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  running_ = false;
}

void SimModule::wait() {
  if (thread_.joinable()) thread_.join();
  running_ = false;
}

std::string SimModule::error() const {
  std::lock_guard<std::mutex> lk(mu_);
  return error_;
}

void SimModule::thread_main() {
  try {
    auto pace_wall = Clock::now();
    double pace_sim = sim_time_s();
    bool waiting_logged = false;
    bool host_seen = false;           // a host has had the pty open since the start
    bool taken_over = false;          // the link now leads to a newer module's pty
    auto host_last_seen = Clock::now();
    while (!stop_ && sim_time_s() < opts_.duration_s - 1e-9) {
      // Host synchronisation: do not advance while nobody listens or the host lags behind.
      if (opts_.wait_for_host) {
        const auto w0 = Clock::now();
        bool waited = false;
        for (;;) {
          if (stop_) return;
          if (pty_) {
            std::unique_lock<std::mutex> lk(mu_);
            const bool connected = pty_->bridge.host_connected();
            if (connected) {
              exchange_io(false);
              host_seen = true;
              host_last_seen = Clock::now();
            }
            if (connected && to_host_pending_.empty()) break;
            if (!connected && host_seen &&
                std::chrono::duration<double>(Clock::now() - host_last_seen).count() >= opts_.host_gone_exit_s) {
              stats_.ended_host_gone = true;
              char line[256];
              std::snprintf(line, sizeof line, " and none reopened it within %g s; ending at t = %.0f s",
                            opts_.host_gone_exit_s, board_->time_s());
              log("sim-module: the host closed " + opts_.pty_path + line);
              break;
            }
            // A newer module took the link: no host can open this one any more, and one typed
            // while the newer one started reached this one (a README block pasted twice). End.
            if (!connected && !pty_->bridge.link_still_ours()) {
              taken_over = true;
              log("sim-module: " + opts_.pty_path + " now leads to another module; ending at t = " +
                  std::to_string(static_cast<long>(board_->time_s())) + " s");
              break;
            }
            lk.unlock();
            if (!connected && !waiting_logged) {
              log("sim-module: waiting for a host to open " + opts_.pty_path);
              waiting_logged = true;
            }
            if (connected) pty_->bridge.wait_writable(50);
            else std::this_thread::sleep_for(std::chrono::milliseconds(20));
          } else {
            std::unique_lock<std::mutex> lk(mu_);
            if (to_host_inproc_.size() <= opts_.max_unread_bytes) break;
            cv_.wait_for(lk, std::chrono::milliseconds(50));
          }
          waited = true;
        }
        if (stats_.ended_host_gone || taken_over) break;  // written by this thread only
        if (waited) {
          const double dt = std::chrono::duration<double>(Clock::now() - w0).count();
          std::lock_guard<std::mutex> lk(mu_);
          stats_.waited_s += dt;
          if (waiting_logged) log("sim-module: host connected at t = " + std::to_string(board_->time_s()) + " s");
          waiting_logged = false;
          pace_wall = Clock::now();
          pace_sim = board_->time_s();
        }
      }
      const auto c0 = Clock::now();
      const double before = sim_time_s();
      step_chunk(true);
      {
        std::lock_guard<std::mutex> lk(mu_);
        stats_.wall_time_s += std::chrono::duration<double>(Clock::now() - c0).count();
      }
      // The board advances in its own ticks: what is left of a duration a hair above a whole tick
      // (100.0000003 s, or 55,000 segments of 0.1 s summing to 5500.0000000025) cannot be run, and
      // the loop spun on it for ever at full CPU. Nothing moved: the run is over.
      if (!(sim_time_s() > before)) break;
      if (opts_.time_scale > 0.0) {
        // In slices, so that stop() is heard: at --time-scale 0.001 one chunk is minutes of wall
        // time, and one sleep_until ignored Ctrl-C and SIGTERM for that long.
        const double ahead = (sim_time_s() - pace_sim) / opts_.time_scale;
        const auto until = pace_wall + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(ahead));
        while (!stop_ && Clock::now() < until)
          std::this_thread::sleep_until(std::min(until, Clock::now() + std::chrono::milliseconds(100)));
      }
    }
    std::lock_guard<std::mutex> lk(mu_);
    exchange_io(false);
    if (truth_) truth_->writer.flush();
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lk(mu_);
    error_ = e.what();
    log(std::string("sim-module: stopped: ") + e.what());
  }
  running_ = false;
}

void SimModule::run_for(double sim_s) {
  if (running_) throw std::logic_error("SimModule::run_for while the background thread runs");
  const double end = std::min(sim_time_s() + sim_s, opts_.duration_s);
  while (sim_time_s() < end - 1e-9) {
    const double before = sim_time_s();
    step_chunk(false, end);
    if (!(sim_time_s() > before)) break;  // below the board's tick: nothing left to run (see run())
  }
}

void SimModule::step_chunk(bool may_block) { step_chunk(may_block, opts_.duration_s); }

void SimModule::step_chunk(bool /*may_block*/, double limit_s) {
  std::lock_guard<std::mutex> lk(mu_);
  const double t = board_->time_s();
  if (power_cycle_requested_) {
    board_->power_cycle();
    boot_times_.push_back(t);
    power_cycle_requested_ = false;
  }
  apply_to_front_end(*plant_, board_->front_end());
  board_->set_spindle_rpm(plant_->speed_rpm());
  const double t_next = std::min(t + opts_.io_chunk_s, limit_s);
  board_->run_until(t_next);
  plant_->advance_to(t_next);
  write_truth_row();
  exchange_io(false);
  stats_.sim_time_s = board_->time_s();
}

// Called with mu_ held. Moves bytes between the board and the pty / in-process queues.
void SimModule::exchange_io(bool) {
  std::vector<uint8_t> out;
  board_->take_output(out);
  if (!from_host_.empty()) {
    board_->host_send(from_host_.data(), from_host_.size());
    stats_.bytes_from_host += from_host_.size();
    from_host_.clear();
  }
  if (pty_) {
    uint8_t buf[512];
    for (;;) {
      const size_t n = pty_->bridge.read(buf, sizeof buf);
      if (n == 0) break;
      board_->host_send(buf, n);
      stats_.bytes_from_host += n;
    }
    to_host_pending_.insert(to_host_pending_.end(), out.begin(), out.end());
    if (!opts_.wait_for_host && !pty_->bridge.host_connected()) {
      stats_.bytes_dropped += to_host_pending_.size();
      to_host_pending_.clear();
    }
    size_t sent = 0;
    while (sent < to_host_pending_.size()) {
      const size_t n = pty_->bridge.write(to_host_pending_.data() + sent, to_host_pending_.size() - sent);
      if (n == 0) break;
      sent += n;
    }
    stats_.bytes_to_host += sent;
    to_host_pending_.erase(to_host_pending_.begin(), to_host_pending_.begin() + long(sent));
    if (!opts_.wait_for_host && !to_host_pending_.empty()) {
      stats_.bytes_dropped += to_host_pending_.size();
      to_host_pending_.clear();
    }
  } else {
    if (!opts_.wait_for_host && to_host_inproc_.size() + out.size() > opts_.max_unread_bytes) {
      stats_.bytes_dropped += out.size();
    } else {
      to_host_inproc_.insert(to_host_inproc_.end(), out.begin(), out.end());
      stats_.bytes_to_host += out.size();
    }
  }
}

void SimModule::write_truth_row() {
  if (!truth_) return;
  while (plant_->time_s() >= next_truth_s_ - 1e-9) {
    std::vector<double> v;
    for (int ch = 1; ch <= kChannels; ++ch) v.push_back(plant_->probe_temp_c(ch));
    const auto& x = plant_->node_temp_c();
    for (Eigen::Index i = 0; i < x.size(); ++i) v.push_back(x[i]);
    const auto& q = plant_->extra_heat_w();
    for (Eigen::Index i = 0; i < q.size(); ++i) v.push_back(q[i]);
    for (double d : plant_->declared_values()) v.push_back(d);
    truth_->writer.append(plant_->time_s(), plant_->speed_rpm(), plant_->ambient_c(), v);
    next_truth_s_ += opts_.truth_period_s;
  }
}

double SimModule::sim_time_s() const {
  std::lock_guard<std::mutex> lk(mu_);
  return board_->time_s();
}

TruthRow SimModule::truth() const {
  std::lock_guard<std::mutex> lk(mu_);
  TruthRow r;
  r.time_s = plant_->time_s();
  r.speed_rpm = plant_->speed_rpm();
  r.ambient_c = plant_->ambient_c();
  for (int ch = 1; ch <= kChannels; ++ch) r.probe_c[ch - 1] = plant_->probe_temp_c(ch);
  return r;
}

SimModuleStats SimModule::stats() const {
  std::lock_guard<std::mutex> lk(mu_);
  SimModuleStats s = stats_;
  s.sim_time_s = board_->time_s();
  s.board = board_->stats();
  return s;
}

std::vector<double> SimModule::boot_times() const {
  std::lock_guard<std::mutex> lk(mu_);
  return boot_times_;
}

std::string SimModule::pty_slave() const { return pty_ ? pty_->bridge.slave_name() : std::string(); }

void SimModule::replace_speed_from_now(const std::vector<SpeedSegment>& segs) {
  std::lock_guard<std::mutex> lk(mu_);
  plant_->replace_speed_from_now(segs);
}

void SimModule::queue_speed(const SpeedSegment& seg) {
  std::lock_guard<std::mutex> lk(mu_);
  plant_->queue_speed(seg);
}

SpeedProfile SimModule::speed_profile() const {
  std::lock_guard<std::mutex> lk(mu_);
  return plant_->speed_profile();
}

void SimModule::inject_fault(FaultSpec f) {
  std::lock_guard<std::mutex> lk(mu_);
  if (f.start_s < plant_->time_s()) f.start_s = plant_->time_s();
  if (f.end_s <= f.start_s) throw std::invalid_argument("inject_fault: the fault ends before now");
  plant_->add_fault(f);
}

void SimModule::set_effects(const HiddenEffects& fx) {
  std::lock_guard<std::mutex> lk(mu_);
  plant_->set_effects(fx);
}

void SimModule::power_cycle() {
  std::lock_guard<std::mutex> lk(mu_);
  power_cycle_requested_ = true;
}

void SimModule::host_send(const std::vector<uint8_t>& bytes) {
  std::lock_guard<std::mutex> lk(mu_);
  from_host_.insert(from_host_.end(), bytes.begin(), bytes.end());
}

std::vector<uint8_t> SimModule::host_receive() {
  std::vector<uint8_t> out;
  {
    std::lock_guard<std::mutex> lk(mu_);
    out.swap(to_host_inproc_);
  }
  cv_.notify_all();
  return out;
}

}  // namespace btsm::sim
