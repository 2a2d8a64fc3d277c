#pragma once
// Recordings of the spindle4 network with one effect of the library as the truth, simulated by the
// shared simulator: a short identification procedure (three warm-ups with natural cooling for the
// fit, a stepwise run for the check), 30 s samples, 5 mK noise, every node probed. The effect is
// expressed by residual::augment, so these tests check the library against itself: the plant-side
// effects (independent physics) are the undeclared-effect suite's job (host/sim/suite).
#include "host/residual/effects.hpp"
#include "host/thermal/declared_columns.hpp"
#include "host/thermal/simulator.hpp"

#include <cmath>
#include <map>
#include <random>
#include <string>
#include <vector>

namespace btsm::residual::test {

struct Programme {
  std::string name;
  std::vector<std::pair<double, double>> segments;  // (hours, rpm)
};

inline const std::vector<Programme>& fit_programmes() {
  static const std::vector<Programme> p = {
      {"warmup_4000", {{0.1, 0}, {3.0, 4000}, {2.0, 0}}},
      {"warmup_6000", {{0.1, 0}, {3.0, 6000}, {2.0, 0}}},
      {"warmup_8000", {{0.1, 0}, {3.0, 8000}, {2.0, 0}}},
  };
  return p;
}
inline const Programme& check_programme() {
  static const Programme p{"stepwise", {{0.1, 0}, {1.5, 3000}, {1.5, 5000}, {1.5, 7000}, {2.0, 0}}};
  return p;
}

struct Truth {
  EffectSpec spec;                         // kind Count = no effect
  std::map<std::string, double> values;    // effect parameter values (augment keys)
  bool ambient_varies = false;             // a room temperature that swings 1.5 K (8 h period)
  bool coolant_column = false;             // a declared coolant column cycling around 17 degC
  bool event_column = false;               // a declared lid_open column, opened twice per run
  bool no_effect = false;
  // s, every reading passed through a first-order filter of this lag (0: none) after the noise,
  // as a module's own filter does: a real lag of the measurement chain, not of the plant
  double reading_lag_s = 0;
  bool module_recording = false;           // metadata `module_id` (recorded from a BTSM module)
};

// One recording of the truth. Declared columns are declared in the metadata.
inline thermal::Recording simulate(const Programme& prog, const AugmentedModel& truth, const Truth& t, unsigned seed, double phase) {
  thermal::Recording rec;
  rec.source = prog.name + ".csv";
  const double dt = 30.0;
  double time = 0;
  for (const auto& [hours, rpm] : prog.segments)
    for (int k = 0; k < static_cast<int>(std::lround(hours * 3600 / dt)); ++k) {
      rec.time_s.push_back(time);
      rec.speed_rpm.push_back(rpm);
      rec.ambient_c.push_back(t.ambient_varies ? 21.0 + 1.5 * std::sin(2 * M_PI * time / (8 * 3600.0) + phase) : 21.0);
      time += dt;
    }
  const auto rows = static_cast<Eigen::Index>(rec.rows());
  std::vector<std::string> probes;
  for (const auto& m : truth.net.measurements) probes.push_back(m.column);
  rec.channels = probes;
  if (t.coolant_column) rec.channels.push_back("coolant_c");
  if (t.event_column) rec.channels.push_back("lid_open");
  rec.temp_c = Eigen::MatrixXd::Zero(rows, static_cast<Eigen::Index>(rec.channels.size()));
  if (t.coolant_column) {
    const int c = rec.channel_index("coolant_c");
    for (Eigen::Index k = 0; k < rows; ++k)
      rec.temp_c(k, c) = 17.0 + 1.0 * std::sin(2 * M_PI * rec.time_s[static_cast<std::size_t>(k)] / 2400.0 + phase);
  }
  if (t.event_column) {
    const int c = rec.channel_index("lid_open");
    const double len = rec.time_s.back();
    for (Eigen::Index k = 0; k < rows; ++k) {
      const double x = rec.time_s[static_cast<std::size_t>(k)] / len;
      rec.temp_c(k, c) = (x > 0.2 + 0.02 * phase && x < 0.25 + 0.02 * phase) || (x > 0.6 && x < 0.66) ? 1.0 : 0.0;
    }
  }
  std::vector<std::string> boundaries, events;
  if (t.coolant_column) boundaries.push_back("coolant_c");
  if (t.event_column) events.push_back("lid_open");
  thermal::declare_columns(rec, boundaries, events);
  if (t.module_recording) rec.meta.emplace_back("module_id", "0000de70");
  Eigen::MatrixXd extra;
  if (truth.transient_node >= 0) extra = transient_impulses_w(truth.net, truth.params, rec, truth.transient_node, truth.trigger);
  const Eigen::VectorXd x0 = Eigen::VectorXd::Constant(truth.net.node_count(), rec.ambient_c[0]);
  const Eigen::MatrixXd nodes = thermal::simulate_recording(truth.net, truth.params, rec, x0, truth.transient_node >= 0 ? &extra : nullptr);
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.005);
  const double gain = dt / (t.reading_lag_s + dt);  // a ramp read through it lags by reading_lag_s
  for (std::size_t j = 0; j < truth.net.measurements.size(); ++j) {
    const auto& m = truth.net.measurements[j];
    double filtered = 0;
    for (Eigen::Index k = 0; k < rows; ++k) {
      double v = nodes(k, m.node) + noise(rng);
      if (m.drift_param >= 0) v += truth.params[m.drift_param] * rec.time_s[static_cast<std::size_t>(k)] / 3600.0;
      filtered = k == 0 ? v : filtered + gain * (v - filtered);
      rec.temp_c(k, static_cast<Eigen::Index>(j)) = filtered;
    }
  }
  return rec;
}

struct Recordings {
  AugmentedModel truth;
  std::vector<thermal::Recording> fit, check;
};

inline Recordings make_recordings(const Truth& t, unsigned seed = 100) {
  const thermal::Network base = thermal::preset_network("spindle4");
  Recordings r;
  if (t.no_effect) {
    r.truth.net = base;
    r.truth.params = thermal::default_parameters(base);
  } else {
    r.truth = augment(base, thermal::default_parameters(base), t.spec, t.values);
  }
  double phase = 0;
  for (const auto& p : fit_programmes()) r.fit.push_back(simulate(p, r.truth, t, seed++, phase += 1.0));
  r.check.push_back(simulate(check_programme(), r.truth, t, seed++, phase += 1.0));
  return r;
}

}  // namespace btsm::residual::test
