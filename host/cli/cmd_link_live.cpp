// btsm monitor | record: the live sample stream, shown or written to a recording.
#include "cmd_link_support.hpp"
#include "common/wire_messages.hpp"
#include "host/link/device_keys.hpp"
#include "host/link/recorder.hpp"

#include <fmt/core.h>
#include <unistd.h>

#include <chrono>
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

void print_monitor_event(const MonitorArgs& a, const ModuleIdentity& id, const SampleEvent& ev) {
  if (a.json) {
    std::cout << sample_json(ev.sample, &ev).dump() << std::endl;
    return;
  }
  if (ev.restarted) std::cerr << "monitor: module restarted (sample index went back)\n";
  if (ev.gap)
    std::cerr << fmt::format("monitor: {} sample(s) lost ({}-{})\n", ev.gap->count(), ev.gap->first, ev.gap->last);
  std::cout << format_sample_line(ev.sample, id.roles) << std::endl;
}

void run_monitor(const MonitorArgs& a) {
  install_interrupt_handler();
  auto conn = connect(a.link);
  const ModuleIdentity id = identify(*conn.session);
  if (!a.json)
    std::cerr << fmt::format("monitor: module {} firmware {} via {}; {}\n", device_id_text(id.info.device_id),
                             firmware_version(id.info), id.link, id.roles.describe());
  uint64_t shown = 0, reconnects = 0;
  auto last_rx = std::chrono::steady_clock::now();
  while (!g_link_stop && (a.count == 0 || shown < a.count)) {
    auto ev = next_sample_with_reconnect(*conn.session, Millis(250), a.reconnect, reconnects, &g_link_stop);
    if (!ev) {
      if (std::chrono::steady_clock::now() - last_rx > std::chrono::seconds(60))
        throw LinkError(LinkErrorKind::kTimeout, conn.transport->describe() + ": no sample for 60 s");
      continue;
    }
    last_rx = std::chrono::steady_clock::now();
    print_monitor_event(a, id, *ev);
    ++shown;
  }
}

void register_monitor(CLI::App& app) {
  auto a = std::make_shared<MonitorArgs>();
  auto* c = app.add_subcommand("monitor", "Live view of temperatures, predictions and diagnosis, one line per sample");
  c->footer(
      "Each line: sample index, speed, then per channel the measured temperature (degC), the model's\n"
      "prediction when a model is active, and the diagnosis when not NORMAL (WARN, ALARM, SENSOR_FAULT\n"
      "with fault bits open/short/adc/ref); last the overall state. Lost samples are reported on\n"
      "stderr, never filled in. Ctrl-C or --count ends it. --json prints one JSON object per line.");
  add_link_options(*c, a->link);
  c->add_flag("--json", a->json, "one JSON object per sample (NDJSON)");
  c->add_option("--count", a->count, "stop after N samples (0 = until Ctrl-C)")->capture_default_str();
  c->add_option("--reconnect", a->reconnect, "keep reopening a lost link for this many seconds (0 = exit)")
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
  if (!a.json) return;
  json gaps = json::array();
  for (const auto& g : s.gaps) gaps.push_back({g.first, g.last});
  print_json({{"out", a.out}, {"rows", s.rows}, {"lost", s.lost}, {"gaps", gaps}, {"restarts", s.restarts},
              {"reconnects", s.reconnects}, {"rejected_frames", s.invalid_frames}, {"stop_reason", s.stop_reason}});
}

void run_record(const RecordArgs& a) {
  install_interrupt_handler();
  auto conn = connect(a.link);
  const ModuleIdentity id = identify(*conn.session);
  std::cerr << fmt::format("record: module {} firmware {} via {} -> {}\n", device_id_text(id.info.device_id),
                           firmware_version(id.info), id.link, a.out);
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
      "first sample (s), speed (rpm), ambient channel (degC), temperatures (degC, empty = missing).\n"
      "Lost samples are never invented: each gap is a '# dropped: a-b' line (sample_index range) after\n"
      "the rows, with samples, lost_samples, module_restarts, link_reconnects and stop_reason.\n"
      "Progress goes to stderr; Ctrl-C stops cleanly.\n"
      "  btsm record --port /tmp/btsm-sim --out rec.csv --duration 3600");
  add_link_options(*c, a->link);
  c->add_option("--out", a->out, "CSV file to write")->required();
  c->add_option("--duration", a->duration, "stop after this much module time, s (0 = no limit)")->capture_default_str();
  c->add_option("--samples", a->samples, "stop after this many rows (0 = no limit)")->capture_default_str();
  c->add_option("--reconnect", a->reconnect, "keep reopening a lost link for this many seconds (0 = fail)")
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
