#include "host/demo/demo.hpp"

#include "host/io/output_file.hpp"
#include "host/sim/plant/faults.hpp"
#include "host/sim/plant/hidden_effects.hpp"
#include "host/sim/runner/sim_module.hpp"
#include "common/wire_messages.hpp"
#include "host/demo/commission.hpp"
#include "host/demo/demo_analysis.hpp"
#include "host/demo/demo_plan.hpp"
#include "host/demo/production_watch.hpp"
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

void check_demo_options(const DemoOptions& opts) {
  if (!opts.effect.empty()) {
    sim::HiddenEffects fx;
    sim::parse_effect(opts.effect, fx);  // throws naming what it does not understand
  }
  if (sim::parse_board_kind(opts.board) == sim::BoardKind::Avr) {
    const std::string elf = opts.elf_path.empty() ? default_elf() : opts.elf_path;
    if (const std::string why = sim::avr_elf_problem(elf); !why.empty()) throw std::invalid_argument("--elf " + elf + ": " + why);
  }
  io::refuse_output_dir_that_cannot_be_made(opts.out_dir, "--out");
}

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
    const ModuleKey key = make_module_key(out.string());
    sim::SimModuleOptions so = demo_module_options(plan, opts.effect, key);
    so.truth_csv = (out / "recordings" / "plant_truth.csv").string();
    so.truth_period_s = 60.0;
    so.board = sim::parse_board_kind(opts.board);
    so.elf_path = opts.elf_path.empty() ? default_elf() : opts.elf_path;
    so.pty_path = (fs::temp_directory_path() / fmt::format("btsm-demo-{}.pty", ::getpid())).string();
    so.eeprom_path = (out / "module-eeprom.bin").string();
    fs::remove(so.eeprom_path);
    so.log = [](const std::string& s) { say("module: " + s); };
    sim::SimModule module(so);
    module.start();
    say(fmt::format("simulated module ({} board) on {}", module.board_kind(), so.pty_path));

    link::SerialTransport transport(so.pty_path);
    link::Session session(transport);
    CommissionIo io;
    io.out_dir = out.string();
    io.board_kind = module.board_kind();
    io.page = &page;
    io.step = &step;
    io.say = [](const std::string& s) { say(s); };
    const Commissioned com = commission_module(session, plan, key, io);
    const link::ModuleIdentity& id = com.id;
    const AnalysisOutputs& an = com.analysis;

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
