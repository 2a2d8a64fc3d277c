// Thermal network fitting: equation-error starts, Levenberg-Marquardt output-error stages with
// forward sensitivities, Gauss-Newton covariance and identifiability diagnostics.
#include "fit.hpp"

#include "simulator.hpp"

#include "common/wire_messages.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <sstream>
#include <thread>
#include <stdexcept>

namespace btsm::thermal {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// A contiguous row range [begin, end] (inclusive) of a recording used as one experiment.
struct Run {
  const Recording* rec = nullptr;
  std::size_t begin = 0, end = 0;
  std::vector<int> cols;               // recording channel per measurement
  const Eigen::MatrixXd* extra = nullptr;
  int recording_index = -1;            // index into the caller's recordings (-1 = sub-range)
};

struct Transform {
  bool log = true;
  double zmin = 0, zmax = 0;
  double to_p(double z) const { return log ? std::exp(z) : z; }
  double dp_dz(double z) const { return log ? std::exp(z) : 1.0; }
  double to_z(double p) const { return log ? std::log(p) : p; }
};

Transform transform_of(const Parameter& par) {
  Transform t;
  t.log = par.log_scale;
  t.zmin = t.to_z(par.min);
  t.zmax = t.to_z(par.max);
  return t;
}

// Which parameters a mode uses (capacitances are used by both).
std::vector<bool> params_used(const Network& net, Mode mode) {
  std::vector<bool> used(static_cast<std::size_t>(net.param_count()), false);
  for (const auto& n : net.nodes) used[static_cast<std::size_t>(n.capacitance_param)] = true;
  for (const auto& l : net.links)
    for (const auto& t : mode == Mode::Operating ? l.operating : l.cooling) used[static_cast<std::size_t>(t.param)] = true;
  for (const auto& s : net.sources)
    for (const auto& t : mode == Mode::Operating ? s.operating : s.cooling) used[static_cast<std::size_t>(t.param)] = true;
  return used;
}

// ---------------------------------------------------------------------------------------------
// Output-error problem: free parameters (transformed) + optional per-run initial states.
struct LmProblem {
  const Network* net = nullptr;
  std::vector<Run> runs;
  std::vector<int> free;               // parameter indices
  std::vector<Transform> tf;
  Eigen::VectorXd p;                   // all parameter values
  bool estimate_x0 = true;
  std::vector<Eigen::VectorXd> x0;
  double sum_c = kNaN;
  int n() const { return net->node_count(); }
  int nf() const { return static_cast<int>(free.size()); }
  int unknowns() const { return nf() + (estimate_x0 ? static_cast<int>(runs.size()) * n() : 0); }
};

struct KeyData {
  StepMatrices base;
  Eigen::MatrixXd dphi_stack;   // (n*nf) x n, block j = dPhi/dz_j
  Eigen::MatrixXd dgamma_stack; // (n*nf) x n, only when extra heat is used
  Eigen::MatrixXd ddrive;       // n x nf
  Eigen::MatrixXd damb;         // n x nf
};

struct Evaluation {
  double ssr = 0;        // data residuals only
  double cost = 0;       // 0.5 (ssr + gauge^2)
  std::size_t count = 0;
  Eigen::MatrixXd H;     // J^T J
  Eigen::VectorXd g;     // J^T r
};

class LmEvaluator {
 public:
  explicit LmEvaluator(LmProblem& pr) : pr_(pr) {
    for (Mode m : {Mode::Operating, Mode::Cooling}) used_[m == Mode::Operating ? 0 : 1] = params_used(*pr.net, m);
    for (const auto& r : pr.runs) uses_extra_ = uses_extra_ || r.extra != nullptr;
  }

  // Sets parameters from u and evaluates; with_jacobian fills H and g.
  Evaluation evaluate(const Eigen::VectorXd& u, bool with_jacobian) {
    apply(u);
    build_keys(with_jacobian);
    const int local = pr_.nf() + (pr_.estimate_x0 ? pr_.n() : 0);
    const int nu = pr_.unknowns();
    // Runs are independent given the parameters: spread them over the cores.
    const std::size_t nruns = pr_.runs.size();
    const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
    const std::size_t workers = std::min<std::size_t>({nruns, hw, 4});
    std::vector<Evaluation> part(workers);
    for (auto& e : part)
      if (with_jacobian) {
        e.H = Eigen::MatrixXd::Zero(nu, nu);
        e.g = Eigen::VectorXd::Zero(nu);
      }
    // Longest runs first, round-robin, for balance.
    std::vector<std::size_t> order(nruns);
    for (std::size_t i = 0; i < nruns; ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return pr_.runs[a].end - pr_.runs[a].begin > pr_.runs[b].end - pr_.runs[b].begin;
    });
    auto work = [&](std::size_t w) {
      for (std::size_t i = w; i < nruns; i += workers) evaluate_run(order[i], with_jacobian, local, part[w]);
    };
    if (workers <= 1) {
      work(0);
    } else {
      std::vector<std::thread> threads;
      for (std::size_t w = 1; w < workers; ++w) threads.emplace_back(work, w);
      work(0);
      for (auto& t : threads) t.join();
    }
    Evaluation ev = std::move(part[0]);
    for (std::size_t w = 1; w < workers; ++w) {
      ev.ssr += part[w].ssr;
      ev.count += part[w].count;
      if (with_jacobian) {
        ev.H += part[w].H;
        ev.g += part[w].g;
      }
    }
    ev.cost = 0.5 * ev.ssr;
    gauge(u, with_jacobian, ev);
    return ev;
  }

  void evaluate_run(std::size_t ri, bool with_jacobian, int local, Evaluation& ev) const {
    const int n = pr_.n(), nf = pr_.nf();
    constexpr int kBlock = 512;
    Eigen::MatrixXd jbuf(kBlock, local);
    Eigen::VectorXd rbuf(kBlock);
    Eigen::MatrixXd S(n, nf), X(n, n), Snext(n, nf), Xnext(n, n), D(n, nf);
    Eigen::VectorXd x(n), xnext(n), dv(n * nf), extra(n);
    {
      const Run& run = pr_.runs[ri];
      const Recording& rec = *run.rec;
      Eigen::MatrixXd Hl;
      Eigen::VectorXd gl;
      if (with_jacobian) {
        Hl = Eigen::MatrixXd::Zero(local, local);
        gl = Eigen::VectorXd::Zero(local);
      }
      int fill = 0;
      auto flush = [&] {
        if (fill == 0) return;
        Hl.selfadjointView<Eigen::Lower>().rankUpdate(jbuf.topRows(fill).transpose());
        gl.noalias() += jbuf.topRows(fill).transpose() * rbuf.head(fill);
        fill = 0;
      };
      x = pr_.x0[ri];
      S.setZero();
      X.setIdentity();
      for (std::size_t k = run.begin; k <= run.end; ++k) {
        const auto kr = static_cast<Eigen::Index>(k);
        for (std::size_t m = 0; m < run.cols.size(); ++m) {
          const double y = rec.temp_c(kr, run.cols[m]);
          if (!std::isfinite(y)) continue;
          const int node = pr_.net->measurements[m].node;
          const double r = x[node] - y;
          ev.ssr += r * r;
          ++ev.count;
          if (with_jacobian) {
            jbuf.row(fill).head(nf) = S.row(node);
            if (pr_.estimate_x0) jbuf.row(fill).tail(n) = X.row(node);
            rbuf[fill] = r;
            if (++fill == kBlock) flush();
          }
        }
        if (k == run.end) break;
        const double dt = rec.time_s[k + 1] - rec.time_s[k];
        const double amb = rec.ambient_c[k];
        const KeyData& kd = keys_.find(std::make_pair(rec.speed_rpm[k], dt))->second;
        xnext.noalias() = kd.base.Phi * x;
        xnext += kd.base.drive + kd.base.ambient_gain * amb;
        if (run.extra) {
          extra = run.extra->row(kr).transpose();
          xnext.noalias() += kd.base.Gamma * extra;
        }
        if (with_jacobian) {
          dv.noalias() = kd.dphi_stack * x;
          if (run.extra) dv.noalias() += kd.dgamma_stack * extra;
          D = Eigen::Map<const Eigen::MatrixXd>(dv.data(), n, nf);
          D += kd.ddrive + kd.damb * amb;
          Snext.noalias() = kd.base.Phi * S;
          S = Snext + D;
          if (pr_.estimate_x0) {
            Xnext.noalias() = kd.base.Phi * X;
            X = Xnext;
          }
        }
        x = xnext;
      }
      if (with_jacobian) {
        flush();
        Hl.triangularView<Eigen::Upper>() = Hl.transpose();
        ev.H.topLeftCorner(nf, nf) += Hl.topLeftCorner(nf, nf);
        ev.g.head(nf) += gl.head(nf);
        if (pr_.estimate_x0) {
          const int off = nf + static_cast<int>(ri) * n;
          ev.H.block(off, off, n, n) += Hl.bottomRightCorner(n, n);
          ev.H.block(0, off, nf, n) += Hl.topRightCorner(nf, n);
          ev.H.block(off, 0, n, nf) += Hl.bottomLeftCorner(n, nf);
          ev.g.segment(off, n) += gl.tail(n);
        }
      }
    }
  }

