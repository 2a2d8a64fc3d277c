// btsm monitor | record: the live sample stream, shown or written to a recording.
#include "cmd_link_support.hpp"
#include "common/wire_messages.hpp"
#include "host/io/output_file.hpp"
#include "host/link/device_keys.hpp"
#include "host/link/recorder.hpp"

#include <fmt/core.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <iostream>
#include <memory>

namespace btsm::cli {
namespace {

using namespace btsm::link;
using nlohmann::json;

// --- monitor -------------------------------------------------------------------------------------

struct MonitorArgs {
  LinkOptions link;
  bool json = false;
  uint64_t count = 0;
  double reconnect = 30;
};

// Host wall-clock time of day, "12:03:05" (what a technician compares with the machine's clock).
std::string clock_text(std::chrono::system_clock::time_point t, bool with_date = false) {
  const std::time_t tt = std::chrono::system_clock::to_time_t(t);
  std::tm tm{};
  ::localtime_r(&tt, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, with_date ? "%Y-%m-%dT%H:%M:%S" : "%H:%M:%S", &tm);
  return buf;
}

void monitor_note(const std::string& what) {
  std::cerr << "monitor: " << clock_text(std::chrono::system_clock::now()) << " " << what << std::endl;
}

void print_monitor_event(const MonitorArgs& a, const ModuleIdentity& id, const SampleEvent& ev) {
  const auto now = std::chrono::system_clock::now();
  if (a.json) {
    json j = sample_json(ev.sample, &ev);
    j["host_time"] = clock_text(now, true);
    std::cout << j.dump() << std::endl;
    return;
  }
  if (ev.restarted) monitor_note("module restarted (sample index went back)");
  if (ev.gap) monitor_note(fmt::format("{} sample(s) lost ({}-{})", ev.gap->count(), ev.gap->first, ev.gap->last));
  // Host time of day, then the module's own time since it started (s).
  std::cout << fmt::format("{} t={:<9.1f} {}", clock_text(now), ev.sample.time_ms / 1000.0,
                           format_sample_line(ev.sample, id.roles))
            << std::endl;
}

// When to say the stream went quiet: one sample period as the module is configured
// (sample_period_ms) plus the reply timeout. Not the host's arrival rate: a simulated module runs
// faster than real time and its rate ("one expected every 5.81e-06 s") says nothing a user can use.
struct SilenceWatch {
  double declared_period_s = 5.0;
  std::chrono::steady_clock::time_point last_rx = std::chrono::steady_clock::now();
  bool noted = false;

  double expected_period_s() const { return declared_period_s; }
  void sample_arrived() {
    const auto now = std::chrono::steady_clock::now();
    const double dt = std::chrono::duration<double>(now - last_rx).count();
    if (noted) monitor_note(fmt::format("samples again after {:.1f} s", dt));
    noted = false;
    last_rx = now;
  }
  double silent_s() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - last_rx).count();
  }
};

void run_monitor(const MonitorArgs& a) {
  install_interrupt_handler();
  auto conn = connect(a.link);
  const ModuleIdentity id = identify(*conn.session);
  if (!a.json)
    std::cerr << fmt::format("monitor: module {} firmware {} via {}; {}\n", device_id_text(id.info.device_id),
                             firmware_version(id.info), id.link, id.roles.describe());
  SilenceWatch watch;
  try {
    watch.declared_period_s =
        conn.session->get_config(static_cast<uint8_t>(wire::ConfigKey::SamplePeriodMs)).value / 1000.0;
  } catch (const NackError&) {
    // older firmware without GET_CONFIG: keep the default
  }
  // A module that sends every 10 min is not lost after a minute.
  const double give_up_s = std::max(60.0, 3 * watch.declared_period_s + 10);
  LinkLossNotes notes;
  notes.lost = [&](const std::string& reason, double reconnect_s) {
    monitor_note(fmt::format("link lost ({}); reconnecting for up to {:.0f} s", reason, reconnect_s));
  };
  notes.back = [](double after_s) { monitor_note(fmt::format("link back after {:.1f} s", after_s)); };
  uint64_t shown = 0, reconnects = 0;
  while (!g_link_stop && (a.count == 0 || shown < a.count)) {
    auto ev = next_sample_with_reconnect(*conn.session, Millis(100), a.reconnect, reconnects, &g_link_stop, &notes);
    if (!ev) {
      const double silent = watch.silent_s();
      if (!watch.noted && silent > watch.expected_period_s() + a.link.timeout_s) {
        watch.noted = true;
        monitor_note(fmt::format("no sample for {:.1f} s (one expected every {:g} s, the module's sample period): link lost or module stopped; "
                                 "waiting up to {:.0f} s",
                                 silent, watch.expected_period_s(), give_up_s));
      }
      if (silent > give_up_s)
        throw LinkError(LinkErrorKind::kTimeout,
                        fmt::format("{}: no sample for {:.0f} s", conn.transport->describe(), give_up_s));
      continue;
    }
    watch.sample_arrived();
    print_monitor_event(a, id, *ev);
    ++shown;
  }
}

