// Linear screening of the effect dictionary (see screening.hpp).
#include "host/residual/screening.hpp"

#include "host/residual/evaluation.hpp"
#include "host/thermal/column_map.hpp"
#include "host/thermal/simulator.hpp"

#include <fmt/core.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <stdexcept>

namespace btsm::residual {
namespace th = btsm::thermal;
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A group of regressors that share a family and a variant; the regressors differ by the node (or
// column) they act on. A proposal is one group and a subset of its regressors.
struct Group {
  EffectSpec spec;           // family and variant, without nodes
  std::string variant;       // readable
  std::string variant_key;   // the variant without its time constant (for the stability match)
  bool output = false;       // regressors act on measured columns (sensor families)
  // the regressors of one column are taken together (a probe drift: its ramp and its offset in
  // every recording; the ramp, recording -1, leads)
  bool block_per_column = false;
  std::vector<int> regs;
};
struct Reg {
  int group = 0;
  int node = -1;             // heat regressors: the node acted on (-1: several, ambient_dynamics)
  int column = -1;           // output regressors: index of the measured column
  int recording = -1;        // a probe's offset: 1 at its column in this fit recording only
};
struct Dictionary {
  std::vector<Group> groups;
  std::vector<Reg> regs;
  int add_group(const Group& g) {
    groups.push_back(g);
    return static_cast<int>(groups.size()) - 1;
  }
  void add_reg(int g, int node, int column, int recording = -1) {
    regs.push_back({g, node, column, recording});
    groups[static_cast<std::size_t>(g)].regs.push_back(static_cast<int>(regs.size()) - 1);
  }
};

std::string minutes(double s) { return s < 120 ? fmt::format("{:.0f} s", s) : fmt::format("{:.0f} min", s / 60); }

bool wanted(const std::vector<EffectKind>& fam, EffectKind k) { return fam.empty() || std::find(fam.begin(), fam.end(), k) != fam.end(); }

std::vector<int> source_nodes(const th::Network& net) {
  std::vector<int> out;
  for (const auto& s : net.sources) {
    bool own = false;
    for (const auto& t : s.operating) own = own || !t.driven;
    if (own && std::find(out.begin(), out.end(), s.node) == out.end()) out.push_back(s.node);
  }
  std::sort(out.begin(), out.end());
  return out;
}

Dictionary build_dictionary(const th::Network& net, const ScreeningInput& in, const ScreeningOptions& o, double typical_dt) {
  Dictionary d;
  const int n = net.node_count();
  const int nc = static_cast<int>(net.measurements.size());
  const std::vector<int> src = source_nodes(net);
  const auto& fam = o.families;
  if (wanted(fam, EffectKind::HeatSourceTransient)) {
    struct V { TransientTrigger trig; bool mult; const char* text; };
    for (const V v : {V{TransientTrigger::SpeedIncrease, false, "additive, every speed increase"},
                      V{TransientTrigger::StartOrChange, false, "additive, every start or speed change"},
                      V{TransientTrigger::StartOrChange, true, "x friction law, every start or speed change"},
                      V{TransientTrigger::SpeedIncrease, true, "x friction law, every speed increase"}})
      for (double tau : {300.0, 600.0, 1200.0, 2400.0, 4800.0}) {
        Group g;
        g.spec.kind = EffectKind::HeatSourceTransient;
        g.spec.trigger = v.trig;
        g.spec.multiplicative = v.mult;
        g.spec.tau_s = tau;
        g.variant_key = v.text;
        g.variant = fmt::format("{}, tau {}", v.text, minutes(tau));
        const int gi = d.add_group(g);
        for (int i = 0; i < n; ++i)
          if (!v.mult || std::find(src.begin(), src.end(), i) != src.end()) d.add_reg(gi, i, -1);
      }
  }
  if (wanted(fam, EffectKind::TemperatureDependentHeat) && !src.empty()) {
    Group g;
    g.spec.kind = EffectKind::TemperatureDependentHeat;
    g.variant = g.variant_key = "heat x friction law x own rise";
    const int gi = d.add_group(g);
    for (int i : src) d.add_reg(gi, i, -1);
  }
  if (wanted(fam, EffectKind::CoupledHeat))
    for (int a = 0; a < n; ++a)
      for (int b = a + 1; b < n; ++b) {
        Group g;
        g.spec.kind = EffectKind::CoupledHeat;
        g.spec.hot = a;
        g.spec.cold = b;
        g.spec.speed_exponent = 1.0;
        g.variant = g.variant_key = fmt::format("(w/w0) x ({} - {})", net.nodes[static_cast<std::size_t>(a)].name,
                                                net.nodes[static_cast<std::size_t>(b)].name);
        const int gi = d.add_group(g);
        for (int i = 0; i < n; ++i) d.add_reg(gi, i, -1);
      }
  if (wanted(fam, EffectKind::ExtraHeatInput))
    for (double e : {0.0, 1.0, 2.0}) {
      Group g;
      g.spec.kind = EffectKind::ExtraHeatInput;
      g.spec.speed_exponent = e;
      g.variant = g.variant_key = fmt::format("(w/w0)^{:g} while running", e);
      const int gi = d.add_group(g);
      for (int i = 0; i < n; ++i) d.add_reg(gi, i, -1);
    }
  if (wanted(fam, EffectKind::SensorLag))
    for (double tau : {30.0, 60.0, 120.0, 240.0, 480.0, 900.0}) {
      if (tau < typical_dt) continue;  // a lag below the sampling step is not resolved
      Group g;
      g.spec.kind = EffectKind::SensorLag;
      g.spec.tau_s = tau;
      g.output = true;
      g.variant_key = "first-order lag";
      g.variant = fmt::format("first-order lag, tau {}", minutes(tau));
      const int gi = d.add_group(g);
      for (int c = 0; c < nc; ++c) d.add_reg(gi, -1, c);
    }
  if (wanted(fam, EffectKind::SensorDrift)) {
    Group g;
    g.spec.kind = EffectKind::SensorDrift;
    g.output = true;
    g.variant = g.variant_key = "linear in time, own offset per recording";
    // The recordings do not say how long the probe has drifted before each of them (no absolute
    // time), so its offset is one unknown per recording (as the refit has it, thermal/network.hpp):
    // a ramp alone would leave the steps between recordings, usually most of the signal, to the
    // base parameters.
    g.block_per_column = true;
    const int gi = d.add_group(g);
    const int R = static_cast<int>(in.fit->size());
    for (int c = 0; c < nc; ++c) {
      d.add_reg(gi, -1, c);
      for (int r = 0; r < R; ++r) d.add_reg(gi, -1, c, r);
    }
  }
  if (wanted(fam, EffectKind::AmbientDynamics)) {
    bool has_amb = false;
    for (const auto& l : net.links) has_amb = has_amb || l.b == th::kAmbient;
    if (has_amb)
      for (double tau : {900.0, 1800.0, 3600.0, 7200.0}) {
        Group g;
        g.spec.kind = EffectKind::AmbientDynamics;
        g.spec.tau_s = tau;
        g.variant_key = "lagged ambient at every ambient link";
        g.variant = fmt::format("lagged ambient, tau {}", minutes(tau));
        const int gi = d.add_group(g);
        d.add_reg(gi, -1, -1);
      }
  }
  if (wanted(fam, EffectKind::SecondBoundary))
    for (const auto& col : in.boundary_columns) {
      Group g;
      g.spec.kind = EffectKind::SecondBoundary;
      g.spec.column = col;
      g.variant = g.variant_key = "conductance to " + col;
      const int gi = d.add_group(g);
      for (int i = 0; i < n; ++i) d.add_reg(gi, i, -1);
    }
  if (wanted(fam, EffectKind::EventConductance))
    for (const auto& col : in.event_columns) {
      Group g;
      g.spec.kind = EffectKind::EventConductance;
      g.spec.column = col;
      g.variant = g.variant_key = "conductance to ambient while " + col + " = 1";
      const int gi = d.add_group(g);
      for (int i = 0; i < n; ++i) d.add_reg(gi, i, -1);
    }
  if (wanted(fam, EffectKind::LatentMass))
    for (double tau : {600.0, 1800.0, 3600.0, 7200.0, 14400.0}) {
      Group g;
      g.spec.kind = EffectKind::LatentMass;
      g.spec.tau_s = tau;
      g.variant_key = "mass tied to the node";
      g.variant = fmt::format("mass tied to the node, tau {}", minutes(tau));
      const int gi = d.add_group(g);
      for (int i = 0; i < n; ++i) d.add_reg(gi, i, -1);
    }
  return d;
}

// First-order lag of a series sampled at `t` (trapezoidal input over each step), from its first value.
std::vector<double> lowpass(const std::vector<double>& x, const std::vector<double>& t, double tau) {
  std::vector<double> y(x.size());
  if (x.empty()) return y;
  y[0] = x[0];
  for (std::size_t k = 0; k + 1 < x.size(); ++k) {
    const double a = std::exp(-(t[k + 1] - t[k]) / tau);
    y[k + 1] = a * y[k] + (1 - a) * 0.5 * (x[k] + x[k + 1]);
  }
  return y;
}

// What one fit recording contributes: base prediction, its Jacobian, the regressors' responses.
struct RecordingContext {
  const th::Recording* rec = nullptr;
  int index = 0;             // among the fit recordings
  Eigen::MatrixXd nodes_c;   // base node temperatures, rows x nodes
  Eigen::MatrixXd model_c;   // at the measured columns
  Eigen::MatrixXd resid;     // measured - model
};

// Heat input of every heat regressor over each row interval (rows x nodes per regressor) and the
// output regressors (rows x columns per regressor); `nullptr`-free slots for the other kind.
void regressor_series(const th::Network& net, const Eigen::VectorXd& p, const Dictionary& d, const RecordingContext& ctx,
                      std::vector<Eigen::MatrixXd>& heat, std::vector<Eigen::MatrixXd>& output) {
  const th::Recording& rec = *ctx.rec;
  const auto rows = static_cast<Eigen::Index>(rec.rows());
  const int n = net.node_count();
  const Eigen::Index nc = ctx.model_c.cols();
  std::vector<double> s(rec.rows()), run(rec.rows());
  for (std::size_t k = 0; k < rec.rows(); ++k) {
    s[k] = rec.speed_rpm[k] / net.speed_ref_rpm;
    run[k] = net.mode_at(rec.speed_rpm[k]) == th::Mode::Operating ? 1.0 : 0.0;
  }
  auto column_values = [&](const std::string& name) {
    const int c = rec.channel_index(name);
    if (c < 0) throw std::invalid_argument(rec.source + ": declared column '" + name + "' is missing");
    std::vector<double> v(rec.rows());
    for (std::size_t k = 0; k < rec.rows(); ++k) v[k] = rec.temp_c(static_cast<Eigen::Index>(k), c);
    return v;
  };
  std::map<std::pair<int, double>, std::vector<double>> decays;  // (trigger, tau) -> z
  auto decay = [&](TransientTrigger trig, double tau) -> const std::vector<double>& {
    const auto key = std::make_pair(static_cast<int>(trig), tau);
    auto it = decays.find(key);
    if (it != decays.end()) return it->second;
    const std::vector<double> u = transient_triggers(net, rec, trig, tau);  // StartOrChange restarts at one unit
    std::vector<double> z(rec.rows(), 0.0);
    for (std::size_t k = 0; k < rec.rows(); ++k) z[k] = (k ? z[k - 1] * std::exp(-(rec.time_s[k] - rec.time_s[k - 1]) / tau) : 0.0) + u[k];
    return decays.emplace(key, std::move(z)).first->second;
  };
  heat.assign(d.regs.size(), Eigen::MatrixXd());
  output.assign(d.regs.size(), Eigen::MatrixXd());
  for (std::size_t j = 0; j < d.regs.size(); ++j) {
    const Reg& r = d.regs[j];
    const Group& g = d.groups[static_cast<std::size_t>(r.group)];
    if (g.output) {
      Eigen::MatrixXd y = Eigen::MatrixXd::Zero(rows, nc);
      if (g.spec.kind == EffectKind::SensorLag) {
        std::vector<double> x(rec.rows());
        for (std::size_t k = 0; k < rec.rows(); ++k) x[k] = ctx.model_c(static_cast<Eigen::Index>(k), r.column);
        const std::vector<double> lp = lowpass(x, rec.time_s, g.spec.tau_s);
        for (Eigen::Index k = 0; k < rows; ++k) y(k, r.column) = lp[static_cast<std::size_t>(k)] - x[static_cast<std::size_t>(k)];
      } else if (r.recording >= 0) {  // SensorDrift: the probe's offset in one recording
        if (r.recording == ctx.index) y.col(r.column).setOnes();
      } else {  // SensorDrift: the ramp
        for (Eigen::Index k = 0; k < rows; ++k) y(k, r.column) = (rec.time_s[static_cast<std::size_t>(k)] - rec.time_s.front()) / 3600.0;
      }
      output[j] = std::move(y);
      continue;
    }
    Eigen::MatrixXd u = Eigen::MatrixXd::Zero(rows, n);
    const int i = r.node;
    auto node_series = [&](int node) {
      std::vector<double> v(rec.rows());
      for (std::size_t k = 0; k < rec.rows(); ++k) v[k] = ctx.nodes_c(static_cast<Eigen::Index>(k), node);
      return v;
    };
    switch (g.spec.kind) {
      case EffectKind::HeatSourceTransient: {
        const std::vector<double>& z = decay(g.spec.trigger, g.spec.tau_s);
        const double e = g.spec.multiplicative ? friction_exponent(net, i) : 0.0;
        for (Eigen::Index k = 0; k < rows; ++k) {
          const auto ku = static_cast<std::size_t>(k);
          u(k, i) = run[ku] * z[ku] * (e == 0.0 ? 1.0 : std::pow(s[ku], e));
        }
        break;
      }
      case EffectKind::TemperatureDependentHeat: {
        const double e = friction_exponent(net, i);
        for (Eigen::Index k = 0; k < rows; ++k) {
          const auto ku = static_cast<std::size_t>(k);
          u(k, i) = run[ku] * std::pow(s[ku], e) * (ctx.nodes_c(k, i) - rec.ambient_c[ku]);
        }
        break;
      }
      case EffectKind::CoupledHeat:
        for (Eigen::Index k = 0; k < rows; ++k) {
          const auto ku = static_cast<std::size_t>(k);
          u(k, i) = run[ku] * std::pow(s[ku], g.spec.speed_exponent) * (ctx.nodes_c(k, g.spec.hot) - ctx.nodes_c(k, g.spec.cold));
        }
        break;
      case EffectKind::ExtraHeatInput:
        for (Eigen::Index k = 0; k < rows; ++k) {
          const auto ku = static_cast<std::size_t>(k);
          u(k, i) = run[ku] * (g.spec.speed_exponent == 0.0 ? 1.0 : std::pow(s[ku], g.spec.speed_exponent));
        }
        break;
      case EffectKind::AmbientDynamics: {
        const std::vector<double> lp = lowpass(rec.ambient_c, rec.time_s, g.spec.tau_s);
        std::map<double, Eigen::VectorXd> g_amb;
        for (Eigen::Index k = 0; k < rows; ++k) {
          const auto ku = static_cast<std::size_t>(k);
          auto it = g_amb.find(rec.speed_rpm[ku]);
          if (it == g_amb.end()) it = g_amb.emplace(rec.speed_rpm[ku], th::assemble(net, p, rec.speed_rpm[ku]).ambient_conductance).first;
          u.row(k) = (it->second * (lp[ku] - rec.ambient_c[ku])).transpose();
        }
        break;
      }
      case EffectKind::SecondBoundary: {
        const std::vector<double> b = column_values(g.spec.column);
        for (Eigen::Index k = 0; k < rows; ++k) u(k, i) = b[static_cast<std::size_t>(k)] - ctx.nodes_c(k, i);
        break;
      }
      case EffectKind::EventConductance: {
        const std::vector<double> e = column_values(g.spec.column);
        for (Eigen::Index k = 0; k < rows; ++k) {
          const auto ku = static_cast<std::size_t>(k);
          u(k, i) = (e[ku] == 1.0 ? 1.0 : 0.0) * (rec.ambient_c[ku] - ctx.nodes_c(k, i));
        }
        break;
      }
      case EffectKind::LatentMass: {
        const std::vector<double> x = node_series(i);
        const std::vector<double> lp = lowpass(x, rec.time_s, g.spec.tau_s);
        for (Eigen::Index k = 0; k < rows; ++k) u(k, i) = lp[static_cast<std::size_t>(k)] - x[static_cast<std::size_t>(k)];
        break;
      }
      default: break;
    }
    heat[j] = std::move(u);
  }
}

// The projected normal equations of one resample: M = Z'(I - P_J)Z, cz = Z'(I - P_J)r.
struct Stats {
  Eigen::MatrixXd M;
  Eigen::VectorXd cz;
  double rss0 = 0;
  Eigen::MatrixXd Pb;   // A+ B: the base coefficients' response to the regressors
  Eigen::VectorXd Pa;   // A+ a: the base coefficients without any regressor
};

Stats project(const Eigen::MatrixXd& G, int q, int m) {
  Stats s;
  const Eigen::MatrixXd A = G.topLeftCorner(q, q);
  const Eigen::MatrixXd B = G.block(0, q, q, m);
  const Eigen::VectorXd a = G.block(0, q + m, q, 1);
  Eigen::VectorXd sc(q);
  for (int i = 0; i < q; ++i) sc[i] = A(i, i) > 0 ? 1.0 / std::sqrt(A(i, i)) : 0.0;
  const Eigen::MatrixXd As = sc.asDiagonal() * A * sc.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(As);
  const Eigen::VectorXd lam = es.eigenvalues();
  const double tol = 1e-10 * std::max(lam.maxCoeff(), 1e-300);
  Eigen::VectorXd inv(q);
  for (int i = 0; i < q; ++i) inv[i] = lam[i] > tol ? 1.0 / lam[i] : 0.0;
  // A+ = S V diag(inv) V' S
  const Eigen::MatrixXd W = sc.asDiagonal() * es.eigenvectors();
  const Eigen::MatrixXd Pb = W * (inv.asDiagonal() * (W.transpose() * B));   // A+ B
  const Eigen::VectorXd Pa = W * (inv.asDiagonal() * (W.transpose() * a));   // A+ a
  s.M = G.block(q, q, m, m) - B.transpose() * Pb;
  s.cz = G.block(q, q + m, m, 1) - Pb.transpose() * a;
  s.rss0 = G(q + m, q + m) - a.dot(Pa);
  s.Pb = Pb;
  s.Pa = Pa;
  return s;
}

double gain_of(const Stats& st, const std::vector<int>& set, Eigen::VectorXd* beta = nullptr) {
  if (set.empty()) return 0.0;
  const auto k = static_cast<Eigen::Index>(set.size());
  Eigen::MatrixXd Ms(k, k);
  Eigen::VectorXd c(k);
  for (Eigen::Index i = 0; i < k; ++i) {
    c[i] = st.cz[set[static_cast<std::size_t>(i)]];
    for (Eigen::Index j = 0; j < k; ++j) Ms(i, j) = st.M(set[static_cast<std::size_t>(i)], set[static_cast<std::size_t>(j)]);
  }
  Eigen::LDLT<Eigen::MatrixXd> ldlt(Ms);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-12 * std::max(Ms.diagonal().maxCoeff(), 1e-300))) return -1.0;
  const Eigen::VectorXd b = ldlt.solve(c);
  if (beta) *beta = b;
  return c.dot(b);
}

