#include "host/sim/suite/generate.hpp"

#include "common/wire_messages.hpp"
#include "host/io/output_file.hpp"
#include "host/link/recorder.hpp"
#include "host/link/session.hpp"
#include "host/sim/suite/module_transport.hpp"

#include <fmt/core.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

namespace fs = std::filesystem;

namespace btsm::sim::suite {
namespace {

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ",") + x;
  return s;
}

// Adds the declared columns to a recording written by the recorder: metadata lines before the
// header, the column names on the header, the logger's value at each row's plant time.
void merge_declared_columns(const std::string& path, const HiddenEffects& fx, double plant_t0_s, double sigma_k,
                            unsigned seed) {
  const auto bcols = fx.boundary_columns(), ecols = fx.event_columns();
  if (bcols.empty() && ecols.empty()) return;
  std::ifstream in(path);
  std::stringstream out;
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma_k);
  std::string line;
  bool header = false;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') {
      out << line << "\n";
      continue;
    }
    if (!header) {
      if (!bcols.empty()) out << "# boundary_columns: " << join(bcols) << "\n";
      if (!ecols.empty()) out << "# event_columns: " << join(ecols) << "\n";
      out << line;
      for (const auto& c : bcols) out << "," << c;
      for (const auto& c : ecols) out << "," << c;
      out << "\n";
      header = true;
      continue;
    }
    const double t = plant_t0_s + std::stod(line.substr(0, line.find(',')));
    out << line;
    for (const auto& b : fx.boundaries) out << fmt::format(",{:.3f}", b.temperature.celsius_at(t) + noise(rng));
    for (const auto& e : fx.events) out << (e.on_at(t) ? ",1" : ",0");
    out << "\n";
  }
  in.close();
  io::write_output_file(path, out.str(), "recording");
}

// Sum of squared (recorded - true) over T1, T2, T3 (and T5 when recorded), and the cell count.
std::pair<double, size_t> floor_sums(const std::string& path, const std::vector<TruthSample>& truth, double t0) {
  const thermal::Recording rec = thermal::read_recording_csv(path);
  double ss = 0;
  size_t n = 0;
  for (int ch : {1, 2, 3, 5}) {
    const int col = rec.channel_index("T" + std::to_string(ch));
    if (col < 0 && ch == 5) continue;  // channel 5 disabled: no shaft probe
    if (col < 0) throw std::runtime_error(path + ": no column T" + std::to_string(ch));
    for (size_t r = 0; r < rec.rows(); ++r) {
      const double v = rec.temp_c(long(r), col);
      if (std::isnan(v)) continue;
      const double d = v - truth_at(truth, t0 + rec.time_s[r], ch);
      ss += d * d;
      ++n;
    }
  }
  return {ss, n};
}

}  // namespace

GeneratedCase generate_case(const SuiteCase& c, const std::string& dir, const GenerateOptions& opts) {
  const auto w0 = std::chrono::steady_clock::now();
  const auto fail = [&](const std::string& what) { throw std::runtime_error("suite case " + c.id + ": " + what); };
  fs::create_directories(dir);
  const Procedure proc = make_procedure({c.procedure}, c.seed);

  SimModuleOptions so;
  so.board = BoardKind::Native;
  so.plant.speed = proc.speed();
  so.plant.ambient = AmbientProfile::parse(c.ambient);
  so.plant.ch5 = c.shaft_probe ? Ch5Mode::ShaftEnd : Ch5Mode::Disabled;
  for (const auto& e : c.effects) parse_effect(e, so.plant.effects);
  so.adc.seed = c.seed;
  so.adc.noise_scale = 1.0;  // the AD7794 datasheet noise
  SimModule module(so);
  ModuleTransport transport(module);

  // Channel 5 sits on the shaft end: give it the role, as an installer would, so the recordings
  // carry it and the residual loop places the probe by itself (a case without the shaft probe
  // disables the channel instead).
  {
    link::Session s(transport);
    s.set_config(wire::channel_role_key(4), static_cast<int32_t>(c.shaft_probe ? wire::ChannelRole::Shaft
                                                                               : wire::ChannelRole::Disabled));
  }

  GeneratedCase g;
  double ss_fit = 0, ss_check = 0;
  size_t n_fit = 0, n_check = 0;
  for (const auto& run : proc.runs) {
    // Overnight: the module runs on, nobody records.
    const double lead_s = 30;
    while (module.sim_time_s() < run.start_s - lead_s) {
      module.run_for(std::min(600.0, run.start_s - lead_s - module.sim_time_s()));
      (void)module.host_receive();
    }
    link::Session session(transport);  // a new `btsm record` for the day
    const link::ModuleIdentity id = link::identify(session);
    GeneratedRun gr;
    gr.name = run.name;
    gr.path = run.name + ".csv";
    gr.for_fit = run.for_fit;
    link::RecordOptions ro;
    ro.out_path = (fs::path(dir) / gr.path).string();
    ro.duration_s = run.duration_s() + lead_s;
    ro.source_label = "btsm record (simulated spindle, undeclared-effect suite)";
    bool first = true;
    ro.progress = [&](const link::RecordProgress& p) {
      if (first && p.last) gr.plant_start_s = p.last->time_ms / 1000.0;  // module uptime = plant time
      first = false;
    };
    transport.clear_truth();
    transport.keep_truth(true);
    const link::RecordSummary rs = link::record(session, id, ro);
    transport.keep_truth(false);
    gr.rows = rs.rows;
    gr.lost = rs.lost;
    gr.rejected_frames = rs.invalid_frames;
    if (rs.lost > 0) fail(fmt::format("{}: {} samples lost on the link", run.name, rs.lost));
    if (rs.rows == 0) fail(run.name + ": nothing recorded");
    const auto [ss, n] = floor_sums(ro.out_path, transport.truth(), gr.plant_start_s);
    (run.for_fit ? ss_fit : ss_check) += ss;
    (run.for_fit ? n_fit : n_check) += n;
    merge_declared_columns(ro.out_path, so.plant.effects, gr.plant_start_s, opts.coolant_logger_sigma_k,
                           c.seed ^ unsigned(g.runs.size() + 1) * 0x9e3779b9u);
    g.runs.push_back(gr);
  }
  g.noise_floor_fit_k = n_fit ? std::sqrt(ss_fit / double(n_fit)) : 0.0;
  g.noise_floor_check_k = n_check ? std::sqrt(ss_check / double(n_check)) : 0.0;
  g.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
  io::write_output_file((fs::path(dir) / "truth.json").string(), generated_json(c, g).dump(1) + "\n", "case truth");
  return g;
}

nlohmann::json generated_json(const SuiteCase& c, const GeneratedCase& g) {
  nlohmann::json j = to_json(c);
  j["runs"] = nlohmann::json::array();
  for (const auto& r : g.runs)
    j["runs"].push_back({{"name", r.name}, {"file", r.path}, {"use", r.for_fit ? "fit" : "check"},
                         {"plant_start_s", r.plant_start_s}, {"rows", r.rows}, {"lost", r.lost},
                         {"rejected_frames", r.rejected_frames}});
  j["noise_floor_fit_K"] = g.noise_floor_fit_k;
  j["noise_floor_check_K"] = g.noise_floor_check_k;
  j["generate_wall_s"] = g.wall_s;
  return j;
}

}  // namespace btsm::sim::suite