void register_monitor(CLI::App& app) {
  auto a = std::make_shared<MonitorArgs>();
  auto* c = app.add_subcommand("monitor", "Live view of temperatures, predictions and diagnosis, one line per sample");
  c->footer(
      "Each line: host time of day, the module's time since it started (t=, s), sample index, speed,\n"
      "then per channel the measured temperature (°C), the model's prediction when a model is active,\n"
      "and the diagnosis when not NORMAL (WARN, ALARM, SENSOR_FAULT with fault bits open/short/adc/ref);\n"
      "last the overall state. Lost samples are reported on stderr, never filled in. A lost link is\n"
      "said at once on stderr ('link lost (...); reconnecting for up to N s', then 'link back'), a\n"
      "silent one after one sample interval plus --timeout. Ctrl-C or --count ends it. --json prints\n"
      "one JSON object per line (with host_time).");
  add_link_options(*c, a->link);
  c->add_flag("--json", a->json, "one JSON object per sample (NDJSON)");
  c->add_option("--count", a->count, "stop after N samples (0 = until Ctrl-C)")
      ->check(non_negative_number())  // -1 meant "until Ctrl-C" silently
      ->capture_default_str();
  c->add_option("--reconnect", a->reconnect, "keep reopening a lost link for this many seconds (0 = exit)")
      ->check(non_negative_number())
      ->capture_default_str();
  c->callback([a] { guarded([&] { run_monitor(*a); }); });
}

// --- record --------------------------------------------------------------------------------------

struct RecordArgs {
  LinkOptions link;
  std::string out;
  double duration = 0;
  uint64_t samples = 0;
  double reconnect = 30;
  bool json = false;
};

void print_record_summary(const RecordArgs& a, const RecordSummary& s) {
  std::cerr << fmt::format("record: {} rows written to {}, {} samples lost in {} gap(s), stopped: {}\n", s.rows,
                           a.out, s.lost, s.gaps.size(), s.stop_reason);
  for (const auto& f : s.sensor_faults)
    std::cerr << fmt::format("record: {} reported {} from {:.1f} to {:.1f} s (empty cells)\n", f.channel, f.code,
                             f.from_s, f.to_s);
  if (!a.json) return;
  json gaps = json::array();
  for (const auto& g : s.gaps) gaps.push_back({g.first, g.last});
  json faults = json::array();
  for (const auto& f : s.sensor_faults)
    faults.push_back({{"channel", f.channel}, {"code", f.code}, {"from_s", f.from_s}, {"to_s", f.to_s}});
  print_json({{"out", a.out}, {"rows", s.rows}, {"lost", s.lost}, {"gaps", gaps}, {"restarts", s.restarts},
              {"reconnects", s.reconnects}, {"rejected_frames", s.invalid_frames}, {"sensor_faults", faults},
              {"stop_reason", s.stop_reason}});
}

