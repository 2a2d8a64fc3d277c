// `btsm residual`: close the loop — fit the base model, test and trace its residual, propose effects
// from it, refit them jointly with the base, and attribute the residual to an effect, a partial
// explanation, "none" or "unexplained" (host/residual/).
#include "cli_support.hpp"
#include "commands.hpp"
#include "host/io/output_file.hpp"
#include "host/io/utf8_text.hpp"
#include "host/residual/residual_loop.hpp"
#include "host/residual/residual_report.hpp"
#include "host/thermal/column_map.hpp"
#include "host/thermal/declared_columns.hpp"
#include "host/thermal/fit.hpp"
#include "host/thermal/heat_inverse.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"
#include "host/thermal/recording_metadata.hpp"

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
  std::vector<std::string> columns, boundaries, events;
  bool use_values = false, json = false;
  rs::LoopOptions opts;
};

void run_residual(ResidualArgs& a) {
  if (a.preset.empty() == a.network.empty()) throw CommandError(kExitUsage, "give exactly one of --preset NAME or --network NET.json");
  th::ModelWithParameters model;
  std::vector<th::Recording> fit, check;
  try {
    // before the loop, which may run for half an hour: an unwritable --report failed after it
    io::refuse_output_dir_that_cannot_be_made(a.report_dir, "--report", rs::report_files());
    if (!a.preset.empty()) {
      model.network = th::preset_network(a.preset);
      model.params = th::default_parameters(model.network);
    } else if (a.use_values) {
      model = th::load_model_with_parameters(a.network);
    } else {
      try {
        model.network = th::load_network(a.network);
      } catch (const std::invalid_argument& e) {
        // A fitted model given where a network is read fails on its extra fields ("unknown field
        // 'channel_map'"); say what the user meant instead.
        bool fitted_model = false;
        try {
          (void)th::load_model_with_parameters(a.network);
          fitted_model = true;
        } catch (const std::exception&) {
        }
        if (!fitted_model) throw;
        throw std::invalid_argument(a.network + ": a fitted model, not a network: add --use-values to keep its fitted values "
                                                "as the base, or give the network it was fitted with");
      }
    }
    for (const auto& f : a.fit) fit.push_back(th::read_recording_csv(f));
    for (const auto& f : a.check) check.push_back(th::read_recording_csv(f));
    for (auto* set : {&fit, &check})
      for (auto& r : *set) {
        th::declare_columns(r, a.boundaries, a.events);
        for (const std::string& w : th::reading_warnings(r)) std::cerr << "residual: WARNING: " << io::printable(w) << "\n";
      }
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  std::vector<th::Recording> all = fit;
  all.insert(all.end(), check.begin(), check.end());
  try {
    for (const auto& c : check)
      for (const auto& f : fit)
        if (th::same_samples(f, c))
          throw CommandError(kExitUsage, c.source + ": the check recording holds the same samples as the fit recording " + f.source +
                                             "; the check must be held out from the fit, or its error says nothing of an effect");
        else if (const std::string how = th::repeated_samples(f, c); !how.empty())
          throw CommandError(kExitUsage, c.source + ": the check recording repeats the samples of the fit recording " + f.source + " (" +
                                             how + "); the check must be held out from the fit, or its error says nothing of an effect");
        else if (const std::string held = th::repeated_samples(c, f); !held.empty())
          throw CommandError(kExitUsage, c.source + ": the check recording holds the samples of the fit recording " + f.source + " (" +
                                             held + "); the check must be held out from the fit, or its error says nothing of an effect");
    th::refuse_repeated_recordings(all);
  } catch (const std::invalid_argument& e) {
    throw CommandError(kExitUsage, e.what());
  }
  try {
    if (a.use_values) {
      // a fitted model says itself which column measures which node; only --column changes that
      th::check_mapping_agrees_with_roles(model.network, model.channel_map, all, a.columns,
                                          "say which with --column NODE=COLUMN, or refit the model with these recordings");
      th::remap_measurements(model.network, a.columns);
      std::string said;
      for (const auto& m : model.network.measurements) said += " " + model.network.nodes[static_cast<std::size_t>(m.node)].name + "=" + m.column;
      std::cerr << "residual: the model's own column mapping:" << said << "\n";
    } else {
      const std::string said = th::map_measurements(model.network, all, a.columns);
      if (!said.empty()) std::cerr << "residual: from the recordings' channel roles:" << said << given_columns(a.columns) << "\n";
    }
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
    // an empty list would mean "every family", the opposite of what a list says
    if (a.opts.effects.empty()) throw CommandError(kExitUsage, "--effects '" + a.effects + "': names no effect family");
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
  // The base fit's warnings (parameters started from their peers because the cooling data left
  // them unsettled, weakly or not identifiable ones, an iteration limit), as `btsm fit` prints
  // them: the candidates are judged against that base, so its weak spots must be visible here too.
  for (const auto& w : r.base_fit.warnings) std::cerr << "residual: base fit warning: " << w << "\n";
  if (!a.report_dir.empty()) {
    try {
      rs::write_report(r, check, a.report_dir, fit.empty() ? nullptr : &fit.front());
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
      "and mode, correlations), trace the unexplained heat per node, regress the residual on a dictionary of physical\n"
      "regressors (what the base refit would absorb projected out, stability over time-block resamples), refit the\n"
      "best proposals jointly with every base parameter from several starts, and decide on held-out evidence:\n"
      "BIC on the fit recordings, parameter significance and identifiability, check-recording RMSE. Families:\n"
      "heat_source_transient, temperature_dependent_heat, coupled_heat, extra_heat_input, sensor_lag, sensor_drift,\n"
      "ambient_dynamics, second_boundary, event_conductance, latent_mass. Verdict: effect, partial (explains part of\n"
      "the check error only; reported, never claimed), none (nothing beyond noise) or unexplained; with the effect's\n"
      "quantities in physical terms and RMSE / NMSE / max error before and after on fit and check recordings.");
  cmd->add_option("--fit", a->fit, "Recording CSV(s) to fit on")->required()->check(existing_input_file());
  cmd->add_option("--check", a->check, "Recording CSV(s) to score on (not used for fitting)")->required()->check(existing_input_file());
  cmd->add_option("--preset", a->preset, "Base network preset (spindle4)");
  cmd->add_option("--network", a->network, "Base network JSON, or with --use-values a fitted model (its measured columns must be in every recording)");
  cmd->add_option("--column", a->columns, "NODE=COLUMN: which recording column measures a node (repeatable; NODE= drops it)");
  cmd->add_option("--boundary", a->boundaries,
                  "COL: declare a recorded column as a second thermal boundary (degC, e.g. coolant), as '# boundary_columns' does (repeatable)");
  cmd->add_option("--event", a->events, "COL: declare a recorded 0/1 column as a switch event, as '# event_columns' does (repeatable)");
  cmd->add_flag("--use-values", a->use_values,
                "Do not refit the base: use the parameter values (and column mapping) of --network, a fitted model, and fit only the effects");
  cmd->add_option("--effects", a->effects, "Comma-separated subset of the effect families to try (default: all)");
  cmd->add_option("--bic-margin", a->opts.bic_margin, "BIC decrease an effect must achieve on the fit recordings (default 10)")
      ->check(CLI::Range(0.0, 1.0e6));
  cmd->add_option("--check-improvement", a->opts.check_improvement, "Required ratio check RMSE before/after (default 1.25)")
      ->check(CLI::Range(1.0, 1.0e6));
  cmd->add_option("--explained-factor", a->opts.explained_factor,
                  "Check RMSE cut that counts as explaining the residual; less is 'partial' (default 2)")
      ->check(CLI::Range(1.0, 1.0e6));
  cmd->add_option("--param-z", a->opts.param_z, "Required |parameter| / sigma of the effect's key parameters (default 3)")
      ->check(non_negative_number());
  cmd->add_option("--max-candidates", a->opts.max_candidates, "Proposals refitted jointly, best screening score first; while they repeat a family at the same nodes, further distinct ones until this many distinct explanations are refitted (default 4)")
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--iterations", a->opts.max_iterations, "Levenberg-Marquardt iterations of each start's effect-only stage (default 60)")
      ->check(CLI::Range(1, 1000000));
  cmd->add_option("--refine-iterations", a->opts.refine_iterations, "Iterations of each joint refit and of the base fit (default 300; one still descending at it goes on in chunks of 100 while a chunk gains > 0.1 %, up to 3x)")
      ->check(CLI::Range(1, 1000000));
  cmd->add_option("--refit-step", a->opts.refit_step_s,
                  "Step [s] of the decimated fit recordings the candidate refits run on; the chosen one is polished at full rate (default 10)")
      ->check(positive_number());
  cmd->add_option("--threads", a->opts.threads,
                  "Independent refits run at once (default 0 = the machine's cores; the result does not depend on it)")
      ->check(CLI::Range(0, 1024));
  cmd->add_option("--trace-step", a->opts.trace_step_s, "Step of the unexplained-heat trace [s] (default max(60 s, 10 samples))")
      ->check(non_negative_number());
  cmd->add_option("--report", a->report_dir, "Write residual_result.json, residual_table.txt and plots (PNG + SVG) here")
      ->transform([](std::string dir) {  // "dir/" printed "dir//file"
        while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
        return dir;
      });
  cmd->add_flag("--json", a->json, "Print the result as JSON on stdout");
  cmd->callback([a] { run_residual(*a); });
}

}  // namespace btsm::cli