  // Scale gauge as a stiff residual on log(sum C).
  void gauge(const Eigen::VectorXd& u, bool with_jacobian, Evaluation& ev) const {
    const int nf = pr_.nf();
    const int nu = pr_.unknowns();
    if (std::isfinite(pr_.sum_c)) {
      double sum = 0;
      for (const auto& nd : pr_.net->nodes) sum += pr_.p[nd.capacitance_param];
      const double rg = kGaugeWeight * std::log(sum / pr_.sum_c);
      ev.cost += 0.5 * rg * rg;
      if (with_jacobian) {
        Eigen::VectorXd jg = Eigen::VectorXd::Zero(nu);
        for (int j = 0; j < nf; ++j)
          for (const auto& nd : pr_.net->nodes)
            if (nd.capacitance_param == pr_.free[static_cast<std::size_t>(j)])
              jg[j] += kGaugeWeight * pr_.tf[static_cast<std::size_t>(j)].dp_dz(u[j]) / sum;
        ev.H += jg * jg.transpose();
        ev.g += jg * rg;
      }
    }
  }

  void apply(const Eigen::VectorXd& u) {
    for (int j = 0; j < pr_.nf(); ++j) pr_.p[pr_.free[static_cast<std::size_t>(j)]] = pr_.tf[static_cast<std::size_t>(j)].to_p(u[j]);
    if (pr_.estimate_x0)
      for (std::size_t r = 0; r < pr_.runs.size(); ++r)
        pr_.x0[r] = u.segment(pr_.nf() + static_cast<int>(r) * pr_.n(), pr_.n());
  }

  static constexpr double kGaugeWeight = 1e4;

 private:
  void build_keys(bool with_jacobian) {
    keys_.clear();
    const int n = pr_.n(), nf = pr_.nf();
    std::map<double, ModalForm> modal;
    for (const auto& run : pr_.runs) {
      const Recording& rec = *run.rec;
      for (std::size_t k = run.begin; k < run.end; ++k) {
        const auto key = std::make_pair(rec.speed_rpm[k], rec.time_s[k + 1] - rec.time_s[k]);
        if (keys_.count(key)) continue;
        auto mit = modal.find(key.first);
        if (mit == modal.end()) mit = modal.emplace(key.first, modal_form(assemble(*pr_.net, pr_.p, key.first))).first;
        KeyData kd;
        kd.base = step_matrices(mit->second, key.second);
        if (with_jacobian) {
          kd.dphi_stack = Eigen::MatrixXd::Zero(n * nf, n);
          if (uses_extra_) kd.dgamma_stack = Eigen::MatrixXd::Zero(n * nf, n);
          kd.ddrive = Eigen::MatrixXd::Zero(n, nf);
          kd.damb = Eigen::MatrixXd::Zero(n, nf);
          const auto& used = used_[pr_.net->mode_at(key.first) == Mode::Operating ? 0 : 1];
          for (int j = 0; j < nf; ++j) {
            const int pi = pr_.free[static_cast<std::size_t>(j)];
            if (!used[static_cast<std::size_t>(pi)]) continue;
            const Transform& tf = pr_.tf[static_cast<std::size_t>(j)];
            const double p0 = pr_.p[pi];
            const double z0 = tf.to_z(p0);
            const double h = tf.log ? 1e-5 : 1e-5 * std::max(1.0, std::abs(p0));
            Eigen::VectorXd pp = pr_.p, pm = pr_.p;
            pp[pi] = tf.to_p(z0 + h);
            pm[pi] = tf.to_p(z0 - h);
            const StepMatrices sp = step_matrices(modal_form(assemble(*pr_.net, pp, key.first)), key.second);
            const StepMatrices sm = step_matrices(modal_form(assemble(*pr_.net, pm, key.first)), key.second);
            const double inv = 1.0 / (2 * h);
            kd.dphi_stack.middleRows(j * n, n) = (sp.Phi - sm.Phi) * inv;
            if (uses_extra_) kd.dgamma_stack.middleRows(j * n, n) = (sp.Gamma - sm.Gamma) * inv;
            kd.ddrive.col(j) = (sp.drive - sm.drive) * inv;
            kd.damb.col(j) = (sp.ambient_gain - sm.ambient_gain) * inv;
          }
          // dv = dphi_stack * x is laid out block-wise (j*n + i); the evaluator maps it as an
          // n x nf column-major matrix, which is exactly that layout.
        }
        keys_.emplace(key, std::move(kd));
      }
    }
  }

  LmProblem& pr_;
  std::vector<bool> used_[2];
  bool uses_extra_ = false;
  std::map<std::pair<double, double>, KeyData> keys_;
};

struct LmOutcome {
  Evaluation ev;       // at the solution, with Jacobian
  Eigen::VectorXd u;
  int iterations = 0;
  bool converged = false;
};

Eigen::VectorXd pack(const LmProblem& pr) {
  Eigen::VectorXd u(pr.unknowns());
  for (int j = 0; j < pr.nf(); ++j) u[j] = pr.tf[static_cast<std::size_t>(j)].to_z(pr.p[pr.free[static_cast<std::size_t>(j)]]);
  if (pr.estimate_x0)
    for (std::size_t r = 0; r < pr.runs.size(); ++r) u.segment(pr.nf() + static_cast<int>(r) * pr.n(), pr.n()) = pr.x0[r];
  return u;
}

void clamp_to_bounds(const LmProblem& pr, Eigen::VectorXd& u) {
  for (int j = 0; j < pr.nf(); ++j) {
    const Transform& t = pr.tf[static_cast<std::size_t>(j)];
    u[j] = std::clamp(u[j], t.zmin, t.zmax);
  }
}

