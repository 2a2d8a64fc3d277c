// Start values for the fit's output-error stages (see fit_starts.hpp).
#include "fit_starts.hpp"

#include "fit_support.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace btsm::thermal::fitting {

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
              if (o < 0) continue;  // ambient or a declared boundary: always known
              for (std::size_t k = b; k <= last && ok; ++k) ok = std::isfinite(d.temps(static_cast<Eigen::Index>(k), o));
            }
            for (const auto& src : net.sources) {
              if (!ok) break;
              if (src.node != i) continue;
              for (const auto& t : mode == Mode::Operating ? src.operating : src.cooling)
                for (int o : {t.hot, t.cold})
                  if (t.driven && o >= 0)
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
              const unsigned mask = d.inputs && !d.inputs->event_mask.empty() ? d.inputs->event_mask[k] : 0u;
              auto present = [&](const Term& t) { return t.event < 0 || ((mask >> t.event) & 1u) != 0; };
              // temperature of a link end or driven-term end over the interval's ends (ambient and
              // boundaries are held over the interval, as the simulator does)
              auto end_temp = [&](int o, Eigen::Index row) {
                if (o == kAmbient) return rec.ambient_c[k];
                if (is_boundary_end(o)) return d.inputs->boundary_c(k0, boundary_of_end(o));
                return d.temps(row, o);
              };
              for (const auto& l : net.links) {
                if (l.a != i && l.b != i) continue;
                const int o = l.a == i ? l.b : l.a;
                const double f0 = end_temp(o, k0) - d.temps(k0, i);
                const double f1 = end_temp(o, k1) - d.temps(k1, i);
                const double area = 0.5 * (f0 + f1) * dt;
                for (const auto& t : mode == Mode::Operating ? l.operating : l.cooling) {
                  if (!present(t)) continue;
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
                  if (!present(t)) continue;
                  const double sf = t.speed_exponent == 0.0 ? 1.0 : std::pow(s, t.speed_exponent);
                  // a driven term's heat is value x (T_hot - T_cold), averaged over the interval
                  const double drive = t.driven ? 0.5 * (end_temp(t.hot, k0) - end_temp(t.cold, k0) + end_temp(t.hot, k1) -
                                                         end_temp(t.cold, k1))
                                                : 1.0;
                  const int c = col_of[static_cast<std::size_t>(t.param)];
                  if (c >= 0) integ[c] += sf * drive * dt;
                  else known_integ += p[t.param] * sf * drive * dt;
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
      if (other >= 0 && measured[static_cast<std::size_t>(other)] &&
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

void start_unreached_from_peers(const Network& net, const std::vector<int>& wanted, const std::vector<int>& got,
                                double sum_c, Eigen::VectorXd& p, std::vector<std::string>& warnings) {
  const auto unit_of = [&](int j) -> const std::string& { return net.params[static_cast<std::size_t>(j)].unit; };
  const int np = static_cast<int>(net.params.size());
  // The geometric mean of the other parameters of i's unit that have a positive value.
  const auto peer_mean = [&](int i) {
    double log_sum = 0;
    int n = 0;
    for (int j = 0; j < np; ++j)
      if (j != i && unit_of(j) == unit_of(i) && std::isfinite(p[j]) && p[j] > 0) {
        log_sum += std::log(p[j]);
        ++n;
      }
    return n > 0 ? std::exp(log_sum / n) : std::numeric_limits<double>::quiet_NaN();
  };
  // The parameters still to start: a capacitance among them is not a known part of the gauge.
  std::vector<int> pending;
  for (int i : wanted)
    if (std::find(got.begin(), got.end(), i) == got.end()) pending.push_back(i);
  const auto is_pending = [&](int j) { return std::find(pending.begin(), pending.end(), j) != pending.end(); };
  for (int i : wanted) {
    if (!is_pending(i)) continue;
    const auto& par = net.params[static_cast<std::size_t>(i)];
    // A value on entry is what the equation-error solve left when its passes ended with other
    // parameters still failing: not confirmed by the data, so it is replaced like a missing one.
    const std::string why = std::isfinite(p[i])
                                ? "the equation-error solve left it unsettled: parameters kept coming out non-positive, as "
                                  "when the heat balances disagree between recordings (a drifting probe) or terms are collinear"
                                : "its nodes are not measured";
    double start = std::numeric_limits<double>::quiet_NaN();
    std::string from = "from its peers";
    if (par.unit == "J/K" && std::isfinite(sum_c)) {
      double known = 0;
      int unknown = 0;
      for (int j = 0; j < np; ++j)
        if (unit_of(j) == "J/K") {
          if (std::isfinite(p[j]) && !is_pending(j)) known += p[j];
          else ++unknown;
        }
      if (unknown > 0 && sum_c > known) start = (sum_c - known) / unknown;
      if (std::isfinite(p[i])) from = "as an equal share of what the settled capacitances leave of the gauge";
    } else {
      start = peer_mean(i);
    }
    // Fallbacks where the rule above has nothing to share out (the capacitance gauge already used
    // up by the others, no peer started): the geometric mean of the parameters of its unit, then
    // the network's nominal (design) value. Either only starts the output-error stages that follow.
    if (!std::isfinite(start) || start <= 0) {
      start = peer_mean(i);
      from = "at the geometric mean of the other " + par.unit + " parameters";
    }
    if ((!std::isfinite(start) || start <= 0) && std::isfinite(par.nominal) && par.nominal > 0) {
      start = par.nominal;
      from = "at the network's nominal value";
    }
    if (!std::isfinite(start) || start <= 0)
      throw std::invalid_argument("fit: could not start '" + par.name + "' (" + par.unit + ") from the data: " + why +
                                  "; no other parameter of unit " + par.unit +
                                  " was started and the network gives it no nominal value; give an initial value");
    p[i] = std::clamp(start, par.min, par.max);
    pending.erase(std::find(pending.begin(), pending.end(), i));
    warnings.push_back("'" + par.name + "' could not be started from the data (" + why + "): started at " +
                       fmt_double(p[i]) + " " + par.unit + " " + from + "; its estimate rests on the output-error fit alone");
  }
}

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

}  // namespace btsm::thermal::fitting
