#pragma once
// Live recording of SAMPLEs into the recording CSV (host/thermal/recording.hpp), plus the
// helpers `btsm monitor` shares: channel roles, unit conversion, a one-line text view.
//
// Columns: time_s, speed_rpm, ambient_c, then T<k> for every channel k (1-based) that is neither
// disabled nor the ambient channel (so column names keep the hardware channel numbers).
// time_s is module time since the first sample (continued across a module restart with the
// host clock). ambient_c is the ambient channel's reading; when it is missing on a row the last
// valid value is held and counted (`# ambient_held_rows`), rows before the first valid ambient
// are skipped and counted (`# rows_without_ambient`). Lost samples are never filled in: each
// gap is a `# dropped: a-b` line (sample_index range, inclusive) at the end of the file. A channel
// the module reports faulted (open, short, ADC, reference) is an empty cell, and why is a
// `# sensor_fault: T2 open 1200.000-1500.000` line at the end (host/thermal/sensor_faults.hpp).

#include "host/link/session.hpp"
#include "host/thermal/sensor_faults.hpp"

#include <atomic>
#include <functional>
#include <string>
#include <vector>

namespace btsm::link {

// Role code per channel (wire::ChannelRole), read with GET_CONFIG; `from_module` false when the
// firmware did not answer GET_CONFIG and the contract's defaults are assumed.
struct ChannelRoles {
  uint8_t role[wire::kChannels] = {};
  bool from_module = false;
  int ambient_index() const;  // 0-based, -1 when none
  std::string describe() const;  // "T1=rear_bearing,T2=housing,...,T4=ambient"
};
ChannelRoles read_channel_roles(Session& session);

// Degrees C from a wire mK value; NaN for kMissing.
double mk_to_c(int32_t mk);

struct ModuleIdentity {
  wire::Info info{};
  ChannelRoles roles;
  std::string link;  // transport description
};
ModuleIdentity identify(Session& session);
std::string firmware_version(const wire::Info& info);

// What a live view says about a lost link: `lost` at once when the transport reports the
// device gone (the reason, and for how long reopening will be tried), `back` when a reopen
// succeeded (after how many seconds).
struct LinkLossNotes {
  std::function<void(const std::string& reason, double reconnect_s)> lost;
  std::function<void(double after_s)> back;
};

struct RecordProgress {
  uint64_t rows = 0, lost = 0, restarts = 0;
  double elapsed_s = 0;        // host wall-clock time since the recording started, s
  double module_time_s = 0;    // recording time on the module's clock (the CSV's time_s), s
  const wire::Sample* last = nullptr;
};

struct RecordOptions {
  std::string out_path;
  double duration_s = 0;       // stop after this much module time, s (0 = no limit)
  uint64_t max_samples = 0;    // stop after this many rows (0 = no limit)
  double sample_timeout_s = 0; // give up when no sample arrives for this long (0 = 3 x period + 10 s)
  double reconnect_s = 30;     // keep reopening a vanished link for this long, s (0 = fail at once)
  std::function<void(const RecordProgress&)> progress;
  LinkLossNotes link_notes;    // told at once when the link is lost and when it is back
  const std::atomic<bool>* stop = nullptr;  // set from a signal handler to end cleanly
  std::string source_label = "btsm record";
};

struct RecordSummary {
  uint64_t rows = 0, lost = 0, restarts = 0, invalid_frames = 0, reconnects = 0;
  uint64_t ambient_held_rows = 0, rows_without_ambient = 0;
  std::vector<SampleGap> gaps;
  std::vector<thermal::SensorFaultEpisode> sensor_faults;  // also '# sensor_fault:' lines in the file
  std::string stop_reason;
};

RecordSummary record(Session& session, const ModuleIdentity& id, const RecordOptions& opts);

// Waits for a sample, reopening the transport after a disconnect (for up to reconnect_s).
// Returns nullopt on timeout. `reconnects` counts successful reopens.
std::optional<SampleEvent> next_sample_with_reconnect(Session& session, Millis timeout, double reconnect_s,
                                                      uint64_t& reconnects, const std::atomic<bool>* stop,
                                                      const LinkLossNotes* notes = nullptr);

// The fault code of a channel status byte ("open", "open+adc", "fault"), "" when it reports none.
std::string sensor_fault_code(uint8_t channel_status);

// One text line for `btsm monitor`: index, speed, per channel measured/predicted/state, overall.
std::string format_sample_line(const wire::Sample& s, const ChannelRoles& roles);

}  // namespace btsm::link