LmOutcome levenberg_marquardt(LmProblem& pr, const FitOptions& opts) {
  LmEvaluator evaluator(pr);
  LmOutcome out;
  Eigen::VectorXd u = pack(pr);
  clamp_to_bounds(pr, u);
  Evaluation ev = evaluator.evaluate(u, true);
  double mu = 1e-3;
  for (int it = 0; it < opts.max_iterations; ++it) {
    out.iterations = it + 1;
    bool accepted = false;
    for (int attempt = 0; attempt < 12 && !accepted; ++attempt) {
      Eigen::MatrixXd A = ev.H;
      Eigen::VectorXd g = ev.g;
      for (Eigen::Index i = 0; i < A.rows(); ++i) A(i, i) += mu * std::max(ev.H(i, i), 1e-12);
      // Variables at a bound whose descent direction points outside stay put this iteration
      // (a clamped Gauss-Newton step is not a descent step in general).
      for (int j = 0; j < pr.nf(); ++j) {
        const Transform& t = pr.tf[static_cast<std::size_t>(j)];
        if ((u[j] <= t.zmin && g[j] > 0) || (u[j] >= t.zmax && g[j] < 0)) {
          A.row(j).setZero();
          A.col(j).setZero();
          A(j, j) = 1.0;
          g[j] = 0.0;
        }
      }
      Eigen::VectorXd delta = A.ldlt().solve(-g);
      if (!delta.allFinite()) {
        mu *= 10;
        continue;
      }
      Eigen::VectorXd un = u + delta;
      clamp_to_bounds(pr, un);
      const Evaluation trial = evaluator.evaluate(un, false);
      if (std::isfinite(trial.cost) && trial.cost < ev.cost) {
        const double rel = (ev.cost - trial.cost) / std::max(ev.cost, 1e-300);
        const double step = (un - u).cwiseAbs().maxCoeff();
        u = un;
        ev = evaluator.evaluate(u, true);
        mu = std::max(mu / 3.0, 1e-12);
        accepted = true;
        if (rel < opts.relative_tolerance || step < 1e-10) {
          out.converged = true;
        }
      } else {
        mu *= 4.0;
      }
    }
    if (!accepted) {  // no decrease possible any more: at a (local) minimum
      out.converged = true;
      evaluator.evaluate(u, false);  // leave pr.p / pr.x0 at u
      break;
    }
    if (out.converged) break;
  }
  evaluator.apply(u);
  out.ev = std::move(ev);
  out.u = u;
  return out;
}

// ---------------------------------------------------------------------------------------------
// Equation-error (integral) start for a set of parameters that enter linearly.

enum class LinearForm { Value, Inverse, None };  // v = p, v = 1/p, or not linear

std::vector<LinearForm> linear_forms(const Network& net) {
  std::vector<LinearForm> f(static_cast<std::size_t>(net.param_count()), LinearForm::None);
  std::vector<int> seen(static_cast<std::size_t>(net.param_count()), 0);  // bit 1 value, bit 2 inverse
  for (const auto& n : net.nodes) seen[static_cast<std::size_t>(n.capacitance_param)] |= 1;
  auto mark = [&](const std::vector<Term>& ts) {
    for (const auto& t : ts) seen[static_cast<std::size_t>(t.param)] |= (t.kind == TermKind::Resistance ? 2 : 1);
  };
  for (const auto& l : net.links) { mark(l.operating); mark(l.cooling); }
  for (const auto& s : net.sources) { mark(s.operating); mark(s.cooling); }
  for (std::size_t i = 0; i < f.size(); ++i)
    f[i] = seen[i] == 1 ? LinearForm::Value : seen[i] == 2 ? LinearForm::Inverse : LinearForm::None;
  return f;
}

struct EquationErrorInput {
  const Recording* rec;
  Eigen::MatrixXd temps;                // rows x nodes (measured or filled), NaN = unknown
  const Eigen::MatrixXd* extra = nullptr;
};

// Solves for `unknown` (parameter indices, all linear) from the integral heat balances of every
// segment of `mode`. Returns the indices that could be determined (positive); writes them into p.
std::vector<int> equation_error_start(const Network& net, const std::vector<EquationErrorInput>& data, Mode mode,
                                      std::vector<int> unknown, double sum_c, Eigen::VectorXd& p,
                                      std::vector<std::string>& warnings) {
  const auto forms = linear_forms(net);
  const int n = net.node_count();
  std::vector<int> determined;
  std::vector<int> col_of(static_cast<std::size_t>(net.param_count()), -1);
  for (int pass = 0; pass < 3 && !unknown.empty(); ++pass) {
    std::fill(col_of.begin(), col_of.end(), -1);
    for (std::size_t c = 0; c < unknown.size(); ++c) col_of[static_cast<std::size_t>(unknown[c])] = static_cast<int>(c);
    const int nu = static_cast<int>(unknown.size());
    Eigen::MatrixXd AtA = Eigen::MatrixXd::Zero(nu, nu);
    Eigen::VectorXd Atb = Eigen::VectorXd::Zero(nu);
    Eigen::VectorXd row(nu);
    std::vector<bool> touched(static_cast<std::size_t>(nu), false);
    for (const auto& d : data) {
      const Recording& rec = *d.rec;
      const std::size_t rows = rec.rows();
      std::size_t b = 0;
      while (b + 1 < rows) {
        if (net.mode_at(rec.speed_rpm[b]) != mode) { ++b; continue; }
        std::size_t e = b;
        while (e + 1 < rows && net.mode_at(rec.speed_rpm[e]) == mode) ++e;
        // intervals b..e-1 are in `mode`, rows b..e are their end points
        const std::size_t last = e;  // the state at row e is reached through interval e-1
        if (last - b >= 10) {
          for (int i = 0; i < n; ++i) {
            // links at node i in this mode, and the rows they need
            bool ok = true;
            for (std::size_t k = b; k <= last && ok; ++k) ok = std::isfinite(d.temps(static_cast<Eigen::Index>(k), i));
            for (const auto& l : net.links) {
              if (!ok) break;
              if (l.a != i && l.b != i) continue;
              if ((mode == Mode::Operating ? l.operating : l.cooling).empty()) continue;
              const int o = l.a == i ? l.b : l.a;
              if (o == kAmbient) continue;
              for (std::size_t k = b; k <= last && ok; ++k) ok = std::isfinite(d.temps(static_cast<Eigen::Index>(k), o));
            }
            if (!ok) continue;
            // running integrals per column and for the known part
            Eigen::VectorXd integ = Eigen::VectorXd::Zero(nu);
            double known_integ = 0.0;
            const int ci = net.nodes[static_cast<std::size_t>(i)].capacitance_param;
            const double Ti0 = d.temps(static_cast<Eigen::Index>(b), i);
            for (std::size_t k = b; k < last; ++k) {
              const auto k0 = static_cast<Eigen::Index>(k), k1 = k0 + 1;
              const double dt = rec.time_s[k + 1] - rec.time_s[k];
              const double s = rec.speed_rpm[k] / net.speed_ref_rpm;
              for (const auto& l : net.links) {
                if (l.a != i && l.b != i) continue;
                const int o = l.a == i ? l.b : l.a;
                const double f0 = (o == kAmbient ? rec.ambient_c[k] : d.temps(k0, o)) - d.temps(k0, i);
                const double f1 = (o == kAmbient ? rec.ambient_c[k] : d.temps(k1, o)) - d.temps(k1, i);
                const double area = 0.5 * (f0 + f1) * dt;
                for (const auto& t : mode == Mode::Operating ? l.operating : l.cooling) {
                  // g = v * s^(-e) for resistances (v = 1/p), v * s^e for conductances
                  const double sf = t.speed_exponent == 0.0 ? 1.0
                                    : std::pow(s, t.kind == TermKind::Resistance ? -t.speed_exponent : t.speed_exponent);
                  const int c = col_of[static_cast<std::size_t>(t.param)];
                  if (c >= 0) integ[c] += sf * area;
                  else {
                    const double pv = p[t.param];
                    known_integ += (t.kind == TermKind::Resistance ? 1.0 / pv : pv) * sf * area;
                  }
                }
              }
              for (const auto& src : net.sources) {
                if (src.node != i) continue;
                for (const auto& t : mode == Mode::Operating ? src.operating : src.cooling) {
                  const double sf = t.speed_exponent == 0.0 ? 1.0 : std::pow(s, t.speed_exponent);
                  const int c = col_of[static_cast<std::size_t>(t.param)];
                  if (c >= 0) integ[c] += sf * dt;
                  else known_integ += p[t.param] * sf * dt;
                }
              }
              if (d.extra) known_integ += (*d.extra)(k0, i) * dt;
              // equation at row k+1:  C_i (T_i(k+1) - T_i(b)) - sum(unknown integrals) = known integrals
              row = -integ;
              double rhs = known_integ;
              const double dT = d.temps(k1, i) - Ti0;
              if (col_of[static_cast<std::size_t>(ci)] >= 0) row[col_of[static_cast<std::size_t>(ci)]] += dT;
              else rhs -= p[ci] * dT;
              AtA.selfadjointView<Eigen::Lower>().rankUpdate(row);
              Atb += row * rhs;
              for (int c = 0; c < nu; ++c) touched[static_cast<std::size_t>(c)] = touched[static_cast<std::size_t>(c)] || row[c] != 0.0;
            }
          }
        }
        b = e;
      }
    }
    AtA.triangularView<Eigen::Upper>() = AtA.transpose();
    // Capacitance gauge: sum of unknown C = sum_c - known C.
    Eigen::VectorXd crow = Eigen::VectorXd::Zero(nu);
    double crhs = std::isfinite(sum_c) ? sum_c : 0.0;
    bool has_c_unknown = false;
    for (const auto& nd : net.nodes) {
      const int c = col_of[static_cast<std::size_t>(nd.capacitance_param)];
      if (c >= 0) { crow[c] = 1.0; has_c_unknown = true; }
      else crhs -= p[nd.capacitance_param];
    }
    const bool use_gauge = has_c_unknown && std::isfinite(sum_c);
    // Column scaling for conditioning.
    Eigen::VectorXd scale(nu);
    for (int c = 0; c < nu; ++c) scale[c] = AtA(c, c) > 0 ? 1.0 / std::sqrt(AtA(c, c)) : 1.0;
    const int dim = nu + (use_gauge ? 1 : 0);
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(dim, dim);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(dim);
    K.topLeftCorner(nu, nu) = scale.asDiagonal() * AtA * scale.asDiagonal();
    rhs.head(nu) = scale.asDiagonal() * Atb;
    if (use_gauge) {
      K.block(nu, 0, 1, nu) = (crow.cwiseProduct(scale)).transpose();
      K.block(0, nu, nu, 1) = crow.cwiseProduct(scale);
      rhs[nu] = crhs;
    }
    for (int c = 0; c < nu; ++c)
      if (!touched[static_cast<std::size_t>(c)]) { K.row(c).setZero(); K.col(c).setZero(); K(c, c) = 1.0; rhs[c] = 0.0; }
    Eigen::VectorXd sol = K.fullPivLu().solve(rhs);
    Eigen::VectorXd v = scale.cwiseProduct(sol.head(nu));
    std::vector<int> bad;
    std::vector<double> good_values;
    for (int c = 0; c < nu; ++c) {
      const int pi = unknown[static_cast<std::size_t>(c)];
      if (!touched[static_cast<std::size_t>(c)] || !std::isfinite(v[c]) || v[c] <= 0) { bad.push_back(pi); continue; }
      const double val = forms[static_cast<std::size_t>(pi)] == LinearForm::Inverse ? 1.0 / v[c] : v[c];
      const auto& par = net.params[static_cast<std::size_t>(pi)];
      p[pi] = std::clamp(val, par.min, par.max);
    }
    if (bad.empty()) {
      determined.insert(determined.end(), unknown.begin(), unknown.end());
      return determined;
    }
    // Hold the failed ones at a neutral value and solve again for the rest.
    std::vector<int> next;
    for (int pi : unknown) {
      if (std::find(bad.begin(), bad.end(), pi) == bad.end()) { next.push_back(pi); continue; }
      const auto& par = net.params[static_cast<std::size_t>(pi)];
      const int c = col_of[static_cast<std::size_t>(pi)];
      const bool touched_c = touched[static_cast<std::size_t>(c)];
      if (!touched_c) continue;  // not in any equation: left undetermined
      // neutral value: a weak (10 % of the typical) conductance, or no heat for a source term
      double typical_v = 0;
      int cnt = 0;
      for (int c2 = 0; c2 < nu; ++c2)
        if (v[c2] > 0 && std::isfinite(v[c2]) && forms[static_cast<std::size_t>(unknown[static_cast<std::size_t>(c2)])] == forms[static_cast<std::size_t>(pi)]) {
          typical_v += std::log(v[c2]);
          ++cnt;
        }
      double val;
      if (!par.log_scale && par.min <= 0) val = std::max(par.min, 0.0);
      else if (cnt > 0) {
        const double vv = 0.1 * std::exp(typical_v / cnt);
        val = forms[static_cast<std::size_t>(pi)] == LinearForm::Inverse ? 1.0 / vv : vv;
      } else val = std::sqrt(par.min * par.max);
      p[pi] = std::clamp(val, par.min, par.max);
      determined.push_back(pi);
      warnings.push_back("equation-error start: '" + par.name + "' came out non-positive; started at " +
                         std::to_string(p[pi]) + " " + par.unit + " and left to the output-error stages");
    }
    unknown = next;
  }
  return determined;
}

