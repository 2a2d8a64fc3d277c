#include "host/demo/production_watch.hpp"

#include "common/wire_messages.hpp"
#include "host/io/output_file.hpp"
#include "host/link/device_keys.hpp"
#include "host/report/plot_style.hpp"

#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <fstream>

namespace btsm::demo {
namespace {

int diag_state(uint8_t status) { return status & 0x03; }  // wire::DiagState in the low bits

}  // namespace

ProductionResult watch_production(link::Session& session, const link::ModuleIdentity& id,
                                  const ProductionOptions& o, report::HtmlReport& page) {
  ProductionResult r;
  namespace fs = std::filesystem;
  const std::string csv_path = (fs::path(o.out_dir) / "recordings" / "production.csv").string();
  // Written row by row as an ofstream; checked first, as every output: a named pipe there blocked
  // the demo for ever.
  io::refuse_output_file_that_cannot_be_made(csv_path, "demo output", "production CSV");
  std::ofstream csv(csv_path);
  csv << "# production phase: module diagnosis per sample (states: 0 NORMAL 1 WARN 2 ALARM 3 SENSOR_FAULT)\n"
      << "# fault_start_s: " << o.fault_s - o.start_s << "\n"
      << "time_s,speed_rpm";
  for (int c = 1; c <= wire::kChannels; ++c) csv << ",T" << c << ",P" << c << ",S" << c;
  csv << ",overall\n";

  std::vector<double> t_h, state, meas1, pred1, meas3, pred3, speed;
  uint64_t reconnects = 0;
  double last_report = o.start_s;
  while (true) {
    auto ev = link::next_sample_with_reconnect(session, link::Millis(10000), 10, reconnects, nullptr);
    if (!ev) {
      r.failures.push_back("no sample from the module for 10 s during production");
      break;
    }
    if (ev->gap) r.failures.push_back(fmt::format("samples {}..{} lost during production", ev->gap->first, ev->gap->last));
    const wire::Sample& s = ev->sample;
    const double t = s.time_ms / 1000.0;
    if (t < o.start_s) continue;  // produced before the production profile began
    const double rel = t - o.start_s;
    const int overall = diag_state(s.overall);
    csv << fmt::format("{:.1f},{}", rel, s.speed_rpm);
    for (int c = 0; c < wire::kChannels; ++c)
      csv << fmt::format(",{:.4f},{:.4f},{}", link::mk_to_c(s.temp_mK[c]), link::mk_to_c(s.predicted_mK[c]),
                         diag_state(s.channel_status[c]));
    csv << "," << overall << "\n";
    t_h.push_back(rel / 3600);
    state.push_back(overall);
    speed.push_back(s.speed_rpm);
    meas1.push_back(link::mk_to_c(s.temp_mK[0]));
    pred1.push_back(link::mk_to_c(s.predicted_mK[0]));
    meas3.push_back(link::mk_to_c(s.temp_mK[2]));
    pred3.push_back(link::mk_to_c(s.predicted_mK[2]));

    if (t < o.fault_s) {
      if (overall == 2) ++r.false_alarms;
      if (overall == 1) ++r.warn_before_fault;
    } else if (overall == 2 && r.fault_to_alarm_s < 0) {
      r.fault_to_alarm_s = t - o.fault_s;
      for (int c = 0; c < wire::kChannels; ++c)
        if (diag_state(s.channel_status[c]) == 2) { r.alarm_channel = c + 1; break; }
      if (o.progress)
        o.progress(fmt::format("ALARM raised by the module on channel {} {:.1f} simulated minutes after the fault",
                               r.alarm_channel, r.fault_to_alarm_s / 60));
    }
    if (o.progress && t - last_report >= 3600) {
      last_report = t;
      o.progress(fmt::format("production: {:.1f} of {:.1f} h, {} rpm, state {}", rel / 3600, (o.end_s - o.start_s) / 3600,
                             s.speed_rpm, overall));
    }
    if (t >= o.end_s) break;
  }
  if (r.false_alarms > 0) r.failures.insert(r.failures.begin(), fmt::format("{} false ALARM samples before the fault", r.false_alarms));
  if (r.fault_to_alarm_s < 0) r.failures.push_back("the module never raised ALARM after the bearing fault");

  const double fault_h = (o.fault_s - o.start_s) / 3600;
  const std::string stem = (fs::path(o.out_dir) / "alarm_timeline").string();
  report::Plot temps{"Production: measured vs the module's own prediction", report::kTimeAxis,
                     report::kTemperatureAxis,
                     {report::measured("rear_bearing", t_h, meas1), report::model("rear_bearing", t_h, pred1, "module prediction"),
                      report::measured("front_bearing", t_h, meas3),
                      report::model("front_bearing", t_h, pred3, "module prediction")}};
  report::Plot diag{"Module diagnosis (0 NORMAL, 1 WARN, 2 ALARM, 3 SENSOR_FAULT)", report::kTimeAxis, "overall state",
                    {report::Series{"overall state", t_h, state, report::Series::Style::Step}}};
  diag.height_weight = 0.7;
  for (auto* p : {&temps, &diag}) p->markers.push_back({fault_h, "fault starts"});
  report::save_figure({temps, diag, report::speed_panel(t_h, speed)}, stem);
  page.heading("5. Production: normal running, then a bearing fault");
  page.paragraph(fmt::format("Module {} with its flashed model. A {:.0f} W extra heat at the rear bearing starts {:.1f} h "
                             "into production; the module itself decides its diagnosis.",
                             link::device_id_text(id.info.device_id), o.fault_heat_w, fault_h));
  page.table({"ALARM samples before fault", "WARN samples before fault", "fault to ALARM (min)", "channel"},
             {{std::to_string(r.false_alarms), std::to_string(r.warn_before_fault),
               r.fault_to_alarm_s < 0 ? "never" : fmt::format("{:.1f}", r.fault_to_alarm_s / 60),
               std::to_string(r.alarm_channel)}});
  page.image("alarm_timeline.png", "Alarm timeline: measured vs predicted, the module's diagnosis, speed");
  return r;
}

}  // namespace btsm::demo
