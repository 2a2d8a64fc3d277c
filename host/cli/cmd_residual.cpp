// `btsm residual`: close the loop — fit the base model, test and trace its residual, and attribute
// it to an effect of the library, to "none" or to "unexplained" (host/residual/).
#include "cli_support.hpp"
#include "commands.hpp"
#include "host/residual/residual_loop.hpp"
#include "host/residual/residual_report.hpp"
#include "host/thermal/fit.hpp"
#include "host/thermal/heat_inverse.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"

#include <fmt/core.h>

#include <iostream>
#include <memory>
#include <sstream>

namespace btsm::cli {
namespace {

namespace th = btsm::thermal;
namespace rs = btsm::residual;

struct ResidualArgs {
  std::vector<std::string> fit, check;
  std::string preset, network, report_dir, effects;
  std::vector<std::string> columns;
  bool use_values = false, json = false;
  rs::LoopOptions opts;
};

void run_residual(ResidualArgs& a) {
  if (a.preset.empty() == a.network.empty()) throw CommandError(kExitUsage, "give exactly one of --preset NAME or --network NET.json");
  th::ModelWithParameters model;
  std::vector<th::Recording> fit, check;
  try {
    if (!a.preset.empty()) {
      model.network = th::preset_network(a.preset);
      model.params = th::default_parameters(model.network);
    } else if (a.use_values) {
      model = th::load_model_with_parameters(a.network);
    } else {
      model.network = th::load_network(a.network);
    }
    for (const auto& f : a.fit) fit.push_back(th::read_recording_csv(f));
    for (const auto& f : a.check) check.push_back(th::read_recording_csv(f));
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  std::vector<th::Recording> all = fit;
  all.insert(all.end(), check.begin(), check.end());
  try {
    const std::string said = th::map_measurements(model.network, all, a.columns);
    if (!said.empty()) std::cerr << "residual: from the recordings' channel roles:" << said << "\n";
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  if (!a.effects.empty()) {
    std::stringstream ss(a.effects);
    std::string name;
    while (std::getline(ss, name, ','))
      try {
        if (!name.empty()) a.opts.effects.push_back(rs::parse_effect_kind(name));
      } catch (const std::invalid_argument& e) {
        throw CommandError(kExitUsage, std::string("--effects: ") + e.what());
      }
  }
  a.opts.fit_base = !a.use_values;
  a.opts.progress = [](const std::string& s) { std::cerr << s << "\n"; };
  rs::LoopResult r;
  try {
    // without --use-values, network "initial"/"nominal" values only serve as fit starts
    Eigen::VectorXd start = a.use_values ? model.params : Eigen::VectorXd();
    r = rs::run_residual_loop(model.network, start, fit, check, a.opts);
  } catch (const std::invalid_argument& e) {
    throw CommandError(kExitUsage, e.what());
  }
  if (!a.report_dir.empty()) {
    try {
      rs::write_report(r, check, a.report_dir);
    } catch (const std::exception& e) {
      throw CommandError(kExitFailure, e.what());
    }
  }
  if (a.json) {
    print_json(rs::to_json(r));
  } else {
    std::cout << rs::format_table(r);
    if (!a.report_dir.empty())
      std::cout << "\n  report: " << a.report_dir
                << "/residual_result.json, residual_table.txt, residual_model.png, residual_residuals.png, residual_heat_trace.png\n";
  }
}

}  // namespace

void register_residual_commands(CLI::App& app) {
  auto a = std::make_shared<ResidualArgs>();
  CLI::App* cmd = app.add_subcommand(
      "residual",
      "Close the loop: fit the base thermal network on --fit recordings, test its residuals (whiteness per channel\n"
      "and mode, correlation with speed, speed changes, temperatures, ambient and rates), trace the unexplained heat\n"
      "flow per node (inverse method on the residual), then fit augmented models from the effect library\n"
      "(heat_source_transient, temperature_dependent_heat, sensor_lag, ambient_dynamics, extra_heat_input) and\n"
      "attribute the residual by check-recording error AND BIC AND parameter significance. Prints the effect (or\n"
      "'none' for a white residual, 'unexplained' for structure nothing explains) with its parameters +- 1 sigma\n"
      "and RMSE / NMSE / max error before and after on fit and check recordings.");
  cmd->add_option("--fit", a->fit, "Recording CSV(s) to fit on")->required()->check(CLI::ExistingFile);
  cmd->add_option("--check", a->check, "Recording CSV(s) to score on (not used for fitting)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--preset", a->preset, "Base network preset (spindle4)");
  cmd->add_option("--network", a->network, "Base network JSON (its measured columns must be in every recording)");
  cmd->add_option("--column", a->columns, "NODE=COLUMN: which recording column measures a node (repeatable; NODE= drops it)");
  cmd->add_flag("--use-values", a->use_values,
                "Do not refit the base: use the parameter values of --network (a fitted model) and fit only the effects");
  cmd->add_option("--effects", a->effects, "Comma-separated subset of the effect library to try (default: all)");
  cmd->add_option("--bic-margin", a->opts.bic_margin, "BIC decrease an effect must achieve on the fit recordings (default 10)");
  cmd->add_option("--check-improvement", a->opts.check_improvement, "Required ratio check RMSE before/after (default 1.25)");
  cmd->add_option("--param-z", a->opts.param_z, "Required |parameter| / sigma of the effect's key parameter (default 3)");
  cmd->add_option("--max-heat-nodes", a->opts.max_heat_nodes, "Heat effects are tried at this many nodes with the most traced heat (default 4)");
  cmd->add_option("--max-sensor-columns", a->opts.max_sensor_columns, "sensor_lag is tried on this many columns (default 2)");
  cmd->add_option("--iterations", a->opts.max_iterations, "Levenberg-Marquardt iterations per screening fit (default 60)");
  cmd->add_option("--refine-iterations", a->opts.refine_iterations, "Iterations for refining the best candidates and for the base fit (default 600)");
  cmd->add_option("--trace-step", a->opts.trace_step_s, "Step of the unexplained-heat trace [s] (default max(60 s, 10 samples))");
  cmd->add_option("--report", a->report_dir, "Write residual_result.json, residual_table.txt and plots (PNG + SVG) here");
  cmd->add_flag("--json", a->json, "Print the result as JSON on stdout");
  cmd->callback([a] { run_residual(*a); });
}

}  // namespace btsm::cli
