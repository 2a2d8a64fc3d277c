#include "host/demo/commission.hpp"

#include "common/device_key.hpp"
#include "host/sim/plant/faults.hpp"

#include <fmt/core.h>

#include <filesystem>
#include <stdexcept>

namespace fs = std::filesystem;

namespace btsm::demo {

ModuleKey make_module_key(const std::string& out_dir) {
  ModuleKey k;
  k.key = link::KeyStore::generate();
  link::KeyStore keys((fs::path(out_dir) / "keys").string());
  keys.save(k.device_id, k.key, /*overwrite=*/true);
  return k;
}

sim::SimModuleOptions demo_module_options(const DemoPlan& plan, const std::string& effect, const ModuleKey& key) {
  sim::SimModuleOptions so;
  so.plant.ambient = sim::AmbientProfile{20.0};
  so.plant.ch5 = sim::Ch5Mode::ShaftEnd;  // the fifth probe on the stationary shaft end
  sim::parse_effect(effect, so.plant.effects);  // hidden from everything on the host side
  for (const auto& run : plan.identification)
    for (const auto& seg : run.segments) so.plant.speed.append(seg);
  so.plant.speed.append({1e6, 0});  // idle until the production phase
  uint8_t record[device_key::kRecordSize];
  device_key::build_record(record, key.device_id, key.key.data());
  so.key_record.assign(record, record + device_key::kRecordSize);
  return so;
}

Commissioned commission_module(link::Session& session, const DemoPlan& plan, const ModuleKey& key,
                               const CommissionIo& io) {
  const fs::path out(io.out_dir);
  report::HtmlReport scratch_page("");
  report::HtmlReport& page = io.page ? *io.page : scratch_page;
  std::string scratch_step;
  std::string& step = io.step ? *io.step : scratch_step;
  const auto say = [&io](const std::string& s) { if (io.say) io.say(s); };
  fs::create_directories(out / "recordings");
  fs::create_directories(out / "models");
  Commissioned c;
  c.id = link::identify(session);
  say(fmt::format("module {} firmware {} channels {}", link::device_id_text(c.id.info.device_id),
                  link::firmware_version(c.id.info), c.id.roles.describe()));
  if (c.id.info.device_id != key.device_id)
    throw std::runtime_error("the module reports another device id than its key record");

  // --- 2. Identification procedure over the module's link ---------------------------------------
  step = "record the identification procedure";
  AnalysisInputs ain;
  ain.out_dir = out.string();
  ain.reduce_speeds_rpm = plan.reduce_speeds_rpm;
  ain.progress = io.say;
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
    const link::RecordSummary rs = link::record(session, c.id, ro);
    if (rs.lost > 0) throw std::runtime_error(fmt::format("{}: {} samples lost on the link", run.name, rs.lost));
    (run.for_fit ? ain.fit_csv : ain.check_csv).push_back(path);
    run_rows.push_back({run.name, run.for_fit ? "fit" : "external check", fmt::format("{:.1f}", run.duration_s() / 3600),
                        std::to_string(rs.rows), std::to_string(rs.lost)});
  }
  page.heading("1. Identification procedure recorded over the module's serial link");
  page.paragraph(fmt::format("Board: {}. Each warm-up is followed by natural cooling; the stepwise run is kept "
                             "for external validation. The plant's spindle has an effect the paper's model "
                             "lacks; the host side is not told which.", io.board_kind));
  page.table({"recording", "use", "hours", "samples", "lost"}, run_rows);

  // --- 3 + 4. Fit, validate, residual loop, reduce --------------------------------------------------
  step = "analyse (fit, validate, residual loop, reduce)";
  c.analysis = analyse(ain, page);
  if (!c.analysis.failures.empty()) throw std::runtime_error(c.analysis.failures.front());

  // --- 4b. Flash the reduced model with authentication -----------------------------------------------
  step = "flash the reduced model";
  link::FlashOptions fo;
  fo.progress = [&](const link::FlashProgress& p) {
    if (p.bytes_sent == p.total || p.bytes_sent % 128 == 0)
      say(fmt::format("flash-model {}: {}/{} bytes", p.phase, p.bytes_sent, p.total));
  };
  c.flash = link::flash_model(session, c.analysis.blob, key.key, fo);
  if (!c.flash.verified) throw std::runtime_error("the model read back from the module differs from the one sent");
  say(fmt::format("model flashed: {} bytes in {} chunks (largest frame {} B), CRC {:08x}, read back and verified",
                  c.flash.blob_size, c.flash.chunks, c.flash.max_chunk_frame, c.flash.model_crc));
  page.heading("4b. Reduced model flashed to the module");
  page.table({"blob bytes", "chunks", "largest chunk frame (B)", "model CRC-32", "model seq", "verified"},
             {{std::to_string(c.flash.blob_size), std::to_string(c.flash.chunks), std::to_string(c.flash.max_chunk_frame),
               fmt::format("{:08x}", c.flash.model_crc), std::to_string(c.flash.model_seq_after), "yes"}});
  return c;
}

}  // namespace btsm::demo