// Fills unmeasured node temperatures quasi-statically from neighbours (weights = the mode's
// internal conductances), rescaled in rise above ambient to the measured values at the ends of each gap.
Eigen::MatrixXd filled_temperatures(const Network& net, const Eigen::VectorXd& p, const Recording& rec,
                                    const std::vector<int>& cols) {
  const int n = net.node_count();
  const auto rows = static_cast<Eigen::Index>(rec.rows());
  Eigen::MatrixXd T = Eigen::MatrixXd::Constant(rows, n, kNaN);
  for (std::size_t m = 0; m < cols.size(); ++m) T.col(net.measurements[m].node) = rec.temp_c.col(cols[m]);
  const Eigen::MatrixXd filled_from = T;
  const NodeMatrices mc = assemble(net, p, 0.0);
  for (int i = 0; i < n; ++i) {
    Eigen::Index k = 0;
    while (k < rows) {
      if (std::isfinite(filled_from(k, i))) { ++k; continue; }
      Eigen::Index e = k;
      while (e < rows && !std::isfinite(filled_from(e, i))) ++e;
      // gap rows k..e-1; quasi-static estimate
      for (Eigen::Index r = k; r < e; ++r) {
        double num = 0, den = 0;
        for (int j = 0; j < n; ++j) {
          if (j == i || !std::isfinite(filled_from(r, j))) continue;
          const double g = -mc.G(i, j);
          num += g * filled_from(r, j);
          den += g;
        }
        T(r, i) = den > 0 ? num / den : kNaN;
      }
      // rescale the rise so the fill meets the measured values at the gap ends
      auto factor_at = [&](Eigen::Index r_meas, Eigen::Index r_fill) {
        const double amb = rec.ambient_c[static_cast<std::size_t>(r_meas)];
        const double fill = T(r_fill, i) - rec.ambient_c[static_cast<std::size_t>(r_fill)];
        const double meas = filled_from(r_meas, i) - amb;
        return std::abs(fill) > 1e-3 ? meas / fill : kNaN;
      };
      const double f_start = k > 0 ? factor_at(k - 1, k) : kNaN;
      const double f_end = e < rows ? factor_at(e, e - 1) : kNaN;
      const double fs = std::isfinite(f_start) ? f_start : (std::isfinite(f_end) ? f_end : 1.0);
      const double fe = std::isfinite(f_end) ? f_end : fs;
      const double t0 = rec.time_s[static_cast<std::size_t>(k)], t1 = rec.time_s[static_cast<std::size_t>(e - 1)];
      for (Eigen::Index r = k; r < e; ++r) {
        if (!std::isfinite(T(r, i))) continue;
        const double w = t1 > t0 ? (rec.time_s[static_cast<std::size_t>(r)] - t0) / (t1 - t0) : 1.0;
        const double amb = rec.ambient_c[static_cast<std::size_t>(r)];
        T(r, i) = amb + ((1 - w) * fs + w * fe) * (T(r, i) - amb);
      }
      k = e;
    }
  }
  return T;
}