void run_record(const RecordArgs& a) {
  // --out at the module's own port wrote the CSV into the link (frame errors, no recording).
  try {
    io::refuse_output_over_input(a.out, "--out", {a.link.port});
    io::refuse_output_file_that_cannot_be_made(a.out, "--out", "recording");  // before connecting, not after
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  install_interrupt_handler();
  auto conn = connect(a.link);
  const ModuleIdentity id = identify(*conn.session);
  std::cerr << fmt::format("record: module {} firmware {} via {} -> {}\n", device_id_text(id.info.device_id),
                           firmware_version(id.info), id.link, a.out);
  // A recording of hours is never replaced silently: the old file is kept beside the new one.
  const std::string kept = io::keep_existing_as_backup(a.out);
  if (!kept.empty()) std::cerr << fmt::format("record: {} existed; kept it as {}\n", a.out, kept);
  RecordOptions ro;
  ro.out_path = a.out;
  ro.duration_s = a.duration;
  ro.max_samples = a.samples;
  ro.reconnect_s = a.reconnect;
  ro.stop = &g_link_stop;
  const bool tty = ::isatty(STDERR_FILENO);
  ro.progress = [&](const RecordProgress& p) {
    const std::string line =
        fmt::format("record: {} rows, {} lost, {} restarts, {:.0f} s", p.rows, p.lost, p.restarts, p.elapsed_s);
    if (tty) std::cerr << "\r" << line << std::flush;
    else if (p.rows % 100 == 0) std::cerr << line << "\n";
  };
  ro.link_notes.lost = [&](const std::string& reason, double reconnect_s) {
    std::cerr << (tty ? "\n" : "")
              << fmt::format("record: link lost ({}); reconnecting for up to {:.0f} s\n", reason, reconnect_s);
  };
  ro.link_notes.back = [](double after_s) { std::cerr << fmt::format("record: link back after {:.1f} s\n", after_s); };
  const RecordSummary s = record(*conn.session, id, ro);
  if (tty) std::cerr << "\n";
  print_record_summary(a, s);
}

void register_record(CLI::App& app) {
  auto a = std::make_shared<RecordArgs>();
  auto* c = app.add_subcommand("record", "Record samples into a recording CSV (the input of `btsm fit`)");
  c->footer(
      "CSV: '# key: value' metadata (module_id, firmware_version, link, channel_roles, ambient_channel),\n"
      "header time_s,speed_rpm,ambient_c,T<k>... (one column per channel that is neither disabled nor\n"
      "ambient, named by its hardware channel number), then one row per sample: module time since the\n"
      "first sample (s), speed (rpm), ambient channel (°C), temperatures (°C, empty = missing).\n"
      "Lost samples are never invented: each gap is a '# dropped: a-b' line (sample_index range) after\n"
      "the rows, with samples, lost_samples, module_restarts, link_reconnects and stop_reason. A channel\n"
      "the module reports faulted is an empty cell, and a '# sensor_fault: T2 open 1200.000-1500.000'\n"
      "line after the rows says which fault over which time_s range (codes open, short, adc, ref).\n"
      "Progress goes to stderr; Ctrl-C stops cleanly.\n"
      "  btsm record --port /tmp/btsm-sim --out rec.csv --duration 3600");
  add_link_options(*c, a->link);
  c->add_option("--out", a->out, "CSV file to write (an existing one is kept as FILE.~N~)")->required();
  c->add_option("--duration", a->duration, "stop after this much module time, s (0 = no limit)")
      ->check(non_negative_number())  // -1 meant "no limit" silently
      ->capture_default_str();
  c->add_option("--samples", a->samples, "stop after this many rows (0 = no limit)")
      ->check(non_negative_number())
      ->capture_default_str();
  c->add_option("--reconnect", a->reconnect, "keep reopening a lost link for this many seconds (0 = fail)")
      ->check(non_negative_number())
      ->capture_default_str();
  c->add_flag("--json", a->json, "print the summary as JSON");
  c->callback([a] { guarded([&] { run_record(*a); }); });
}

}  // namespace

void register_link_live_commands(CLI::App& app) {
  register_monitor(app);
  register_record(app);
}

}  // namespace btsm::cli
