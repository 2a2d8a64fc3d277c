#include "host/demo/demo.hpp"

#include "host/sim/plant/faults.hpp"
#include "host/sim/runner/sim_module.hpp"
#include "common/wire_messages.hpp"
#include "firmware/device_key.hpp"
#include "host/demo/demo_analysis.hpp"
#include "host/demo/demo_plan.hpp"
#include "host/demo/production_watch.hpp"
#include "host/link/device_keys.hpp"
#include "host/link/model_flash.hpp"
#include "host/link/recorder.hpp"
#include "host/link/serial_transport.hpp"
#include "host/link/session.hpp"
#include "host/report/html_report.hpp"

#include <fmt/core.h>

#include <chrono>
#include <filesystem>
#include <iostream>
#include <stdexcept>
#include <unistd.h>

namespace fs = std::filesystem;

namespace btsm::demo {
namespace {

using Clock = std::chrono::steady_clock;

void say(const std::string& s) { std::cerr << "[demo] " << s << std::endl; }

std::string default_elf() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return (exe.parent_path() / "btsm-fw-bluno.elf").string();
}

// The step that failed is named in the summary; every step throws with what went wrong.
struct StepFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace

DemoSummary run_demo(const DemoOptions& opts) {
  DemoSummary summary;
  const auto t0 = Clock::now();
  const DemoPlan plan = make_demo_plan(opts.quick);
  const fs::path out = fs::absolute(opts.out_dir);
  fs::create_directories(out / "recordings");
  fs::create_directories(out / "models");
  report::HtmlReport page("BTSM closed-loop demo on the simulated module");
  std::string step = "setup";
  try {
    // --- 1. The simulated module -------------------------------------------------------------
    step = "start the simulated module";
    const uint32_t device_id = 0x0000B75Du;
    const link::DeviceKey key = link::KeyStore::generate();
    link::KeyStore keys((out / "keys").string());
    keys.save(device_id, key, /*overwrite=*/true);

    sim::SimModuleOptions so;
    so.board = sim::parse_board_kind(opts.board);
    so.elf_path = opts.elf_path.empty() ? default_elf() : opts.elf_path;
    so.pty_path = (fs::temp_directory_path() / fmt::format("btsm-demo-{}.pty", ::getpid())).string();
    so.eeprom_path = (out / "module-eeprom.bin").string();
    fs::remove(so.eeprom_path);
    so.truth_csv = (out / "recordings" / "plant_truth.csv").string();
    so.truth_period_s = 60.0;
    so.plant.ambient = sim::AmbientProfile{20.0};
    so.plant.ch5 = sim::Ch5Mode::ShaftEnd;  // the fifth probe on the stationary shaft end
    sim::parse_effect(opts.effect, so.plant.effects);  // hidden from everything below
    for (const auto& run : plan.identification)
      for (const auto& seg : run.segments) so.plant.speed.append(seg);
    so.plant.speed.append({1e6, 0});  // idle until the production phase
    uint8_t record[device_key::kRecordSize];
    device_key::build_record(record, device_id, key.data());
    so.key_record.assign(record, record + device_key::kRecordSize);
    so.log = [](const std::string& s) { say("module: " + s); };
    sim::SimModule module(so);
    module.start();
    say(fmt::format("simulated module ({} board) on {}", module.board_kind(), so.pty_path));

    link::SerialTransport transport(so.pty_path);
    link::Session session(transport);
    const link::ModuleIdentity id = link::identify(session);
    say(fmt::format("module {} firmware {} channels {}", link::device_id_text(id.info.device_id),
                    link::firmware_version(id.info), id.roles.describe()));
    if (id.info.device_id != device_id) throw StepFailure("the module reports another device id than its key record");

    // --- 2. Identification procedure over the serial link -------------------------------------
    step = "record the identification procedure";
    AnalysisInputs ain;
    ain.out_dir = out.string();
    ain.reduce_speeds_rpm = plan.reduce_speeds_rpm;
    ain.progress = [](const std::string& s) { say(s); };
    std::vector<std::vector<std::string>> run_rows;
    for (size_t i = 0; i < plan.identification.size(); ++i) {
      const auto& run = plan.identification[i];
      const std::string path = (out / "recordings" / (run.name + ".csv")).string();
      link::RecordOptions ro;
      ro.out_path = path;
      ro.duration_s = run.duration_s();
      ro.source_label = "btsm demo";
      ro.progress = [&](const link::RecordProgress& p) {
        if (p.rows % 400 == 0)
          say(fmt::format("recording {} ({}/{}): {:.1f} of {:.1f} h simulated", run.name, i + 1,
                          plan.identification.size(), p.module_time_s / 3600, run.duration_s() / 3600));
      };
      const link::RecordSummary rs = link::record(session, id, ro);
      if (rs.lost > 0) throw StepFailure(fmt::format("{}: {} samples lost on the link", run.name, rs.lost));
      (run.for_fit ? ain.fit_csv : ain.check_csv).push_back(path);
      run_rows.push_back({run.name, run.for_fit ? "fit" : "external check", fmt::format("{:.1f}", run.duration_s() / 3600),
                          std::to_string(rs.rows), std::to_string(rs.lost)});
    }
    page.heading("1. Identification procedure recorded over the module's serial link");
    page.paragraph(fmt::format("Board: {}. Each warm-up is followed by natural cooling; the stepwise run is kept "
                               "for external validation. The plant's spindle has an effect the paper's model "
                               "lacks; the host side is not told which.", module.board_kind()));
    page.table({"recording", "use", "hours", "samples", "lost"}, run_rows);

    // --- 3 + 4. Fit, validate, residual loop, reduce --------------------------------------------
    step = "analyse (fit, validate, residual loop, reduce)";
    const AnalysisOutputs an = analyse(ain, page);
    if (!an.failures.empty()) throw StepFailure(an.failures.front());

    // --- 4b. Flash the reduced model with authentication ---------------------------------------
    step = "flash the reduced model";
    link::FlashOptions fo;
    fo.progress = [](const link::FlashProgress& p) {
      if (p.bytes_sent == p.total || p.bytes_sent % 128 == 0)
        say(fmt::format("flash-model {}: {}/{} bytes", p.phase, p.bytes_sent, p.total));
    };
    const link::FlashSummary fs_ = link::flash_model(session, an.blob, key, fo);
    if (!fs_.verified) throw StepFailure("the model read back from the module differs from the one sent");
    say(fmt::format("model flashed: {} bytes in {} chunks (largest frame {} B), CRC {:08x}, read back and verified",
                    fs_.blob_size, fs_.chunks, fs_.max_chunk_frame, fs_.model_crc));
    page.heading("4. Reduced model flashed to the module");
    page.table({"blob bytes", "chunks", "largest chunk frame (B)", "model CRC-32", "model seq", "verified"},
               {{std::to_string(fs_.blob_size), std::to_string(fs_.chunks), std::to_string(fs_.max_chunk_frame),
                 fmt::format("{:08x}", fs_.model_crc), std::to_string(fs_.model_seq_after), "yes"}});

    // --- 5. Production: normal running, then a bearing fault ------------------------------------
    step = "production phase";
    const double t_start = module.sim_time_s();
    sim::FaultSpec fault;
    fault.kind = sim::FaultKind::BearingHeat;
    fault.start_s = t_start + plan.fault_after_s;
    fault.heat_w = plan.fault_heat_w;
    module.inject_fault(fault);
    module.replace_speed_from_now(plan.production);
    ProductionOptions po;
    po.start_s = t_start;
    po.fault_s = fault.start_s;
    po.fault_heat_w = fault.heat_w;
    po.end_s = t_start + [&] { double s = 0; for (auto& g : plan.production) s += g.duration_s; return s; }();
    po.out_dir = out.string();
    po.progress = [](const std::string& s) { say(s); };
    const ProductionResult pr = watch_production(session, id, po, page);
    module.stop();
    if (!pr.failures.empty()) throw StepFailure(pr.failures.front());

    // --- 6. Report -----------------------------------------------------------------------------
    step = "write the report";
    summary.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
    page.heading("Summary");
    page.table({"item", "value"},
               {{"effect found by the residual loop", an.effect},
                {"check RMSE before / after (K)", fmt::format("{:.4f} / {:.4f}", an.check_rmse_before_K, an.check_rmse_after_K)},
                {"quantized firmware model vs full model, max (K)", fmt::format("{:.4f}", an.quantized_vs_full_max_K)},
                {"false alarms before the fault", std::to_string(pr.false_alarms)},
                {"fault to ALARM (simulated minutes)", fmt::format("{:.1f}", pr.fault_to_alarm_s / 60)},
                {"wall time (s)", fmt::format("{:.0f}", summary.wall_s)}});
    page.write((out / "index.html").string());
    say("report: " + (out / "index.html").string());
    summary.ok = true;
  } catch (const std::exception& e) {
    summary.failure = step + ": " + e.what();
    try { page.paragraph("The demo stopped: " + summary.failure); page.write((out / "index.html").string()); } catch (...) {}
  }
  summary.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return summary;
}

}  // namespace btsm::demo