Eigen::VectorXd state_from_row(const Network& net, const Recording& rec, const std::vector<int>& cols, std::size_t row) {
  const int n = net.node_count();
  const double amb = rec.ambient_c[row];
  Eigen::VectorXd x = Eigen::VectorXd::Constant(n, kNaN);
  double rise = 0;
  int cnt = 0;
  for (std::size_t m = 0; m < cols.size(); ++m) {
    const double v = rec.temp_c(static_cast<Eigen::Index>(row), cols[m]);
    if (std::isfinite(v)) {
      x[net.measurements[m].node] = v;
      rise += v - amb;
      ++cnt;
    }
  }
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(x[i])) x[i] = amb + (cnt ? rise / cnt : 0.0);
  return x;
}

std::string fmt_double(double v, int prec = 6) {
  std::ostringstream os;
  os.precision(prec);
  os << v;
  return os.str();
}

// For the equation-error start only: a node no probe measures gets, row by row, the mean of its
// measured neighbours (links to ambient do not count). In natural cooling the nodes of a spindle
// converge on one another, so this is a fair first guess; nothing after stage 1 uses it. Returns
// whether any column was filled.
bool fill_unmeasured_from_neighbours(const Network& net, Eigen::MatrixXd& temps) {
  bool filled = false;
  const Eigen::Index n = temps.cols();
  std::vector<bool> measured(static_cast<std::size_t>(n));
  for (Eigen::Index k = 0; k < n; ++k) measured[static_cast<std::size_t>(k)] = temps.col(k).array().isFinite().any();
  for (Eigen::Index k = 0; k < n; ++k) {
    if (measured[static_cast<std::size_t>(k)]) continue;
    std::vector<int> nb;
    for (const auto& l : net.links) {
      const int other = l.a == k ? l.b : (l.b == k ? l.a : kAmbient);
      if (other != kAmbient && measured[static_cast<std::size_t>(other)] &&
          std::find(nb.begin(), nb.end(), other) == nb.end())
        nb.push_back(other);
    }
    if (nb.empty()) continue;
    for (Eigen::Index i = 0; i < temps.rows(); ++i) {
      double sum = 0;
      int cnt = 0;
      for (int o : nb)
        if (std::isfinite(temps(i, o))) {
          sum += temps(i, o);
          ++cnt;
        }
      temps(i, k) = cnt == static_cast<int>(nb.size()) ? sum / cnt : std::numeric_limits<double>::quiet_NaN();
    }
    filled = true;
  }
  return filled;
}

// A parameter whose equation-error row needs an unmeasured node (the shaft of a spindle whose
// probes all sit on the housing, say) cannot be started from the data directly. It starts at the
// geometric mean of the started parameters of the same unit (a capacitance: an equal share of what
// the capacitance gauge leaves), and the output-error stages that follow fit it like any other. The
// fit says so in its warnings, because such a parameter's estimate rests on the output error alone.
void start_unreached_from_peers(const Network& net, const std::vector<int>& wanted, const std::vector<int>& got,
                                double sum_c, Eigen::VectorXd& p, std::vector<std::string>& warnings) {
  const auto unit_of = [&](int j) -> const std::string& { return net.params[static_cast<std::size_t>(j)].unit; };
  const int np = static_cast<int>(net.params.size());
  for (int i : wanted) {
    if (std::find(got.begin(), got.end(), i) != got.end()) continue;
    const auto& par = net.params[static_cast<std::size_t>(i)];
    double start = std::numeric_limits<double>::quiet_NaN();
    if (par.unit == "J/K" && std::isfinite(sum_c)) {
      double known = 0;
      int unknown = 0;
      for (int j = 0; j < np; ++j)
        if (unit_of(j) == "J/K") {
          if (std::isfinite(p[j])) known += p[j];
          else ++unknown;
        }
      if (unknown > 0 && sum_c > known) start = (sum_c - known) / unknown;
    } else {
      double log_sum = 0;
      int n = 0;
      for (int j = 0; j < np; ++j)
        if (j != i && unit_of(j) == par.unit && std::isfinite(p[j]) && p[j] > 0) {
          log_sum += std::log(p[j]);
          ++n;
        }
      if (n > 0) start = std::exp(log_sum / n);
    }
    if (!std::isfinite(start))
      throw std::invalid_argument("fit: could not start '" + par.name +
                                  "' from the cooling data (its nodes are not measured there) and no started parameter "
                                  "shares its unit; give an initial value");
    p[i] = std::clamp(start, par.min, par.max);
    warnings.push_back("'" + par.name + "' could not be started from the data (its nodes are not measured): started at " +
                       fmt_double(p[i]) + " " + par.unit + " from its peers; its estimate rests on the output-error fit alone");
  }
}

// A start for the operating-only parameters that uses no derivative of the data: every
// resistance at the geometric mean of the resistances stage 2 fitted (same unit family, K/W), and
// the heat sources sharing what holds the warm-ups' largest final rise above ambient across that
// resistance. Crude, but on the output-error surface it lies in the basin of the physical minimum
// for any spindle-like network (heat and resistance scales within a decade converge alike).
Eigen::VectorXd neutral_operating_start(const Network& net, const std::vector<Recording>& recs,
                                        const std::vector<std::vector<int>>& cols, const std::vector<int>& op_auto,
                                        const Eigen::VectorXd& p) {
  const auto is_resistance = [&](int j) { return net.params[static_cast<std::size_t>(j)].unit.rfind("K/W", 0) == 0; };
  double log_sum = 0;
  int n = 0;
  for (int j = 0; j < net.param_count(); ++j)
    if (is_resistance(j) && std::isfinite(p[j]) && p[j] > 0 &&
        std::find(op_auto.begin(), op_auto.end(), j) == op_auto.end()) {
      log_sum += std::log(p[j]);
      ++n;
    }
  const double r_typ = n > 0 ? std::exp(log_sum / n) : 1.0;
  double rise = 0;
  for (std::size_t r = 0; r < recs.size(); ++r) {
    const auto& rec = recs[r];
    if (rec.rows() == 0) continue;
    const auto last = static_cast<Eigen::Index>(rec.rows() - 1);
    for (int c : cols[r]) {
      const double d = rec.temp_c(last, c) - rec.ambient_c[static_cast<std::size_t>(last)];
      if (std::isfinite(d)) rise = std::max(rise, d);
    }
  }
  int heats = 0;
  for (int i : op_auto) heats += is_resistance(i) ? 0 : 1;
  const double q_each = heats > 0 ? std::max(rise, 1.0) / r_typ / heats : 0.0;
  Eigen::VectorXd s = p;
  for (int i : op_auto) {
    const auto& par = net.params[static_cast<std::size_t>(i)];
    s[i] = std::clamp(is_resistance(i) ? r_typ : q_each, par.min, par.max);
  }
  return s;
}

}  // namespace

const char* identifiability_name(Identifiability i) {
  switch (i) {
    case Identifiability::Fixed: return "fixed";
    case Identifiability::Good: return "identifiable";
    case Identifiability::Weak: return "weakly identifiable";
    case Identifiability::NotIdentifiable: return "not identifiable";
  }
  return "?";
}

std::vector<int> measurement_columns(const Network& net, const Recording& rec) {
  std::vector<int> cols;
  if (net.measurements.empty()) throw std::invalid_argument("network '" + net.name + "' declares no measurements");
  for (const auto& m : net.measurements) {
    const int c = rec.channel_index(m.column);
    if (c < 0) {
      std::string have;
      for (const auto& ch : rec.channels) have += " " + ch;
      throw std::invalid_argument(rec.source + ": no column '" + m.column + "' (measures node '" +
                                  net.nodes[static_cast<std::size_t>(m.node)].name + "'); columns:" + have);
    }
    cols.push_back(c);
  }
  return cols;
}

