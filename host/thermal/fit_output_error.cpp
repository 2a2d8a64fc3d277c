// The output-error evaluator of the fit: exact ZOH simulation of every run, forward sensitivities
// and the normal equations (see fit_output_error.hpp).
#include "fit_output_error.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <thread>

namespace btsm::thermal::fitting {

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

OutputErrorEvaluator::OutputErrorEvaluator(OutputErrorProblem& pr) : pr_(pr) {
  for (Mode m : {Mode::Operating, Mode::Cooling}) used_[m == Mode::Operating ? 0 : 1] = params_used(*pr.net, m);
  for (const auto& r : pr.runs) {
    uses_extra_ = uses_extra_ || r.extra != nullptr;
    if (pr.net->has_inputs() && !r.inputs)
      throw std::invalid_argument("fit: the network uses declared columns but a run has no inputs");
  }
  for (const auto& m : pr.net->measurements) {
    int j = -1;
    for (int f = 0; f < pr.nf(); ++f)
      if (m.drift_param >= 0 && pr.free[static_cast<std::size_t>(f)] == m.drift_param) j = f;
    drift_free_.push_back(j);
  }
  std::map<Key, int> numbered;
  for (const auto& run : pr.runs) {
    std::vector<int> steps;
    steps.reserve(run.end - run.begin);
    for (std::size_t k = run.begin; k < run.end; ++k) {
      const Key key = key_of(run, k);
      auto it = numbered.find(key);
      if (it == numbered.end()) {
        it = numbered.emplace(key, static_cast<int>(key_list_.size())).first;
        key_list_.push_back(key);
      }
      steps.push_back(it->second);
    }
    step_key_.push_back(std::move(steps));
  }
}

OutputErrorEvaluator::Key OutputErrorEvaluator::key_of(const Run& run, std::size_t k) {
  const Recording& rec = *run.rec;
  const unsigned mask = run.inputs && !run.inputs->event_mask.empty() ? run.inputs->event_mask[k] : 0u;
  return {rec.speed_rpm[k], mask, rec.time_s[k + 1] - rec.time_s[k]};
}

Evaluation OutputErrorEvaluator::evaluate(const Eigen::VectorXd& u, bool with_jacobian) {
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

namespace {

// y = A x for a column-major rows x cols matrix A (rows / cols fixed at compile time when > 0):
// every y_i is summed over the columns in ascending order, one product added at a time, which is
// the order Eigen's coefficient-based (lazy) product sums in; the figures therefore do not change
// with the node count being known at compile time, only the loop overhead of n = 4..8 goes.
template <int R, int C>
[[gnu::always_inline]] inline void multiply_columns(const double* a, Eigen::Index rows_rt, Eigen::Index cols_rt, const double* x, double* y) {
  const Eigen::Index rows = R > 0 ? R : rows_rt;
  const Eigen::Index cols = C > 0 ? C : cols_rt;
  const double x0 = x[0];
  for (Eigen::Index i = 0; i < rows; ++i) y[i] = a[i] * x0;
  for (Eigen::Index k = 1; k < cols; ++k) {
    const double xk = x[k];
    const double* ak = a + k * rows;
    for (Eigen::Index i = 0; i < rows; ++i) y[i] += ak[i] * xk;
  }
}

}  // namespace

template <class Sink>
void OutputErrorEvaluator::simulate_run(std::size_t ri, bool with_jacobian, Sink&& sink) const {
  // The step recursion is a few hundred flops on 4..8 nodes: with the node count a compile-time
  // constant the small products unroll (same sums in the same order as the general case).
  switch (pr_.n()) {
    case 2: return simulate_run_n<2>(ri, with_jacobian, sink);
    case 3: return simulate_run_n<3>(ri, with_jacobian, sink);
    case 4: return simulate_run_n<4>(ri, with_jacobian, sink);
    case 5: return simulate_run_n<5>(ri, with_jacobian, sink);
    case 6: return simulate_run_n<6>(ri, with_jacobian, sink);
    case 7: return simulate_run_n<7>(ri, with_jacobian, sink);
    case 8: return simulate_run_n<8>(ri, with_jacobian, sink);
    default: return simulate_run_n<Eigen::Dynamic>(ri, with_jacobian, sink);
  }
}

template <int N, class Sink>
void OutputErrorEvaluator::simulate_run_n(std::size_t ri, bool with_jacobian, Sink&& sink) const {
  using MatN = Eigen::Matrix<double, N, N>;
  using MatNF = Eigen::Matrix<double, N, Eigen::Dynamic>;
  using VecN = Eigen::Matrix<double, N, 1>;
  const int n = pr_.n(), nf = pr_.nf();
  MatNF S(n, nf), Snext(n, nf);
  MatN X, Xnext;
  VecN x, xnext, extra, gained;
  X.resize(n, n);
  Xnext.resize(n, n);
  x.resize(n);
  xnext.resize(n);
  extra.setZero(n);
  gained.setZero(n);
  Eigen::VectorXd dv(n * nf), dv_extra(n * nf);
  const Run& run = pr_.runs[ri];
  const Recording& rec = *run.rec;
  const auto& meas = pr_.net->measurements;
  const std::vector<int>& step_key = step_key_[ri];
  const Eigen::Index nb = run.inputs ? run.inputs->boundary_c.cols() : 0;
  Eigen::RowVectorXd drow(nf);
  x = pr_.x0[ri];
  S.setZero();
  X.setIdentity();
  // a held initial state has no sensitivity: its unknown stays where it started
  for (std::size_t i = 0; i < pr_.x0_held.size(); ++i)
    if (pr_.x0_held[i]) X(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(i)) = 0.0;
  for (std::size_t k = run.begin; k <= run.end; ++k) {
    const auto kr = static_cast<Eigen::Index>(k);
    for (std::size_t m = 0; m < run.cols.size(); ++m) {
      const double y = rec.temp_c(kr, run.cols[m]);
      if (!std::isfinite(y)) continue;
      const int node = meas[m].node;
      if (meas[m].drift_param < 0) {
        sink(k - run.begin, m, x[node] - y, S.row(node), X.row(node));
        continue;
      }
      // a drifting probe reads drift [K/h] x hours since the recording's first sample too high,
      // plus its offset at that sample (a nuisance per recording, eliminated by the caller)
      const double hours = (rec.time_s[k] - rec.time_s.front()) / 3600.0;
      drow = S.row(node);
      const int j = drift_free_[m];
      if (j >= 0) drow[j] += hours * pr_.tf[static_cast<std::size_t>(j)].dp_dz(pr_.tf[static_cast<std::size_t>(j)].to_z(pr_.p[meas[m].drift_param]));
      sink(k - run.begin, m, x[node] + pr_.p[meas[m].drift_param] * hours - y, drow, X.row(node));
    }
    if (k == run.end) break;
    const double amb = rec.ambient_c[k];
    const KeyData& kd = keys_[static_cast<std::size_t>(step_key[k - run.begin])];
    const double* phi = kd.base.Phi.data();
    multiply_columns<N, N>(phi, n, n, x.data(), xnext.data());
    xnext += Eigen::Map<const VecN>(kd.base.drive.data(), n) + Eigen::Map<const VecN>(kd.base.ambient_gain.data(), n) * amb;
    for (Eigen::Index b = 0; b < nb; ++b)
      xnext += Eigen::Map<const VecN>(kd.base.boundary_gain.col(b).data(), n) * run.inputs->boundary_c(kr, b);
    if (run.extra) {
      extra = run.extra->row(kr).transpose();
      multiply_columns<N, N>(kd.base.Gamma.data(), n, n, extra.data(), gained.data());
      xnext += gained;
    }
    if (with_jacobian) {
      // S' = Phi S + dPhi/dz x (+ dGamma/dz extra) + d drive/dz + d ambient_gain/dz amb (+ boundary
      // terms); the buffers swap rather than copy.
      multiply_columns<Eigen::Dynamic, N>(kd.dphi_stack.data(), n * nf, n, x.data(), dv.data());
      if (run.extra) {
        multiply_columns<Eigen::Dynamic, N>(kd.dgamma_stack.data(), n * nf, n, extra.data(), dv_extra.data());
        dv += dv_extra;
      }
      for (int j = 0; j < nf; ++j) multiply_columns<N, N>(phi, n, n, S.col(j).data(), Snext.col(j).data());
      Snext += Eigen::Map<const MatNF>(dv.data(), n, nf) + Eigen::Map<const MatNF>(kd.ddrive.data(), n, nf) +
               Eigen::Map<const MatNF>(kd.damb.data(), n, nf) * amb;
      for (Eigen::Index b = 0; b < nb; ++b)
        Snext += Eigen::Map<const MatNF>(kd.dbnd[static_cast<std::size_t>(b)].data(), n, nf) * run.inputs->boundary_c(kr, b);
      S.swap(Snext);
      if (pr_.estimate_x0) {
        for (int j = 0; j < n; ++j) multiply_columns<N, N>(phi, n, n, X.col(j).data(), Xnext.col(j).data());
        X.swap(Xnext);
      }
    }
    x.swap(xnext);
  }
}

void OutputErrorEvaluator::evaluate_run(std::size_t ri, bool with_jacobian, int local, Evaluation& ev) const {
  const int n = pr_.n(), nf = pr_.nf();
  // A drifting probe's offset at the recording's start is unknown (the recording does not say how
  // long the probe has been drifting): one constant per recording and drifting column, eliminated
  // exactly (variable projection). For a constant c with dr/dc = 1 over the column's N cells, the
  // reduced problem is r - mean r, J - mean J: ssr - (sum r)^2/N, J'J - s s'/N, J'r - s (sum r)/N,
  // s = sum of the Jacobian rows; so each is accumulated alongside the run.
  const auto& meas = pr_.net->measurements;
  std::vector<double> off_sum_r(meas.size(), 0.0), off_count(meas.size(), 0.0);
  std::vector<Eigen::VectorXd> off_sum_j(meas.size());
  auto drifting = [&](std::size_t m) { return meas[m].drift_param >= 0; };
  auto reduce_ssr = [&] {
    for (std::size_t m = 0; m < meas.size(); ++m)
      if (drifting(m) && off_count[m] > 0) ev.ssr -= off_sum_r[m] * off_sum_r[m] / off_count[m];
  };
  if (!with_jacobian) {
    simulate_run(ri, false, [&](std::size_t, std::size_t m, double r, const auto&, const auto&) {
      ev.ssr += r * r;
      ++ev.count;
      if (drifting(m)) {
        off_sum_r[m] += r;
        off_count[m] += 1;
      }
    });
    reduce_ssr();
    return;
  }
  for (std::size_t m = 0; m < meas.size(); ++m)
    if (drifting(m)) off_sum_j[m] = Eigen::VectorXd::Zero(local);
  // J^T J of the run from Jacobian rows gathered in blocks (a rank-k update beats k rank-1 ones).
  // The rows are written into a row-major buffer (one contiguous store per row, where a
  // column-major one takes a cache line per entry) and moved into the column-major block the
  // products read at each flush.
  constexpr int kBlock = 512;
  Eigen::MatrixXd jbuf(kBlock, local);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> jrows(kBlock, local);
  Eigen::VectorXd rbuf(kBlock);
  Eigen::MatrixXd Hl = Eigen::MatrixXd::Zero(local, local);
  Eigen::VectorXd gl = Eigen::VectorXd::Zero(local);
  int fill = 0;
  auto flush = [&] {
    if (fill == 0) return;
    jbuf.topRows(fill) = jrows.topRows(fill);
    Hl.selfadjointView<Eigen::Lower>().rankUpdate(jbuf.topRows(fill).transpose());
    gl.noalias() += jbuf.topRows(fill).transpose() * rbuf.head(fill);
    fill = 0;
  };
  simulate_run(ri, true, [&](std::size_t, std::size_t m, double r, const auto& d_params, const auto& d_x0) {
    ev.ssr += r * r;
    ++ev.count;
    jrows.row(fill).head(nf) = d_params;
    if (pr_.estimate_x0) jrows.row(fill).tail(n) = d_x0;
    rbuf[fill] = r;
    if (drifting(m)) {
      off_sum_r[m] += r;
      off_count[m] += 1;
      off_sum_j[m] += jrows.row(fill).transpose();
    }
    if (++fill == kBlock) flush();
  });
  flush();
  Hl.triangularView<Eigen::Upper>() = Hl.transpose();
  reduce_ssr();
  for (std::size_t m = 0; m < meas.size(); ++m)
    if (drifting(m) && off_count[m] > 0) {
      Hl.noalias() -= off_sum_j[m] * off_sum_j[m].transpose() / off_count[m];
      gl.noalias() -= off_sum_j[m] * (off_sum_r[m] / off_count[m]);
    }
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

Eigen::MatrixXd OutputErrorEvaluator::row_scores(std::size_t ri, const Eigen::VectorXd& u) {
  apply(u);
  build_keys(true);
  const int n = pr_.n(), nf = pr_.nf();
  const Run& run = pr_.runs[ri];
  const int local = nf + (pr_.estimate_x0 ? n : 0);
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(run.end - run.begin + 1), local);
  // a drifting probe's per-recording offset (see evaluate_run): the scores of the reduced problem,
  // (r - mean r)(J - mean J), need the means first
  const auto& meas = pr_.net->measurements;
  std::vector<double> mean_r(meas.size(), 0.0), count(meas.size(), 0.0);
  std::vector<Eigen::VectorXd> mean_j(meas.size(), Eigen::VectorXd::Zero(local));
  Eigen::VectorXd row_j(local);
  bool any_drift = false;
  for (const auto& m : meas) any_drift = any_drift || m.drift_param >= 0;
  if (any_drift) {
    simulate_run(ri, true, [&](std::size_t, std::size_t m, double r, const auto& dp, const auto& dx) {
      if (meas[m].drift_param < 0) return;
      mean_r[m] += r;
      count[m] += 1;
      mean_j[m].head(nf) += dp.transpose();
      if (pr_.estimate_x0) mean_j[m].tail(n) += dx.transpose();
    });
    for (std::size_t m = 0; m < meas.size(); ++m)
      if (count[m] > 0) {
        mean_r[m] /= count[m];
        mean_j[m] /= count[m];
      }
  }
  simulate_run(ri, true, [&](std::size_t row, std::size_t m, double r, const auto& dp, const auto& dx) {
    const auto k = static_cast<Eigen::Index>(row);
    row_j.head(nf) = dp.transpose();
    if (pr_.estimate_x0) row_j.tail(n) = dx.transpose();
    if (meas[m].drift_param >= 0) G.row(k) += ((r - mean_r[m]) * (row_j - mean_j[m])).transpose();
    else G.row(k) += (r * row_j).transpose();
  });
  return G;
}

void OutputErrorEvaluator::gauge(const Eigen::VectorXd& u, bool with_jacobian, Evaluation& ev) const {
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

void OutputErrorEvaluator::apply(const Eigen::VectorXd& u) {
  for (int j = 0; j < pr_.nf(); ++j) pr_.p[pr_.free[static_cast<std::size_t>(j)]] = pr_.tf[static_cast<std::size_t>(j)].to_p(u[j]);
  if (pr_.estimate_x0)
    for (std::size_t r = 0; r < pr_.runs.size(); ++r)
      pr_.x0[r] = u.segment(pr_.nf() + static_cast<int>(r) * pr_.n(), pr_.n());
}

void OutputErrorEvaluator::build_keys(bool with_jacobian) {
  keys_.assign(key_list_.size(), KeyData{});
  const int n = pr_.n(), nf = pr_.nf();
  const std::size_t nb = pr_.net->boundaries.size();
  std::map<std::pair<double, unsigned>, ModalForm> modal;
  for (std::size_t ki = 0; ki < key_list_.size(); ++ki) {
    const Key& key = key_list_[ki];
    const double speed = std::get<0>(key), dt = std::get<2>(key);
    const unsigned mask = std::get<1>(key);
    const auto mkey = std::make_pair(speed, mask);
    auto mit = modal.find(mkey);
    if (mit == modal.end()) mit = modal.emplace(mkey, modal_form(assemble(*pr_.net, pr_.p, speed, mask))).first;
    KeyData kd;
    kd.base = step_matrices(mit->second, dt);
    if (with_jacobian) {
      kd.dphi_stack = Eigen::MatrixXd::Zero(n * nf, n);
      if (uses_extra_) kd.dgamma_stack = Eigen::MatrixXd::Zero(n * nf, n);
      kd.ddrive = Eigen::MatrixXd::Zero(n, nf);
      kd.damb = Eigen::MatrixXd::Zero(n, nf);
      kd.dbnd.assign(nb, Eigen::MatrixXd::Zero(n, nf));
      const auto& used = used_[pr_.net->mode_at(speed) == Mode::Operating ? 0 : 1];
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
        const StepMatrices sp = step_matrices(modal_form(assemble(*pr_.net, pp, speed, mask)), dt);
        const StepMatrices sm = step_matrices(modal_form(assemble(*pr_.net, pm, speed, mask)), dt);
        const double inv = 1.0 / (2 * h);
        kd.dphi_stack.middleRows(j * n, n) = (sp.Phi - sm.Phi) * inv;
        if (uses_extra_) kd.dgamma_stack.middleRows(j * n, n) = (sp.Gamma - sm.Gamma) * inv;
        kd.ddrive.col(j) = (sp.drive - sm.drive) * inv;
        kd.damb.col(j) = (sp.ambient_gain - sm.ambient_gain) * inv;
        for (std::size_t b = 0; b < nb; ++b)
          kd.dbnd[b].col(j) = (sp.boundary_gain.col(static_cast<Eigen::Index>(b)) - sm.boundary_gain.col(static_cast<Eigen::Index>(b))) * inv;
      }
      // dv = dphi_stack * x is laid out block-wise (j*n + i); the evaluator maps it as an
      // n x nf column-major matrix, which is exactly that layout.
    }
    keys_[ki] = std::move(kd);
  }
}

Eigen::VectorXd pack(const OutputErrorProblem& pr) {
  Eigen::VectorXd u(pr.unknowns());
  for (int j = 0; j < pr.nf(); ++j) u[j] = pr.tf[static_cast<std::size_t>(j)].to_z(pr.p[pr.free[static_cast<std::size_t>(j)]]);
  if (pr.estimate_x0)
    for (std::size_t r = 0; r < pr.runs.size(); ++r) u.segment(pr.nf() + static_cast<int>(r) * pr.n(), pr.n()) = pr.x0[r];
  return u;
}

void clamp_to_bounds(const OutputErrorProblem& pr, Eigen::VectorXd& u) {
  for (int j = 0; j < pr.nf(); ++j) {
    const Transform& t = pr.tf[static_cast<std::size_t>(j)];
    u[j] = std::clamp(u[j], t.zmin, t.zmax);
  }
}

}  // namespace btsm::thermal::fitting