struct Selection {
  int group = -1;
  std::vector<int> regs;   // dictionary regressor indices
  double gain = 0, score = -std::numeric_limits<double>::infinity();
  Eigen::VectorXd beta;
};

double score_of(double rss0, double gain, std::size_t k, double n_eff) {
  if (!(gain > 0) || !(rss0 > gain)) return -std::numeric_limits<double>::infinity();
  return n_eff * std::log(rss0 / (rss0 - gain)) - static_cast<double>(k) * std::log(n_eff);
}

// Forward selection inside each group of one family; the best group by score.
Selection select_family(const Dictionary& d, const Stats& st, EffectKind kind, int max_nodes, double n_eff,
                         Selection* second = nullptr) {
  Selection best;
  std::vector<Selection> all;
  const double mscale = st.M.diagonal().cwiseAbs().maxCoeff();
  for (std::size_t gi = 0; gi < d.groups.size(); ++gi) {
    const Group& g = d.groups[gi];
    if (g.spec.kind != kind) continue;
    const int limit = g.output ? 1 : max_nodes;
    std::vector<int> set;
    double cur_score = 0, cur_gain = 0;
    bool first = true;
    while (static_cast<int>(set.size()) < limit) {
      int pick = -1;
      std::vector<int> pick_set;
      double pick_gain = cur_gain, pick_score = -std::numeric_limits<double>::infinity();
      for (int r : g.regs) {
        if (std::find(set.begin(), set.end(), r) != set.end()) continue;
        if (g.block_per_column && d.regs[static_cast<std::size_t>(r)].recording >= 0) continue;
        if (!(st.M(r, r) > 1e-12 * mscale)) continue;
        std::vector<int> trial = set;
        trial.push_back(r);
        if (g.block_per_column)
          for (int o : g.regs)
            if (o != r && d.regs[static_cast<std::size_t>(o)].column == d.regs[static_cast<std::size_t>(r)].column) trial.push_back(o);
        const double gn = gain_of(st, trial);
        if (gn < 0) continue;
        const double sc = score_of(st.rss0, gn, trial.size(), n_eff);
        if (sc > pick_score || (pick < 0 && first)) {
          pick = r;
          pick_set = trial;
          pick_gain = gn;
          pick_score = sc;
        }
      }
      if (pick < 0) break;
      // the first regressor of a group is always taken (so every family has a best group to
      // report); further ones only when they improve the criterion
      if (!first && !(pick_score > cur_score)) break;
      set = pick_set;
      cur_gain = pick_gain;
      cur_score = pick_score;
      first = false;
    }
    if (set.empty()) continue;
    Selection sel;
    sel.group = static_cast<int>(gi);
    sel.regs = set;
    sel.gain = cur_gain;
    sel.score = cur_score;
    if (sel.score > best.score || best.group < 0) best = sel;
    all.push_back(sel);
  }
  if (best.group >= 0) gain_of(st, best.regs, &best.beta);
  if (second && best.group >= 0) {
    // the best group of another variant (another trigger or coupling, exponent, pair, column).
    // For a transient, another TRIGGER first: the warm-ups (one start each) hardly tell the
    // triggers apart, only the amplitude's scaling with the start speed differs, while every later
    // speed step depends on it; the coupling (additive or x friction law) they do see.
    const Group& b = d.groups[static_cast<std::size_t>(best.group)];
    const auto pick_second = [&](bool other_trigger_only) {
      for (const auto& s2 : all) {
        const Group& g = d.groups[static_cast<std::size_t>(s2.group)];
        bool other = g.variant_key != b.variant_key || g.spec.hot != b.spec.hot || g.spec.cold != b.spec.cold ||
                     g.spec.speed_exponent != b.spec.speed_exponent || g.spec.column != b.spec.column;
        if (other_trigger_only) other = g.spec.trigger != b.spec.trigger;
        if (other && (second->group < 0 || s2.score > second->score)) *second = s2;
      }
    };
    if (b.spec.kind == EffectKind::HeatSourceTransient) pick_second(true);
    if (second->group < 0) pick_second(false);
    if (second->group >= 0) gain_of(st, second->regs, &second->beta);
  }
  return best;
}