namespace {
// node name -> the column its role names ("" = no channel has it), from the recordings'
// channel_roles metadata; nodes in `explicit_specs` are left out. See map_measurements().
std::map<std::string, std::string> columns_from_roles(const Network& net, const std::vector<Recording>& recs,
                                                      const std::vector<std::string>& explicit_specs) {
  std::map<std::string, std::string> explicit_nodes;
  for (const auto& spec : explicit_specs) explicit_nodes[spec.substr(0, spec.find('='))] = spec;
  std::map<std::string, std::pair<std::string, std::string>> chosen;  // node -> (column, recording)
  for (const auto& rec : recs) {
    const std::string meta = rec.meta_value("channel_roles");
    if (meta.empty() || meta.find('(') != std::string::npos) continue;  // absent, or defaults
    std::map<std::string, std::string> column_of_role;
    std::stringstream ss(meta);
    std::string pair;
    while (std::getline(ss, pair, ',')) {
      const auto eq = pair.find('=');
      if (eq != std::string::npos) column_of_role[pair.substr(eq + 1)] = pair.substr(0, eq);
    }
    for (uint8_t r = 0; r < wire::kChannelRoleCount; ++r) {
      const std::string role = wire::channel_role_name(r);
      if (!wire::is_thermal_role(r) || net.node_index(role) < 0 || explicit_nodes.count(role)) continue;
      const auto it = column_of_role.find(role);
      const std::string column = it == column_of_role.end() ? std::string() : it->second;
      const auto prev = chosen.find(role);
      if (prev == chosen.end()) {
        chosen[role] = {column, rec.source};
      } else if (prev->second.first != column) {
        throw std::invalid_argument("channel roles: " + prev->second.second + " has node '" + role + "' on " +
                                    (prev->second.first.empty() ? "no channel" : prev->second.first) + ", " +
                                    rec.source + " on " + (column.empty() ? "no channel" : column) +
                                    "; say which with --column " + role + "=COLUMN");
      }
    }
  }
  std::map<std::string, std::string> out;
  for (const auto& [node, c] : chosen) out[node] = c.first;
  return out;
}
}  // namespace

std::string map_measurements(Network& net, const std::vector<Recording>& recs, const std::vector<std::string>& columns) {
  const auto from_roles = columns_from_roles(net, recs, columns);
  // Every chosen node loses its old column first, so swapped probes do not collide; --column last.
  std::vector<std::string> specs;
  std::string said;
  for (const auto& [node, column] : from_roles) {
    specs.push_back(node + "=");
    said += " " + node + "=" + (column.empty() ? "(none)" : column);
  }
  for (const auto& [node, column] : from_roles)
    if (!column.empty()) specs.push_back(node + "=" + column);
  specs.insert(specs.end(), columns.begin(), columns.end());
  remap_measurements(net, specs);
  return said;
}

Eigen::VectorXd first_sample_state(const Network& net, const Recording& rec) {
  return state_from_row(net, rec, measurement_columns(net, rec), 0);
}

Eigen::MatrixXd prediction_residuals(const Network& net, const Eigen::VectorXd& params, const Recording& rec,
                                     const Eigen::VectorXd& x0, const Eigen::MatrixXd* extra) {
  const auto cols = measurement_columns(net, rec);
  const Eigen::MatrixXd sim = simulate_recording(net, params, rec, x0, extra);
  Eigen::MatrixXd r(sim.rows(), static_cast<Eigen::Index>(cols.size()));
  for (std::size_t m = 0; m < cols.size(); ++m)
    r.col(static_cast<Eigen::Index>(m)) = sim.col(net.measurements[m].node) - rec.temp_c.col(cols[m]);
  return r;  // NaN where the measurement is missing
}

