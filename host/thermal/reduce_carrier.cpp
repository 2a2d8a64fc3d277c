// Carriers of the module's per-channel models (common/model_blob.hpp: channel j may ride on the
// model of a slower channel h, T_j' = T_amb + a_j (T_j - T_amb) + c_j (T_h - T_amb) + u b_j).
//
// Why: after a stop a bearing relaxes towards what the housing or the shaft around it holds (a
// front bearing next to a hot shaft even warms for a while), and after a restart it warms back
// towards that within minutes. How far it has to go depends on how long and from which speed the
// spindle stopped; a pole scheduled on the time since the stop (fitted for one stop state) cannot
// know it, the carrier's state does. Measured on the demo's fitted network: the front bearing's
// plain model is 2.0 K off in a stop after the top speed, 1.3 K above the probe in a stop after
// 8000 rpm in the identification recordings, and the detector has to forgive that much.
//
// The rule, per channel j and candidate carrier h (another modelled channel, plain):
//   for each coupling share k (c_j = k (1 - a_j) of the plain model at the middle breakpoint; a
//   grid, then golden section around its best),
//   running poles: at each breakpoint the pole whose step response from cold (the carrier's
//     model riding along from cold) is closest in max norm to the network's, b_j DC-matched;
//   stopped: each stop phase's pole the closest in max norm over the phase to the network's free
//     response from the stop state at the cooling reference speed (the carrier's model cooling
//     alongside);
//   the candidate's error = its worst deviation from the network over the duty cycle (restarts
//     after 15, 30, 60-minute and 8 h stops from every speed, speed steps, drifting ambient).
// The best candidate replaces the plain model when it lowers that error by >= 10 %; a channel that
// carries another stays plain (no chains). All in double; quantize() does the fixed point.
#include "reduce.hpp"

#include "grid_golden_search.hpp"
#include "simulator.hpp"

#include <Eigen/LU>

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>