std::vector<int> sorted_targets(const Dictionary& d, const Selection& s) {
  std::vector<int> t;
  for (int r : s.regs) t.push_back(d.regs[static_cast<std::size_t>(r)].node >= 0 ? d.regs[static_cast<std::size_t>(r)].node
                                                                                   : 1000 + d.regs[static_cast<std::size_t>(r)].column);
  std::sort(t.begin(), t.end());
  return t;
}

}  // namespace

ScreeningResult screen_effects(const ScreeningInput& in, const ScreeningOptions& o) {
  if (!in.net || !in.fit || in.fit->empty()) throw std::invalid_argument("screening: no network or no fit recordings");
  const th::Network& net = *in.net;
  const auto& recs = *in.fit;
  if (in.x0.size() != recs.size()) throw std::invalid_argument("screening: one initial state per fit recording is needed");
  const int n = net.node_count();
  const int nc = static_cast<int>(net.measurements.size());
  const int R = static_cast<int>(recs.size());
  const int p = static_cast<int>(in.free_params.size());
  const int q = p + n * R;
  // typical sampling step
  std::vector<double> dts;
  for (const auto& r : recs)
    for (std::size_t k = 1; k < r.rows(); ++k) dts.push_back(r.time_s[k] - r.time_s[k - 1]);
  std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2), dts.end());
  const double dt = dts.empty() ? 1.0 : dts[dts.size() / 2];
  const Dictionary dict = build_dictionary(net, in, o, dt);
  const int m = static_cast<int>(dict.regs.size());
  const int D = q + m + 1;
  ScreeningResult res;
  res.regressors = m;
  if (m == 0) return res;
  const int stride = std::max(1, static_cast<int>(std::lround(o.sample_step_s / dt)));
  const int nblocks = R * std::max(1, o.blocks_per_recording);
  std::vector<Eigen::MatrixXd> gram(static_cast<std::size_t>(nblocks), Eigen::MatrixXd::Zero(D, D));
  double rho_sum = 0;
  int rho_n = 0;

  for (int r = 0; r < R; ++r) {
    const th::Recording& rec = recs[static_cast<std::size_t>(r)];
    const std::vector<int> cols = th::measurement_columns(net, rec);
    RecordingContext ctx;
    ctx.rec = &rec;
    ctx.index = r;
    const Evaluation base = evaluate_model(net, in.params, rec, nullptr, &in.x0[static_cast<std::size_t>(r)]);
    ctx.nodes_c = base.nodes_c;
    ctx.model_c = base.model_c;
    ctx.resid = base.residual_k;
    const auto rows = static_cast<Eigen::Index>(rec.rows());
    // screening rows and cells
    std::vector<std::pair<Eigen::Index, int>> cells;
    for (Eigen::Index k = 0; k < rows; k += stride)
      for (int c = 0; c < nc; ++c)
        if (std::isfinite(ctx.resid(k, c))) cells.emplace_back(k, c);
    if (cells.empty()) continue;
    const auto ncell = static_cast<Eigen::Index>(cells.size());
    Eigen::MatrixXd V = Eigen::MatrixXd::Zero(ncell, D);
    // base parameters: forward differences in the fit's transformed space
    for (int j = 0; j < p; ++j) {
      const int pi = in.free_params[static_cast<std::size_t>(j)];
      const auto& par = net.params[static_cast<std::size_t>(pi)];
      Eigen::VectorXd pp = in.params;
      double h;
      if (par.log_scale) {
        h = 1e-4;
        pp[pi] *= std::exp(h);
      } else {
        h = 1e-4 * std::max(1.0, std::abs(in.params[pi]));
        pp[pi] += h;
      }
      const Evaluation e = evaluate_model(net, pp, rec, nullptr, &in.x0[static_cast<std::size_t>(r)]);
      for (Eigen::Index i = 0; i < ncell; ++i) V(i, j) = (e.model_c(cells[i].first, cells[i].second) - ctx.model_c(cells[i].first, cells[i].second)) / h;
    }
    // initial state: the response is affine in x0
    for (int i0 = 0; i0 < n; ++i0) {
      Eigen::VectorXd x = in.x0[static_cast<std::size_t>(r)];
      x[i0] += 1.0;
      const Evaluation e = evaluate_model(net, in.params, rec, nullptr, &x);
      for (Eigen::Index i = 0; i < ncell; ++i)
        V(i, p + r * n + i0) = e.model_c(cells[i].first, cells[i].second) - ctx.model_c(cells[i].first, cells[i].second);
    }
    // regressors: heat ones through the base network from rest (batched), output ones directly
    std::vector<Eigen::MatrixXd> heat, output;
    regressor_series(net, in.params, dict, ctx, heat, output);
    std::vector<int> heat_idx;
    for (int j = 0; j < m; ++j)
      if (heat[static_cast<std::size_t>(j)].size() > 0) heat_idx.push_back(j);
      else
        for (Eigen::Index i = 0; i < ncell; ++i) V(i, q + j) = output[static_cast<std::size_t>(j)](cells[i].first, cells[i].second);
    if (!heat_idx.empty()) {
      const th::RecordingInputs inputs = th::recording_inputs(net, rec);
      th::Simulator sim(net, in.params);
      const auto mh = static_cast<Eigen::Index>(heat_idx.size());
      Eigen::MatrixXd X = Eigen::MatrixXd::Zero(n, mh), U(n, mh), Xn(n, mh);
      std::size_t ci = 0;
      for (Eigen::Index k = 0; k < rows; ++k) {
        while (ci < cells.size() && cells[ci].first == k) {
          const int node = net.measurements[static_cast<std::size_t>(cells[ci].second)].node;
          for (Eigen::Index j = 0; j < mh; ++j) V(static_cast<Eigen::Index>(ci), q + heat_idx[static_cast<std::size_t>(j)]) = X(node, j);
          ++ci;
        }
        if (k + 1 == rows) break;
        const auto ku = static_cast<std::size_t>(k);
        const th::StepMatrices& sm = sim.matrices(rec.speed_rpm[ku], rec.time_s[ku + 1] - rec.time_s[ku],
                                                  inputs.event_mask.empty() ? 0u : inputs.event_mask[ku]);
        for (Eigen::Index j = 0; j < mh; ++j) U.col(j) = heat[static_cast<std::size_t>(heat_idx[static_cast<std::size_t>(j)])].row(k).transpose();
        Xn.noalias() = sm.Phi * X;
        Xn.noalias() += sm.Gamma * U;
        X.swap(Xn);
      }
    }
    for (Eigen::Index i = 0; i < ncell; ++i) V(i, D - 1) = ctx.resid(cells[i].first, cells[i].second);
    // lag-1 autocorrelation of the residual on the screening rows, per column
    for (int c = 0; c < nc; ++c) {
      std::vector<double> e;
      for (const auto& [k, cc] : cells)
        if (cc == c) e.push_back(ctx.resid(k, c));
      if (e.size() < 10) continue;
      double mean = 0;
      for (double v : e) mean += v;
      mean /= static_cast<double>(e.size());
      double c0 = 0, c1 = 0;
      for (std::size_t k = 0; k < e.size(); ++k) {
        c0 += (e[k] - mean) * (e[k] - mean);
        if (k) c1 += (e[k] - mean) * (e[k - 1] - mean);
      }
      if (c0 > 0) {
        rho_sum += c1 / c0;
        ++rho_n;
      }
    }
    // block Grams
    const int B = std::max(1, o.blocks_per_recording);
    for (int b = 0; b < B; ++b) {
      const Eigen::Index lo = rows * b / B, hi = rows * (b + 1) / B;
      Eigen::Index i0 = 0, i1 = 0;
      while (i0 < ncell && cells[static_cast<std::size_t>(i0)].first < lo) ++i0;
      i1 = i0;
      while (i1 < ncell && cells[static_cast<std::size_t>(i1)].first < hi) ++i1;
      if (i1 > i0) gram[static_cast<std::size_t>(r * B + b)].selfadjointView<Eigen::Lower>().rankUpdate(V.middleRows(i0, i1 - i0).transpose());
    }
    res.cells += static_cast<std::size_t>(ncell);
  }
  for (auto& G : gram) G.triangularView<Eigen::Upper>() = G.transpose();
  const double rho = rho_n ? std::clamp(rho_sum / rho_n, 0.0, 0.999) : 0.0;
  const double n_eff = std::clamp(static_cast<double>(res.cells) * (1 - rho) / (1 + rho), 10.0, static_cast<double>(std::max<std::size_t>(res.cells, 10)));
  res.effective_samples = n_eff;
  Eigen::MatrixXd total = Eigen::MatrixXd::Zero(D, D);
  for (const auto& G : gram) total += G;
  const Stats full = project(total, q, m);
  res.rss_base_k2 = full.rss0;

  std::vector<EffectKind> kinds;
  for (const auto& g : dict.groups)
    if (std::find(kinds.begin(), kinds.end(), g.spec.kind) == kinds.end()) kinds.push_back(g.spec.kind);
  std::vector<Selection> chosen, runner_up;
  for (EffectKind k : kinds) {
    Selection second;
    chosen.push_back(select_family(dict, full, k, o.max_nodes, n_eff, &second));
    runner_up.push_back(second);
  }

  // stability: the same selection on resamples of the time blocks
  std::vector<int> agree(kinds.size(), 0);
  std::mt19937 rng(o.seed);
  std::uniform_int_distribution<int> pick(0, nblocks - 1);
  for (int s = 0; s < o.resamples; ++s) {
    Eigen::MatrixXd G = Eigen::MatrixXd::Zero(D, D);
    for (int b = 0; b < nblocks; ++b) G += gram[static_cast<std::size_t>(pick(rng))];
    const Stats st = project(G, q, m);
    for (std::size_t f = 0; f < kinds.size(); ++f) {
      if (chosen[f].group < 0) continue;
      const Selection sel = select_family(dict, st, kinds[f], o.max_nodes, n_eff);
      if (sel.group < 0) continue;
      const Group& a = dict.groups[static_cast<std::size_t>(sel.group)];
      const Group& b = dict.groups[static_cast<std::size_t>(chosen[f].group)];
      const bool same_tau = (a.spec.tau_s == 0 && b.spec.tau_s == 0) ||
                            (a.spec.tau_s > 0 && b.spec.tau_s > 0 && std::abs(std::log(a.spec.tau_s / b.spec.tau_s)) < std::log(2.1));
      if (a.variant_key == b.variant_key && a.spec.hot == b.spec.hot && a.spec.cold == b.spec.cold &&
          a.spec.speed_exponent == b.spec.speed_exponent && a.spec.column == b.spec.column && same_tau &&
          sorted_targets(dict, sel) == sorted_targets(dict, chosen[f]))
        ++agree[f];
    }
  }

  auto make_proposal = [&](const Selection& s, double stability, bool alternative) {
    const Group& g = dict.groups[static_cast<std::size_t>(s.group)];
    Proposal pr;
    pr.alternative = alternative;
    pr.spec = g.spec;
    pr.variant = g.variant;
    for (std::size_t i = 0; i < s.regs.size(); ++i) {
      const Reg& rg = dict.regs[static_cast<std::size_t>(s.regs[i])];
      if (g.output) pr.spec.column = net.measurements[static_cast<std::size_t>(rg.column)].column;
      else if (rg.node >= 0) pr.spec.nodes.push_back(rg.node);
      pr.coefficients.push_back(s.beta.size() > static_cast<Eigen::Index>(i) ? s.beta[static_cast<Eigen::Index>(i)] : kNaN);
    }
    // coefficients in node order
    if (!g.output && pr.spec.nodes.size() > 1) {
      std::vector<std::pair<int, double>> nb;
      for (std::size_t i = 0; i < pr.spec.nodes.size(); ++i) nb.emplace_back(pr.spec.nodes[i], pr.coefficients[i]);
      std::sort(nb.begin(), nb.end());
      for (std::size_t i = 0; i < nb.size(); ++i) {
        pr.spec.nodes[i] = nb[i].first;
        pr.coefficients[i] = nb[i].second;
      }
    }
    pr.gain_k2 = s.gain;
    pr.rss_fraction = full.rss0 > 0 ? s.gain / full.rss0 : 0.0;
    pr.score = std::isfinite(s.score) ? s.score : -1e300;
    pr.stability = stability;
    // the base coefficients of the same regression: delta = A+ (a - B_S beta), free parameters only
    Eigen::VectorXd delta = full.Pa;
    for (std::size_t i = 0; i < s.regs.size() && static_cast<Eigen::Index>(i) < s.beta.size(); ++i)
      delta -= full.Pb.col(s.regs[i]) * s.beta[static_cast<Eigen::Index>(i)];
    pr.base_shift = delta.head(p);
    return pr;
  };
  for (std::size_t f = 0; f < kinds.size(); ++f) {
    if (chosen[f].group < 0) continue;
    res.proposals.push_back(make_proposal(chosen[f], o.resamples > 0 ? static_cast<double>(agree[f]) / o.resamples : 0.0, false));
    // a clearly different second variant that explains nearly as much gets its own proposal
    if (runner_up[f].group >= 0 && runner_up[f].gain >= 0.8 * chosen[f].gain && runner_up[f].score > 0)
      res.proposals.push_back(make_proposal(runner_up[f], 0.0, true));
  }
  std::sort(res.proposals.begin(), res.proposals.end(), [](const Proposal& a, const Proposal& b) { return a.score > b.score; });
  if (in.progress)
    for (const auto& pr : res.proposals)
      in.progress(fmt::format("residual:   {:<44} {:<52} explains {:5.1f} % (score {:.0f}, stable {:.0f} %){}", effect_label(pr.spec, net),
                              pr.variant, 100 * pr.rss_fraction, pr.score, 100 * pr.stability, pr.alternative ? ", second variant" : ""));
  return res;
}

}  // namespace btsm::residual