FitResult fit_network(const Network& net_in, const std::vector<Recording>& recs, const FitOptions& opts) {
  const auto t_start = Clock::now();
  Network net = net_in;
  net.validate();
  if (recs.empty()) throw std::invalid_argument("fit: no recordings");
  const int n = net.node_count();
  const int np = net.param_count();
  auto say = [&](const std::string& s) { if (opts.progress) opts.progress(s); };
  FitResult res;

  // ---- which parameters are held, start values, gauge
  std::vector<bool> held(static_cast<std::size_t>(np), false);
  Eigen::VectorXd p = Eigen::VectorXd::Constant(np, kNaN);
  for (int i = 0; i < np; ++i) {
    const auto& par = net.params[static_cast<std::size_t>(i)];
    if (!par.initial_auto) p[i] = par.initial;
    if (par.fixed) {
      held[static_cast<std::size_t>(i)] = true;
      if (!std::isfinite(p[i])) p[i] = par.nominal;
    }
  }
  if (opts.start.size() != 0) {
    if (opts.start.size() != np) throw std::invalid_argument("fit: FitOptions::start has the wrong size");
    for (int i = 0; i < np; ++i)
      if (std::isfinite(opts.start[i])) p[i] = opts.start[i];
  }
  auto index_of = [&](const std::string& name) {
    const int i = net.param_index(name);
    if (i < 0) throw std::invalid_argument("fit: unknown parameter '" + name + "'");
    return i;
  };
  if (!opts.free_only.empty()) {
    std::fill(held.begin(), held.end(), true);
    for (const auto& nm : opts.free_only) held[static_cast<std::size_t>(index_of(nm))] = net.params[static_cast<std::size_t>(index_of(nm))].fixed;
  }
  for (const auto& nm : opts.hold) held[static_cast<std::size_t>(index_of(nm))] = true;
  for (int i = 0; i < np; ++i)
    if (held[static_cast<std::size_t>(i)] && !std::isfinite(p[i]))
      throw std::invalid_argument("fit: parameter '" + net.params[static_cast<std::size_t>(i)].name + "' is held but has no value");

  const double sum_c = std::isfinite(opts.sum_capacitance_J_per_K) ? opts.sum_capacitance_J_per_K : net.sum_capacitance_J_per_K;
  bool any_held = false;
  std::string held_names;
  for (int i = 0; i < np; ++i)
    if (held[static_cast<std::size_t>(i)]) { any_held = true; held_names += (held_names.empty() ? "" : ", ") + net.params[static_cast<std::size_t>(i)].name; }
  bool any_c_free = false;
  for (const auto& nd : net.nodes) any_c_free = any_c_free || !held[static_cast<std::size_t>(nd.capacitance_param)];
  const bool use_sum_c = std::isfinite(sum_c) && any_c_free;
  if (use_sum_c) {
    res.gauge = "sum of capacitances fixed at " + fmt_double(sum_c) + " J/K";
    if (any_held) res.gauge += "; held parameters: " + held_names;
  } else if (any_held) {
    res.gauge = "held parameters: " + held_names;
  } else {
    throw std::invalid_argument("fit: no scale gauge: temperatures alone cannot fix the absolute level of C, R and q. "
                                "Give the total heat capacity (--sum-c J/K or \"sum_capacitance_J_per_K\") or fix a parameter");
  }

  // ---- runs over whole recordings
  std::vector<std::vector<int>> cols;
  for (const auto& r : recs) {
    cols.push_back(measurement_columns(net, r));
    if (r.rows() < 2) throw std::invalid_argument(r.source + ": a recording needs at least two rows");
  }
  if (!opts.extra_heat_w.empty()) {
    if (opts.extra_heat_w.size() != recs.size()) throw std::invalid_argument("fit: extra_heat_w needs one matrix per recording");
    for (std::size_t r = 0; r < recs.size(); ++r)
      if (opts.extra_heat_w[r].rows() != static_cast<Eigen::Index>(recs[r].rows()) || opts.extra_heat_w[r].cols() != n)
        throw std::invalid_argument(recs[r].source + ": extra heat matrix must be rows x nodes");
  }
  auto extra_of = [&](std::size_t r) { return opts.extra_heat_w.empty() ? nullptr : &opts.extra_heat_w[r]; };
  std::vector<Run> whole;
  for (std::size_t r = 0; r < recs.size(); ++r) {
    Run run;
    run.rec = &recs[r];
    run.begin = 0;
    run.end = recs[r].rows() - 1;
    run.cols = cols[r];
    run.extra = extra_of(r);
    run.recording_index = static_cast<int>(r);
    whole.push_back(run);
  }

  const auto used_cool = params_used(net, Mode::Cooling);
  std::vector<int> free_all, free_cool, free_op_only;
  for (int i = 0; i < np; ++i) {
    if (held[static_cast<std::size_t>(i)]) continue;
    free_all.push_back(i);
    (used_cool[static_cast<std::size_t>(i)] ? free_cool : free_op_only).push_back(i);
  }
  if (free_all.empty()) throw std::invalid_argument("fit: every parameter is held; nothing to fit");

  auto make_problem = [&](const std::vector<Run>& runs, const std::vector<int>& free, const std::vector<Eigen::VectorXd>& x0) {
    LmProblem pr;
    pr.net = &net;
    pr.runs = runs;
    pr.free = free;
    for (int i : free) pr.tf.push_back(transform_of(net.params[static_cast<std::size_t>(i)]));
    pr.p = p;
    pr.estimate_x0 = opts.initial_state == InitialState::Estimate;
    pr.x0 = x0;
    // the gauge row only acts when some capacitance is free in this stage
    bool c_free = false;
    for (const auto& nd : net.nodes) c_free = c_free || std::find(free.begin(), free.end(), nd.capacitance_param) != free.end();
    pr.sum_c = (use_sum_c && c_free) ? sum_c : kNaN;
    return pr;
  };
  auto run_stage = [&](const std::string& name, LmProblem& pr, bool final_stage = false) {
    const auto t0 = Clock::now();
    say(name + ": " + std::to_string(pr.nf()) + " parameters, " + std::to_string(pr.runs.size()) + " runs ...");
    LmOutcome o = levenberg_marquardt(pr, opts);
    // Levenberg-Marquardt can stop in a curved valley with its damping grown so large that no
    // step is accepted, well before the minimum (seen: the demo's joint fit stopping at 0.215 K
    // where a second run from that point reached 0.167 K). A restart with fresh damping costs one
    // Jacobian when the point really is a minimum; restart while it still gains and budget is left.
    // Only the final stage: the earlier ones are starts, their precision is not what is reported.
    for (int restart = 0; final_stage && restart < 4 && o.converged && o.iterations < opts.max_iterations; ++restart) {
      FitOptions again = opts;
      again.max_iterations = opts.max_iterations - o.iterations;
      LmOutcome r = levenberg_marquardt(pr, again);
      const bool gained = r.ev.ssr < o.ev.ssr * (1 - 1e-6);
      r.iterations += o.iterations;
      o = std::move(r);
      if (!gained) break;
    }
    StageSummary st;
    st.name = name;
    st.iterations = o.iterations;
    st.rms_K = o.ev.count ? std::sqrt(o.ev.ssr / static_cast<double>(o.ev.count)) : 0.0;
    st.seconds = seconds_since(t0);
    say(name + ": rms " + fmt_double(st.rms_K, 4) + " K after " + std::to_string(o.iterations) + " iterations (" +
        fmt_double(st.seconds, 3) + " s)");
    res.stages.push_back(st);
    p = pr.p;
    return o;
  };

  std::vector<Eigen::VectorXd> x0_whole;
  for (std::size_t r = 0; r < recs.size(); ++r) x0_whole.push_back(state_from_row(net, recs[r], cols[r], 0));

  const bool need_auto = [&] {
    for (int i : free_all) if (!std::isfinite(p[i])) return true;
    return false;
  }();
  if (opts.staged || need_auto) {
    // ---- stage 1: cooling segments, equation error
    std::vector<Run> cooling_runs;
    std::vector<EquationErrorInput> cool_data;
    bool warned_fill = false;
    for (std::size_t r = 0; r < recs.size(); ++r) {
      const Recording& rec = recs[r];
      std::size_t b = 0;
      while (b + 1 < rec.rows()) {
        if (net.mode_at(rec.speed_rpm[b]) != Mode::Cooling) { ++b; continue; }
        std::size_t e = b;
        while (e + 1 < rec.rows() && net.mode_at(rec.speed_rpm[e]) == Mode::Cooling) ++e;
        if (e - b >= 10) {
          Run run;
          run.rec = &rec;
          run.begin = b;
          run.end = e;
          run.cols = cols[r];
          run.extra = extra_of(r);
          cooling_runs.push_back(run);
        }
        b = e;
      }
      EquationErrorInput in;
      in.rec = &rec;
      in.temps = Eigen::MatrixXd::Constant(static_cast<Eigen::Index>(rec.rows()), n, kNaN);
      for (std::size_t m = 0; m < cols[r].size(); ++m) in.temps.col(net.measurements[m].node) = rec.temp_c.col(cols[r][m]);
      if (fill_unmeasured_from_neighbours(net, in.temps) && !warned_fill) {
        res.warnings.push_back("stage 1 started with unmeasured node temperatures taken as the mean of their measured "
                               "neighbours; the output-error stages replace that with the network's own prediction");
        warned_fill = true;
      }
      in.extra = extra_of(r);
      cool_data.push_back(std::move(in));
    }
    std::vector<int> cool_auto;
    for (int i : free_cool) if (!std::isfinite(p[i])) cool_auto.push_back(i);
    const auto forms = linear_forms(net);
    for (int i : cool_auto)
      if (forms[static_cast<std::size_t>(i)] == LinearForm::None)
        throw std::invalid_argument("fit: parameter '" + net.params[static_cast<std::size_t>(i)].name +
                                    "' enters non-linearly; give it an initial value");
    if (!cool_auto.empty()) {
      if (cooling_runs.empty())
        throw std::invalid_argument("fit: no natural-cooling segment (>= 10 rows at speed <= operating_above_rpm) to start "
                                    "the cooling-mode parameters from; give initial values");
      say("stage 1: equation-error start of " + std::to_string(cool_auto.size()) + " cooling-mode parameters from " +
          std::to_string(cooling_runs.size()) + " cooling segments");
      const auto got = equation_error_start(net, cool_data, Mode::Cooling, cool_auto, use_sum_c ? sum_c : kNaN, p, res.warnings);
      start_unreached_from_peers(net, cool_auto, got, use_sum_c ? sum_c : kNaN, p, res.warnings);
    }
    // ---- stage 2: output error on cooling segments
    if (!cooling_runs.empty() && !free_cool.empty()) {
      std::vector<Eigen::VectorXd> x0;
      for (const auto& run : cooling_runs) x0.push_back(state_from_row(net, *run.rec, run.cols, run.begin));
      LmProblem pr = make_problem(cooling_runs, free_cool, x0);
      run_stage("stage 2 (cooling output error)", pr);
    }
    // ---- stage 3: operating-only parameters
    std::vector<int> op_auto;
    for (int i : free_op_only) if (!std::isfinite(p[i])) op_auto.push_back(i);
    for (int i : op_auto)
      if (forms[static_cast<std::size_t>(i)] == LinearForm::None)
        throw std::invalid_argument("fit: parameter '" + net.params[static_cast<std::size_t>(i)].name +
                                    "' enters non-linearly; give it an initial value");
    if (!op_auto.empty()) {
      for (int i = 0; i < np; ++i)
        if (!std::isfinite(p[i]) && std::find(op_auto.begin(), op_auto.end(), i) == op_auto.end())
          throw std::invalid_argument("fit: no start for '" + net.params[static_cast<std::size_t>(i)].name + "'");
      std::vector<EquationErrorInput> op_data;
      for (std::size_t r = 0; r < recs.size(); ++r) {
        EquationErrorInput in;
        in.rec = &recs[r];
        // temporarily give the unknown operating parameters a value so the cooling G can be assembled
        Eigen::VectorXd pf = p;
        for (int i : op_auto) pf[i] = 1.0;
        in.temps = filled_temperatures(net, pf, recs[r], cols[r]);
        in.extra = extra_of(r);
        op_data.push_back(std::move(in));
      }
      say("stage 3: equation-error start of " + std::to_string(op_auto.size()) + " operating-only parameters");
      const auto got = equation_error_start(net, op_data, Mode::Operating, op_auto, kNaN, p, res.warnings);
      std::vector<int> log_missing;
      for (int i : op_auto)
        if (std::find(got.begin(), got.end(), i) == got.end()) {
          const auto& par = net.params[static_cast<std::size_t>(i)];
          if (!par.log_scale) p[i] = std::max(par.min, 0.0);
          else log_missing.push_back(i);
        }
      // A resistance the regression could not place (collinear with a source, or estimated with
      // the wrong sign) starts from its peers, like an unmeasured node's in stage 1.
      start_unreached_from_peers(net, log_missing, {}, kNaN, p, res.warnings);
    }
    if (!free_op_only.empty()) {
      // The equation-error start differentiates noisy warm-ups and can land the operating
      // parameters in a far basin (huge heat balanced by a tiny resistance to ambient, seen on the
      // demo's recordings: 1.15 K instead of 0.25 K). So when the data started them, stage 3 also
      // runs from a neutral start that knows nothing of the derivatives, and keeps the better.
      std::vector<std::pair<std::string, Eigen::VectorXd>> starts{{"", p}};
      if (!op_auto.empty()) {
        starts[0].first = ", equation-error start";
        starts.emplace_back(", neutral start", neutral_operating_start(net, recs, cols, op_auto, p));
      }
      double best_ssr = std::numeric_limits<double>::infinity();
      std::size_t best = 0;
      Eigen::VectorXd best_p = p;
      std::vector<Eigen::VectorXd> best_x0 = x0_whole;
      for (std::size_t k = 0; k < starts.size(); ++k) {
        p = starts[k].second;
        LmProblem pr = make_problem(whole, free_op_only, x0_whole);
        const LmOutcome o = run_stage("stage 3 (operating output error" + starts[k].first + ")", pr);
        if (o.ev.ssr < best_ssr) {
          best_ssr = o.ev.ssr;
          best = k;
          best_p = pr.p;
          best_x0 = pr.x0;
        }
      }
      if (starts.size() > 1) say("stage 3: kept the minimum of the" + starts[best].first.substr(1));
      p = best_p;
      x0_whole = best_x0;
    }
  }
  for (int i = 0; i < np; ++i)
    if (!std::isfinite(p[i])) throw std::invalid_argument("fit: no start value for '" + net.params[static_cast<std::size_t>(i)].name + "'");

  // ---- stage 4: joint fit
  LmProblem pr = make_problem(whole, free_all, x0_whole);
  const LmOutcome fin = run_stage(opts.staged ? "stage 4 (joint output error)" : "joint output error", pr, true);
  res.converged = fin.converged;
  res.params = pr.p;
  res.initial_states = pr.x0;
  res.residual_count = fin.ev.count;
  res.rms_K = fin.ev.count ? std::sqrt(fin.ev.ssr / static_cast<double>(fin.ev.count)) : 0.0;
  res.free_parameter_count = pr.nf();
  const int nu = pr.unknowns();
  const double dof = static_cast<double>(fin.ev.count) - nu;
  const double s2 = dof > 0 ? fin.ev.ssr / dof : kNaN;
  res.residual_sigma_K = std::sqrt(s2);

  // ---- covariance (scaled normal matrix, pseudo-inverse) and identifiability
  Eigen::VectorXd dsc(nu);
  for (int i = 0; i < nu; ++i) dsc[i] = fin.ev.H(i, i) > 0 ? 1.0 / std::sqrt(fin.ev.H(i, i)) : 1.0;
  const Eigen::MatrixXd Hs = dsc.asDiagonal() * fin.ev.H * dsc.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Hs);
  const Eigen::VectorXd lam = es.eigenvalues();
  const double lmax = lam.maxCoeff();
  res.condition_number = lam.minCoeff() > 0 ? lmax / lam.minCoeff() : std::numeric_limits<double>::infinity();
  Eigen::VectorXd lam_inv(nu);
  for (int i = 0; i < nu; ++i) lam_inv[i] = lam[i] > 1e-14 * lmax ? 1.0 / lam[i] : 0.0;
  const Eigen::MatrixXd cov_z = dsc.asDiagonal() * (es.eigenvectors() * lam_inv.asDiagonal() * es.eigenvectors().transpose()) *
                                dsc.asDiagonal() * s2;
  res.covariance = Eigen::MatrixXd::Zero(np, np);
  Eigen::VectorXd dpdz(pr.nf());
  for (int j = 0; j < pr.nf(); ++j) dpdz[j] = pr.tf[static_cast<std::size_t>(j)].dp_dz(fin.u[j]);
  for (int a = 0; a < pr.nf(); ++a)
    for (int b = 0; b < pr.nf(); ++b)
      res.covariance(pr.free[static_cast<std::size_t>(a)], pr.free[static_cast<std::size_t>(b)]) = dpdz[a] * dpdz[b] * cov_z(a, b);

  for (int i = 0; i < np; ++i) {
    const auto& par = net.params[static_cast<std::size_t>(i)];
    ParameterEstimate e;
    e.name = par.name;
    e.unit = par.unit;
    e.value = res.params[i];
    if (held[static_cast<std::size_t>(i)]) {
      e.status = Identifiability::Fixed;
      res.estimates.push_back(e);
      continue;
    }
    e.sigma = std::sqrt(std::max(0.0, res.covariance(i, i)));
    const double rel = std::abs(e.value) > 0 ? e.sigma / std::abs(e.value) : std::numeric_limits<double>::infinity();
    e.status = rel > opts.unidentifiable_relative_sigma ? Identifiability::NotIdentifiable
               : rel > opts.weak_relative_sigma       ? Identifiability::Weak
                                                      : Identifiability::Good;
    e.at_bound = e.value <= par.min * (1 + 1e-9) + 1e-300 || e.value >= par.max * (1 - 1e-9);
    std::string note;
    if (e.at_bound) note += "at its bound; ";
    if (e.status != Identifiability::Good) note += "1 sigma is " + fmt_double(100 * rel, 3) + " % of the value; ";
    for (int j = 0; j < np; ++j) {
      if (j == i || held[static_cast<std::size_t>(j)]) continue;
      const double den = std::sqrt(res.covariance(i, i) * res.covariance(j, j));
      const double rho = den > 0 ? res.covariance(i, j) / den : 0.0;
      if (std::abs(rho) > opts.correlation_warning)
        note += "correlation " + fmt_double(rho, 4) + " with " + net.params[static_cast<std::size_t>(j)].name + "; ";
    }
    e.note = note;
    res.estimates.push_back(e);
  }
  // singular-value view: the weakest direction of the scaled normal matrix and who makes it up
  {
    Eigen::Index imin = 0;
    lam.minCoeff(&imin);
    const Eigen::VectorXd vmin = es.eigenvectors().col(imin);
    std::string who;
    for (int j = 0; j < pr.nf(); ++j)
      if (std::abs(vmin[j]) > 0.3) who += " " + net.params[static_cast<std::size_t>(pr.free[static_cast<std::size_t>(j)])].name;
    if (lam[imin] < 1e-10 * lmax)
      res.warnings.push_back("near-singular direction (singular value ratio " + fmt_double(lam[imin] / lmax, 3) +
                             ") made up of:" + (who.empty() ? " initial states" : who));
    for (auto& e : res.estimates)
      if (e.status == Identifiability::NotIdentifiable)
        res.warnings.push_back("'" + e.name + "' is not identifiable from these recordings (value " + fmt_double(e.value) +
                               " " + e.unit + ", 1 sigma " + fmt_double(e.sigma, 3) + ")");
      else if (e.status == Identifiability::Weak)
        res.warnings.push_back("'" + e.name + "' is only weakly identified (1 sigma " + fmt_double(100 * e.sigma / std::abs(e.value), 3) + " %)");
  }
  // residuals per recording
  for (std::size_t r = 0; r < recs.size(); ++r)
    res.residuals_K.push_back(prediction_residuals(net, res.params, recs[r], res.initial_states[r], extra_of(r)));
  if (!res.converged) res.warnings.push_back("the final stage stopped at the iteration limit before converging");
  res.seconds = seconds_since(t_start);
  return res;
}

}  // namespace btsm::thermal
