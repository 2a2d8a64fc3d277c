#pragma once
// SimModule: a complete simulated BTSM module — the spindle plant (host/sim/plant), the
// register-level AD7794 and its probes, and the MCU running the firmware, either natively built
// (BoardKind::Native: firmware::App<NativeBoard>) or the real AVR image in simavr
// (BoardKind::Avr) — reachable like the real module through a pty ("BLE serial") or in-process.
//
// Time: simulated time starts at 0 at power-on and runs faster than real time ("max") or paced
// at `time_scale` simulated seconds per wall second. The module's SAMPLE time_ms is its own
// uptime (the authoritative clock); it equals simulated time until the first power cycle
// (boot_times() lists the simulated time of every power-on).
//
// Host synchronisation (`wait_for_host`, default on): the simulation stops advancing while no
// host has the pty open, and while the host does not read (pty buffer full, about 16 KB) — so a
// recorder never loses data however fast the simulation runs. In-process, the same happens when
// more than `max_unread_bytes` wait in host_receive(). Off: output is dropped while nobody
// listens, like a BLE module without a central.
//
// Use:
//   SimModuleOptions o; o.board = BoardKind::Native; o.pty_path = "/tmp/btsm-sim";
//   o.plant.speed = SpeedProfile::parse("2h@6000,1h@0");
//   SimModule m(o);
//   m.start();                      // background thread; or m.run_for(seconds) synchronously
//   m.inject_fault(parse_fault("open:ch2@3600"));
//   m.replace_speed_from_now({{1800, 3000}});
//   m.wait();                       // until duration_s (or stop())
// Every public method is thread-safe.
#include "host/sim/plant/spindle_plant.hpp"
#include "host/sim/runner/module_board.hpp"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace btsm::sim {

// "housing surface", "shaft end (reads the shaft node)", ...: the fifth probe's place, as the
// truth file names it.
const char* ch5_description(Ch5Mode mode);

enum class BoardKind { Native, Avr };
BoardKind parse_board_kind(const std::string& s);  // "native" | "avr"

struct SimModuleOptions {
  BoardKind board = BoardKind::Native;
  PlantOptions plant;                  // network, speed/ambient profiles, faults, effects, ch5
  std::string elf_path;                // avr: firmware image (btsm-fw-bluno.elf)
  std::string pty_path;                // symlink to the pty slave; empty = in-process I/O only
  double time_scale = 0.0;             // sim s per wall s; 0 = as fast as possible ("max")
  double duration_s = std::numeric_limits<double>::infinity();  // s of simulated time
  bool wait_for_host = true;           // see header comment
  // With wait_for_host and a pty: once a host has had the pty open and closed it, the run ends
  // when no host reopens it within this many wall seconds (the recorder stopped early: the module
  // does not wait for ever). Infinity = wait for ever.
  double host_gone_exit_s = std::numeric_limits<double>::infinity();
  size_t max_unread_bytes = 16384;     // in-process back-pressure limit (bytes)
  std::string truth_csv;               // true temperatures (recording CSV), empty = none
  double truth_period_s = 1.0;         // s between truth rows
  std::string eeprom_path;             // persisted EEPROM image (raw 1024 bytes), empty = none
  double io_chunk_s = 0.05;            // s, simulated time between host I/O exchanges
  Ad7794ModelOptions adc;              // noise seed/scale of the AD7794 model
  uint8_t tach_pulses_per_rev = 1;
  bool avr_dev_key = true;             // avr: provision the development key (see module_board.hpp)
  // Provision this device key record (common/device_key.hpp layout, 64 bytes; build it with
  // device_key::build_record) on either board; empty = development key, device id 0x0000DE70.
  std::vector<uint8_t> key_record;
  std::function<void(const std::string&)> log;  // progress/status lines (CLI: stderr)
};

struct TruthRow {
  double time_s = 0.0;
  double speed_rpm = 0.0;
  double ambient_c = 0.0;
  double probe_c[kChannels] = {};      // true temperature at each probe, degC
};

struct SimModuleStats {
  double sim_time_s = 0.0;
  double wall_time_s = 0.0;            // wall time spent running (not waiting for a host)
  double waited_s = 0.0;               // wall time spent waiting for the host
  uint64_t bytes_to_host = 0, bytes_from_host = 0, bytes_dropped = 0;
  bool ended_host_gone = false;        // the run ended by host_gone_exit_s, not by its duration
  BoardStats board;
};

class SimModule {
 public:
  explicit SimModule(SimModuleOptions opts);  // builds plant, board, pty; throws on bad options
  ~SimModule();                               // stops the thread, saves EEPROM, closes the pty
  SimModule(const SimModule&) = delete;
  SimModule& operator=(const SimModule&) = delete;

  // Background run until duration_s or stop().
  void start();
  void stop();
  void wait();
  bool running() const { return running_; }
  // Synchronous run (no thread): advances simulated time by `sim_s` (not with start()).
  void run_for(double sim_s);
  // Error that ended the background run ("" if none).
  std::string error() const;
  // Saves the EEPROM image (--eeprom) now; throws std::runtime_error naming the file when it cannot
  // be written (the destructor saves again and can only log).
  void save_eeprom_now();

  double sim_time_s() const;
  TruthRow truth() const;
  SimModuleStats stats() const;
  std::vector<double> boot_times() const;
  std::string pty_slave() const;           // "" without a pty
  const char* board_kind() const;

  // Run-time control (takes effect at the next I/O chunk).
  void replace_speed_from_now(const std::vector<SpeedSegment>& segs);
  void queue_speed(const SpeedSegment& seg);
  SpeedProfile speed_profile() const;
  // A fault whose start lies in the past starts now.
  void inject_fault(FaultSpec f);
  void set_effects(const HiddenEffects& fx);
  void power_cycle();                      // at the next chunk boundary

  // In-process host link. With a pty, the firmware output goes to the pty only (host_receive()
  // then returns nothing) while host_send() still adds bytes towards the firmware.
  void host_send(const std::vector<uint8_t>& bytes);
  std::vector<uint8_t> host_receive();

 private:
  void thread_main();
  void step_chunk(bool may_block);
  void step_chunk(bool may_block, double limit_s);
  void exchange_io(bool may_block);
  void write_truth_row();
  void log(const std::string& s) const;

  SimModuleOptions opts_;
  mutable std::mutex mu_;                  // plant, board, queues
  std::condition_variable cv_;
  std::unique_ptr<SpindlePlant> plant_;
  std::unique_ptr<ModuleBoard> board_;
  struct Pty;
  std::unique_ptr<Pty> pty_;
  struct Truth;
  std::unique_ptr<Truth> truth_;
  std::vector<uint8_t> to_host_pending_;   // for the pty, not yet accepted
  std::vector<uint8_t> to_host_inproc_;    // for host_receive()
  std::vector<uint8_t> from_host_;
  bool power_cycle_requested_ = false;
  std::vector<double> boot_times_{0.0};
  double next_truth_s_ = 0.0;
  SimModuleStats stats_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> running_{false};
  std::thread thread_;
  std::string error_;
};

}  // namespace btsm::sim