namespace btsm::thermal {
namespace {

// The coupling shares tried: kShares values evenly in (0, kMaxShare], then kShareRefinements golden
// steps around the best (c_j = share (1 - a_j) of the plain model; a share above 1 lets the
// refitted pole end up slower than the plain one).
const int kShares = 12;
const double kMaxShare = 4.0;
const int kShareRefinements = 8;


// The network's node rises every dt from x0 at one speed (heat on while running), `steps` steps.
std::vector<Eigen::VectorXd> network_rises(Simulator& sim, double speed, double dt, const Eigen::VectorXd& x0, long steps) {
  const StepMatrices& sm = sim.matrices(speed, dt);
  std::vector<Eigen::VectorXd> out;
  out.reserve(static_cast<std::size_t>(steps) + 1);
  Eigen::VectorXd x = x0;
  out.push_back(x);
  for (long k = 0; k < steps; ++k) {
    x = sm.Phi * x + (speed > 0 ? sm.drive : Eigen::VectorXd::Zero(x.size()));
    out.push_back(x);
  }
  return out;
}

struct Candidate {
  int channel = -1, carrier = -1;
  double share = 0, duty_K = 1e300;
  ReducedModelF64 model;  // the whole model with this channel riding
  std::array<double, kModelMaxBreakpoints> tau_s{};
  std::array<double, kModelEarlyStopPhases> stop_tau_s{};
};

}  // namespace

double duty_error(const ReducedModelF64& m, int j, int nd, const std::vector<double>& carrier_pred,
                  const std::vector<Eigen::VectorXd>& full, const std::vector<double>& speed,
                  const std::vector<double>& ambient, double start_c);

void fit_carriers(const Network& net, const Eigen::VectorXd& params, const ReduceOptions& o, ReducedModelF64& fm,
                  std::array<ChannelReduction, 5>& channels) {
  const double dt = o.dt_s;
  Simulator sim(net, params);
  // The duty cycle once: the network's node temperatures, speed and ambient per step.
  double top = 0;
  const auto segs = duty_segments(o, top);
  std::vector<Eigen::VectorXd> full;
  std::vector<double> speed, ambient;
  {
    Simulator d(net, params);
    d.reset(Eigen::VectorXd::Constant(net.node_count(), o.test_ambient_c));
    double t = 0;
    for (const auto& seg : segs) {
      const long steps = std::lround(seg.second / dt);
      for (long k = 0; k < steps; ++k, t += dt) {
        const double amb = o.test_ambient_c + std::sin(2 * M_PI * t / (8 * 3600.0));
        full.push_back(d.node_temp_c());
        speed.push_back(seg.first);
        ambient.push_back(amb);
        d.step(dt, seg.first, amb);
      }
    }
  }
  // The plain model over the duty cycle: every channel's prediction per step (the carriers' inputs)
  // and error.
  std::array<std::vector<double>, 5> plain_pred;
  std::array<double, 5> plain_duty{};
  {
    ReducedModelF64State st;
    init_at_ambient(fm, st, o.test_ambient_c);
    for (std::size_t k = 0; k < full.size(); ++k) {
      double pred[kModelChannels];
      step(fm, st, speed[k], ambient[k], pred);
      for (int ch = 0; ch < 5; ++ch) {
        const int nd = o.channel_node[static_cast<std::size_t>(ch)];
        if (nd < 0) continue;
        plain_pred[static_cast<std::size_t>(ch)].push_back(pred[ch]);
        plain_duty[static_cast<std::size_t>(ch)] = std::max(plain_duty[static_cast<std::size_t>(ch)], std::abs(pred[ch] - full[k][nd]));
      }
    }
  }

  // Network responses shared by every candidate: from cold at each breakpoint speed, and the free
  // response from the stop state at the cooling reference speed.
  const int nb = fm.n_breakpoints;
  const NodeMatrices m0 = assemble(net, params, 0.0);
  const ModalForm f0 = modal_form(m0);
  const double slowest = 1.0 / f0.lambda.minCoeff();
  const long horizon = std::lround(5.0 * slowest / dt);
  std::vector<std::vector<Eigen::VectorXd>> cold(static_cast<std::size_t>(nb));
  for (int i = 1; i < nb; ++i) {  // 5 of the speed's slowest time constants (as the plain fit)
    const double lmin = modal_form(assemble(net, params, fm.speed_rpm[i])).lambda.minCoeff();
    cold[static_cast<std::size_t>(i)] = network_rises(sim, fm.speed_rpm[i], dt, Eigen::VectorXd::Zero(net.node_count()), std::lround(5.0 / lmin / dt));
  }
  std::vector<Eigen::VectorXd> steady(static_cast<std::size_t>(nb));
  for (int i = 1; i < nb; ++i) {
    const NodeMatrices mi = assemble(net, params, fm.speed_rpm[i]);
    steady[static_cast<std::size_t>(i)] = mi.G.fullPivLu().solve(mi.heat_w);
  }
  const double ref_speed = o.cooling_reference_rpm > 0 ? o.cooling_reference_rpm : o.speeds_rpm[o.speeds_rpm.size() / 2];
  const NodeMatrices ms = assemble(net, params, ref_speed);
  const Eigen::VectorXd x_stop = ms.G.fullPivLu().solve(ms.heat_w);
  const std::vector<Eigen::VectorXd> cooling = network_rises(sim, 0.0, dt, x_stop, horizon);

  const double lo = std::log(0.1 * f0.lambda.minCoeff()), hi = std::log(10.0 * f0.lambda.maxCoeff());
  // Channel j on carrier h with coupling share `share`: poles refitted, error over the duty cycle.
  const auto evaluate = [&](int j, int h, double share) {
    const int nj = o.channel_node[static_cast<std::size_t>(j)], nh = o.channel_node[static_cast<std::size_t>(h)];
    Candidate c;
    c.channel = j;
    c.carrier = h;
    c.share = share;
    c.model = fm;
    ReducedModelF64& m = c.model;
    const double couple = share * (1.0 - fm.a[nb / 2][j]);
    m.carrier[j] = static_cast<uint8_t>(h + 1);
    m.couple[j] = couple;
    // Running breakpoints.
    for (int i = 1; i < nb; ++i) {
      const auto& y = cold[static_cast<std::size_t>(i)];
      const double ah = fm.a[i][h], bh = fm.b_K[i][h];
      const double rise_h = bh / (1.0 - ah);
      const double target = steady[static_cast<std::size_t>(i)][nj];  // DC match: the exact steady rise
      const auto err = [&](double log_p) {
        const double a = std::exp(-std::exp(log_p) * dt);
        const double b = (1.0 - a) * target - couple * rise_h;
        double x = 0, xh = 0, e = 0;
        for (std::size_t k = 0; k < y.size(); k += 1) {
          e = std::max(e, std::abs(x - y[k][nj]));
          const double xn = a * x + couple * xh + b;
          xh = ah * xh + bh;
          x = xn;
        }
        return e;
      };
      const double p = std::exp(grid_golden_minimize(err, lo, hi));
      m.a[i][j] = std::exp(-p * dt);
      m.b_K[i][j] = (1.0 - m.a[i][j]) * target - couple * rise_h;
      c.tau_s[static_cast<std::size_t>(i)] = 1.0 / p;
    }
    // Stop phases, then the late stop pole, each from where the previous phase's model ended.
    {
      double x = x_stop[nj], xh = x_stop[nh];
      std::size_t k0 = 0;
      for (int ph = 0; ph <= kModelEarlyStopPhases; ++ph) {
        const bool late = ph == kModelEarlyStopPhases || fm.stop_end_s[ph] == 0;
        const std::size_t k1 = late ? cooling.size() - 1 : std::min(cooling.size() - 1, static_cast<std::size_t>(std::lround(fm.stop_end_s[ph] / dt)));
        // The carrier's stop pole over this window (its own phases).
        std::vector<double> ah_k;
        for (std::size_t k = k0; k < k1; ++k) {
          const double ts = k * dt;
          int hp = kModelEarlyStopPhases;
          for (int q = 0; q < kModelEarlyStopPhases; ++q)
            if (fm.stop_end_s[q] != 0 && ts < fm.stop_end_s[q]) {
              hp = q;
              break;
            }
          ah_k.push_back(hp < kModelEarlyStopPhases ? fm.stop_a[hp][h] : fm.a[0][h]);
        }
        const auto run = [&](double a, double& xe, double& xhe) {
          double xx = x, xxh = xh, e = 0;
          for (std::size_t k = k0; k < k1; ++k) {
            e = std::max(e, std::abs(xx - cooling[k][nj]));
            const double xn = a * xx + couple * xxh;
            xxh = ah_k[k - k0] * xxh;
            xx = xn;
          }
          e = std::max(e, std::abs(xx - cooling[k1][nj]));
          xe = xx, xhe = xxh;
          return e;
        };
        const auto err = [&](double log_p) {
          double xe, xhe;
          return run(std::exp(-std::exp(log_p) * dt), xe, xhe);
        };
        const double p = std::exp(grid_golden_minimize(err, lo, hi));
        const double a = std::exp(-p * dt);
        run(a, x, xh);
        if (late) {
          m.a[0][j] = a;
          c.tau_s[0] = 1.0 / p;
          break;
        }
        m.stop_a[ph][j] = a;
        c.stop_tau_s[static_cast<std::size_t>(ph)] = 1.0 / p;
        k0 = k1;
      }
    }
    c.duty_K = duty_error(m, j, o.channel_node[static_cast<std::size_t>(j)], plain_pred[static_cast<std::size_t>(h)], full, speed, ambient, o.test_ambient_c);
    return c;
  };
  // best[j][h]: channel j's best candidate on carrier h -- a grid of shares, then golden section
  // around the grid's best.
  std::array<std::array<Candidate, 5>, 5> best;
  // Each pair costs a few dozen duty-cycle runs: minutes at a small dt, so say where it is.
  int pairs = 0, done = 0;
  for (int j = 0; j < 5; ++j)
    for (int h = 0; h < 5; ++h) pairs += h != j && o.channel_node[static_cast<std::size_t>(j)] >= 0 && o.channel_node[static_cast<std::size_t>(h)] >= 0;
  auto last_report = std::chrono::steady_clock::now();
  for (int j = 0; j < 5; ++j) {
    if (o.channel_node[static_cast<std::size_t>(j)] < 0) continue;
    for (int h = 0; h < 5; ++h) {
      if (o.channel_node[static_cast<std::size_t>(h)] < 0 || h == j) continue;
      if (const auto now = std::chrono::steady_clock::now(); o.progress && now - last_report > std::chrono::seconds(5)) {
        last_report = now;
        o.progress(fmt::format("carriers: channel pair {} of {}", done + 1, pairs));
      }
      ++done;
      Candidate& b = best[static_cast<std::size_t>(j)][static_cast<std::size_t>(h)];
      int arg = 0;
      for (int s = 1; s <= kShares; ++s) {
        Candidate c = evaluate(j, h, kMaxShare * s / kShares);
        if (c.duty_K < b.duty_K) b = std::move(c), arg = s;
      }
      double x0 = kMaxShare * (arg - 1) / kShares, x1 = kMaxShare * std::min(arg + 1, kShares) / kShares;
      const double g = (std::sqrt(5.0) - 1) / 2;
      for (int it = 0; it < kShareRefinements; ++it) {
        const double xa = x1 - g * (x1 - x0), xb = x0 + g * (x1 - x0);
        Candidate ca = evaluate(j, h, xa), cb = evaluate(j, h, xb);
        if (ca.duty_K < cb.duty_K) x1 = xb; else x0 = xa;
        if (ca.duty_K < b.duty_K) b = std::move(ca);
        if (cb.duty_K < b.duty_K) b = std::move(cb);
      }
    }
  }
  // The assignment (each channel plain or on one carrier; a carrier is plain itself) with the
  // smallest sum of squared duty-cycle errors; a carrier only where it cuts the channel's error by
  // >= 10 %. The channels' errors are independent given plain carriers, so every assignment is
  // scored from the candidates above (5 channels: at most 5^5 assignments).
  std::array<int, 5> choice{}, best_choice{};
  choice.fill(-1);
  best_choice.fill(-1);
  double best_score = 1e300;
  const auto err_of = [&](int j, int h) {
    const auto jj = static_cast<std::size_t>(j);
    if (h < 0) return plain_duty[jj];
    const double e = best[jj][static_cast<std::size_t>(h)].duty_K;
    return e <= 0.9 * plain_duty[jj] ? e : 1e300;
  };
  const auto search = [&](auto&& self, int j) -> void {
    if (j == 5) {
      double score = 0;
      for (int k = 0; k < 5; ++k) {
        if (o.channel_node[static_cast<std::size_t>(k)] < 0) continue;
        const int h = choice[static_cast<std::size_t>(k)];
        if (h >= 0 && choice[static_cast<std::size_t>(h)] >= 0) return;  // a carrier must be plain
        const double e = err_of(k, h);
        score += e * e;
      }
      if (score < best_score) best_score = score, best_choice = choice;
      return;
    }
    choice[static_cast<std::size_t>(j)] = -1;
    self(self, j + 1);
    if (o.channel_node[static_cast<std::size_t>(j)] < 0) return;
    for (int h = 0; h < 5; ++h) {
      if (h == j || o.channel_node[static_cast<std::size_t>(h)] < 0) continue;
      if (err_of(j, h) >= 1e300) continue;
      choice[static_cast<std::size_t>(j)] = h;
      self(self, j + 1);
    }
    choice[static_cast<std::size_t>(j)] = -1;
  };
  search(search, 0);
  for (int j = 0; j < 5; ++j) {
    const int h = best_choice[static_cast<std::size_t>(j)];
    if (h < 0) continue;
    const Candidate& c = best[static_cast<std::size_t>(j)][static_cast<std::size_t>(h)];
    for (int i = 0; i < fm.n_breakpoints; ++i) {
      fm.a[i][j] = c.model.a[i][j];
      fm.b_K[i][j] = c.model.b_K[i][j];
    }
    for (int k = 0; k < kModelEarlyStopPhases; ++k) fm.stop_a[k][j] = c.model.stop_a[k][j];
    fm.carrier[j] = c.model.carrier[j];
    fm.couple[j] = c.model.couple[j];
    ChannelReduction& cr = channels[static_cast<std::size_t>(j)];
    cr.carrier = h;
    cr.coupling_share = c.share;
    cr.plain_duty_K = plain_duty[static_cast<std::size_t>(j)];
    cr.carried_duty_K = c.duty_K;
    for (int i = 0; i < fm.n_breakpoints; ++i) cr.tau_s[static_cast<std::size_t>(i)] = c.tau_s[static_cast<std::size_t>(i)];
    for (int k = 0; k < kModelEarlyStopPhases; ++k)
      if (fm.stop_end_s[k] != 0) cr.stop_tau_s[static_cast<std::size_t>(k)] = c.stop_tau_s[static_cast<std::size_t>(k)];
  }
}

// Channel j's worst deviation (K) from node nd of the network over the duty cycle, stepping that
// channel alone (channel_update: the model's definition, as step() uses it) with its carrier's plain
// predictions as the carrier input.
double duty_error(const ReducedModelF64& m, int j, int nd, const std::vector<double>& carrier_pred,
                  const std::vector<Eigen::VectorXd>& full, const std::vector<double>& speed,
                  const std::vector<double>& ambient, double start_c) {
  double t = start_c, stopped_s = 1e300, e = 0;
  for (std::size_t k = 0; k < full.size(); ++k) {
    e = std::max(e, std::abs(t - full[k][nd]));
    const double amb = ambient[k];
    const ChannelUpdate u = channel_update(m, j, speed[k], stopped_s);
    const double carried = m.carrier[j] != kModelNoCarrier ? m.couple[j] * (carrier_pred[k] - amb) : 0.0;
    t = amb + u.a * (t - amb) + carried + u.b_K;
    stopped_s = speed[k] > 0 ? 0.0 : stopped_s + m.dt_ms * 1e-3;
  }
  return e;
}

}  // namespace btsm::thermal
