#include "host/sim/suite/score.hpp"

#include "host/io/input_error.hpp"
#include "host/io/json_input.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <map>

namespace btsm::sim::suite {
namespace {

double num(const nlohmann::json& j, const char* key) {
  if (!j.contains(key) || !j[key].is_number()) return NAN;
  return j[key].get<double>();
}

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

CaseResult from_truth(const nlohmann::json& truth, double residual_s) {
  CaseResult r;
  r.id = truth.at("id").get<std::string>();
  r.kind = truth.at("kind").get<std::string>();
  r.family = truth.at("family").get<std::string>();
  r.variant = truth.at("variant").get<std::string>();
  r.truth_nodes = truth.at("nodes").get<std::vector<std::string>>();
  r.noise_floor_k = truth.contains("noise_floor_check_K") && truth["noise_floor_check_K"].is_number()
                        ? truth["noise_floor_check_K"].get<double>()
                        : NAN;
  r.goal_factor = truth.value("goal_factor", 5.0);
  r.residual_s = residual_s;
  return r;
}

// A node's name as the networks hold it: no control character (an ESC sequence or a newline
// would go raw to the terminal and table.md), no ',' or '=', not empty.
std::string node_name_problem(const nlohmann::json& n) {
  if (!n.is_string() || n.get_ref<const std::string&>().empty()) return "not a node name";
  if (const std::string why = io::name_problem(n.get<std::string>()); !why.empty()) return "not a node name (it " + why + ")";
  return "";
}

std::string node_list_problem(const nlohmann::json& j, const char* key) {
  if (!j.contains(key)) return "";
  if (!j[key].is_array()) return fmt::format("'{}' is not a list", key);
  for (const auto& n : j[key])
    if (const std::string why = node_name_problem(n); !why.empty())
      return fmt::format("'{}' holds {}, {}", key, io::json_excerpt(n), why);
  return "";
}

// The largest check RMSE an answer can hold: the probes read -200..850 degC, so no recording's
// error comes near it (1e308 was printed as a 309-digit number in the table).
constexpr double kMaxRmseK = 1e4;

std::string string_key_problem(const nlohmann::json& truth, const char* key, const std::string& expected) {
  if (!truth.contains(key) || !truth[key].is_string()) return fmt::format("'{}' is missing or not text", key);
  if (truth[key].get_ref<const std::string&>() != expected)
    return fmt::format("{} '{}' is not the case's {} '{}'", key, truth[key].get<std::string>(), key, expected);
  return "";
}

std::string fmt_k(double v) { return std::isfinite(v) ? fmt::format("{:.4f}", v) : "–"; }

}  // namespace

CaseResult failed_case(const nlohmann::json& truth, const std::string& error, double residual_s) {
  CaseResult r = from_truth(truth, residual_s);
  r.verdict = "error";
  r.error = error;
  return r;
}

std::string answer_shape_problem(const nlohmann::json& answer) {
  if (!answer.is_object()) return "not a JSON object";
  if (!answer.contains("verdict"))  // an answer of a loop that predates `verdict` has its effect name
    return answer.contains("effect") && answer["effect"].is_string() ? "" : "neither 'verdict' nor 'effect'";
  const auto& v = answer["verdict"];
  if (!v.is_string()) return "'verdict' is not text";
  static const char* const kVerdicts[] = {"effect", "partial", "none", "unexplained"};
  if (std::find(std::begin(kVerdicts), std::end(kVerdicts), v.get<std::string>()) == std::end(kVerdicts))
    return "'verdict' is '" + v.get<std::string>() + "', not effect, partial, none or unexplained";
  if (answer.contains("effect") && !answer["effect"].is_string()) return "'effect' is not text";
  // A name no residual run gives (a hand-edited answer, "latent_mass\n| fake | row |") was scored
  // as a claim of some family (probe 5): the ten families, their aliases, none and unexplained.
  if (answer.contains("effect")) {
    static const char* const kFamilies[] = {"heat_source_transient", "temperature_dependent_heat", "coupled_heat",
                                            "extra_heat_input",      "sensor_lag",                 "sensor_drift",
                                            "ambient_dynamics",      "second_boundary",            "event_conductance",
                                            "latent_mass"};
    const std::string e = answer["effect"].get<std::string>();
    bool known = e.empty() || e == "none" || e == "unexplained";
    for (const char* f : kFamilies)
      for (const auto& name : accepted_names(f)) known = known || e == name;
    if (!known) return "'effect' is '" + e + "', not a family the residual loop names";
  }
  if (const std::string why = node_list_problem(answer, "nodes"); !why.empty()) return why;
  for (const char* k : {"rmse_before_K", "rmse_after_K"}) {
    if (!answer.contains(k) || answer[k].is_null()) continue;
    if (!answer[k].is_number()) return std::string("'") + k + "' is not a number";
    if (const double v = answer[k].get<double>(); !(v >= 0 && v <= kMaxRmseK))
      return fmt::format("'{}' is {}, not an RMSE (0..{:g} K)", k, io::json_excerpt(answer[k]), kMaxRmseK);
  }
  if (answer.contains("seconds") && !answer["seconds"].is_null() &&
      !(answer["seconds"].is_number() && answer["seconds"].get<double>() >= 0))
    return "'seconds' is " + io::json_excerpt(answer["seconds"]) + ", not a run time (a number >= 0)";
  return "";
}

std::string truth_problem(const nlohmann::json& truth, const SuiteCase& c) {
  if (!truth.is_object()) return "not a JSON object";
  // id, kind, family and variant follow from the case's folder (its id): they name the table's rows
  if (!truth.contains("id") || !truth["id"].is_string()) return "'id' is missing or not text";
  if (truth["id"].get_ref<const std::string&>() != c.id)
    return fmt::format("id '{}' is not the case's folder '{}'", truth["id"].get<std::string>(), c.id);
  if (!truth.contains("kind") || !truth["kind"].is_string()) return "'kind' is missing or not text";
  if (const std::string kind = truth["kind"].get<std::string>(); kind != case_kind_name(c.kind))
    return fmt::format("kind '{}' is not case {}'s kind '{}' (effect, clean or distractor)", kind, c.id, case_kind_name(c.kind));
  for (const auto& [key, expected] : {std::pair{"family", &c.family}, std::pair{"variant", &c.variant}})
    if (const std::string why = string_key_problem(truth, key, *expected); !why.empty()) return why;
  if (truth.contains("accepted_names")) {
    const auto& names = truth["accepted_names"];
    const auto family_names = accepted_names(c.family);
    std::string listed;
    for (const auto& n : family_names) listed += (listed.empty() ? "" : ", ") + n;
    if (!names.is_array()) return "'accepted_names' is not a list";
    for (const auto& n : names)
      if (!n.is_string() || std::find(family_names.begin(), family_names.end(), n.get<std::string>()) == family_names.end())
        return fmt::format("'accepted_names' holds {}, not a name of family '{}' (the residual loop names it {})", io::json_excerpt(n),
                           c.family, listed);
  }
  for (const char* key : {"nodes", "nodes_allowed"}) {
    if (!truth.contains(key)) return fmt::format("'{}' is missing", key);
    if (const std::string why = node_list_problem(truth, key); !why.empty()) return why;
  }
  for (const auto& n : truth["nodes"])
    if (std::find(truth["nodes_allowed"].begin(), truth["nodes_allowed"].end(), n) == truth["nodes_allowed"].end())
      return fmt::format("'nodes' holds {}, which 'nodes_allowed' does not (no answer could be named)", io::json_excerpt(n));
  if (truth.contains("nodes_matter") && !truth["nodes_matter"].is_boolean()) return "'nodes_matter' is not true or false";
  if (truth.contains("goal_factor") &&
      !(truth["goal_factor"].is_number() && truth["goal_factor"].get<double>() > 1 && truth["goal_factor"].get<double>() <= 1e6))
    return fmt::format("'goal_factor' is {}, not a cut of the check RMSE (a number > 1; at <= 1 every answer meets the goal)",
                       io::json_excerpt(truth["goal_factor"]));
  if (truth.contains("noise_floor_check_K") && !truth["noise_floor_check_K"].is_null() &&
      !(truth["noise_floor_check_K"].is_number() && truth["noise_floor_check_K"].get<double>() >= 0 &&
        truth["noise_floor_check_K"].get<double>() <= kMaxRmseK))
    return fmt::format("'noise_floor_check_K' is {}, not a noise floor (0..{:g} K)", io::json_excerpt(truth["noise_floor_check_K"]),
                       kMaxRmseK);
  return "";
}

CaseResult score_case(const nlohmann::json& truth, const nlohmann::json& answer, double residual_s) {
  CaseResult r = from_truth(truth, residual_s);
  r.effect = answer.value("effect", std::string());
  if (answer.contains("nodes") && answer["nodes"].is_array())
    for (const auto& n : answer["nodes"])
      if (n.is_string()) r.nodes.push_back(n.get<std::string>());
  if (answer.contains("verdict") && answer["verdict"].is_string())
    r.verdict = answer["verdict"].get<std::string>();
  else
    r.verdict = (r.effect == "none" || r.effect == "unexplained" || r.effect.empty()) ? r.effect : "effect";
  r.rmse_before_k = num(answer, "rmse_before_K");
  r.rmse_after_k = num(answer, "rmse_after_K");
  r.claimed = r.verdict == "effect";

  if (r.kind == "effect") {
    const auto names = truth.contains("accepted_names") ? truth["accepted_names"].get<std::vector<std::string>>()
                                                        : accepted_names(r.family);
    r.family_named = std::find(names.begin(), names.end(), r.effect) != names.end() &&
                     (r.verdict == "effect" || r.verdict == "partial");
    bool nodes_ok = true;
    if (truth.value("nodes_matter", true)) {
      const auto allowed = truth.at("nodes_allowed").get<std::vector<std::string>>();
      for (const auto& n : r.truth_nodes)
        if (std::find(r.nodes.begin(), r.nodes.end(), n) == r.nodes.end()) nodes_ok = false;
      for (const auto& n : r.nodes)
        if (std::find(allowed.begin(), allowed.end(), n) == allowed.end()) nodes_ok = false;
    }
    r.named = r.family_named && nodes_ok;
    const bool close_to_floor = std::isfinite(r.noise_floor_k) && r.rmse_after_k <= 2.0 * r.noise_floor_k;
    const bool cut = r.rmse_after_k > 0 && r.cut() >= r.goal_factor;
    r.goal = r.named && r.claimed && (close_to_floor || cut);
  }
  return r;
}

nlohmann::json to_json(const CaseResult& r) {
  const auto n = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  return {{"id", r.id},
          {"kind", r.kind},
          {"family", r.family},
          {"variant", r.variant},
          {"truth_nodes", r.truth_nodes},
          {"verdict", r.verdict},
          {"effect", r.effect},
          {"nodes", r.nodes},
          {"rmse_before_K", n(r.rmse_before_k)},
          {"rmse_after_K", n(r.rmse_after_k)},
          {"noise_floor_K", n(r.noise_floor_k)},
          {"residual_s", n(r.residual_s)},
          {"family_named", r.family_named},
          {"named", r.named},
          {"claimed", r.claimed},
          {"goal", r.goal},
          {"error", r.error}};
}

std::vector<TableRow> summarize(const std::vector<CaseResult>& results) {
  std::vector<TableRow> rows;
  std::map<std::string, size_t> index;
  std::map<std::string, std::vector<const CaseResult*>> members;
  for (const auto& r : results) {
    const bool quiet = r.kind != "effect";
    const std::string group = quiet ? (r.kind == "clean" ? std::string("clean") : "distractor: " + r.variant)
                                    : r.family + " (" + r.variant + ")";
    if (!index.count(group)) {
      index[group] = rows.size();
      rows.push_back({});
      rows.back().group = group;
      rows.back().quiet = quiet;
    }
    members[group].push_back(&r);
  }
  for (auto& row : rows) {
    std::vector<double> before, after, floors;
    double worst_cut = INFINITY;
    for (const CaseResult* r : members[row.group]) {
      ++row.cases;
      row.family_named += r->family_named;
      row.named += r->named;
      row.claimed += r->claimed;
      row.partial += r->verdict == "partial";
      row.goal += r->goal;
      row.errors += r->verdict == "error";
      before.push_back(r->rmse_before_k);
      after.push_back(r->rmse_after_k);
      floors.push_back(r->noise_floor_k);
      if (std::isfinite(r->cut()) && r->cut() < worst_cut) {
        worst_cut = r->cut();
        row.worst_before = r->rmse_before_k;
        row.worst_after = r->rmse_after_k;
      }
    }
    row.before_median = median(before);
    row.after_median = median(after);
    row.floor_median = median(floors);
  }
  return rows;
}

std::string markdown_table(const std::vector<TableRow>& rows) {
  std::string s =
      "| family (variant) | cases | named (family + nodes) | family only | check RMSE before → after, median (K) | "
      "worst case (K) | noise floor (K) | goal met |\n|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : rows) {
    if (r.quiet) continue;
    const double worst_cut = r.worst_before / r.worst_after;
    s += fmt::format("| {} | {} | {}/{} | {}/{} | {} → {} | {} → {} (×{}) | {} | {}/{} |\n", r.group, r.cases, r.named,
                     r.cases, r.family_named, r.cases, fmt_k(r.before_median), fmt_k(r.after_median),
                     fmt_k(r.worst_before), fmt_k(r.worst_after),
                     std::isfinite(worst_cut) ? fmt::format("{:.1f}", worst_cut) : "–", fmt_k(r.floor_median), r.goal,
                     r.cases);
  }
  s += "\n| data without an effect | cases | false claims | partial | check RMSE before → after, median (K) | noise floor (K) |\n"
       "|---|---|---|---|---|---|\n";
  for (const auto& r : rows) {
    if (!r.quiet) continue;
    s += fmt::format("| {} | {} | {}/{} | {}/{} | {} → {} | {} |\n", r.group, r.cases, r.claimed, r.cases, r.partial,
                     r.cases, fmt_k(r.before_median), fmt_k(r.after_median), fmt_k(r.floor_median));
  }
  int errors = 0;
  for (const auto& r : rows) errors += r.errors;
  if (errors) s += fmt::format("\n{} case(s) gave no answer (see results.csv, column error).\n", errors);
  return s;
}

namespace {
// RFC 4180: a field holding a comma, a quote or a line break is quoted, its quotes doubled (an id
// or an error text with a comma shifted every later column; one with a newline split the row).
std::string csv_field(const std::string& v) {
  if (v.find_first_of(",\"\r\n") == std::string::npos) return v;
  std::string q = "\"";
  for (char c : v) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}
}  // namespace

std::string results_csv(const std::vector<CaseResult>& results) {
  std::string s =
      "id,kind,family,variant,truth_nodes,verdict,effect,nodes,rmse_before_K,rmse_after_K,noise_floor_K,cut,"
      "family_named,named,claimed,goal,residual_s,error\n";
  const auto list = [](const std::vector<std::string>& v) {
    std::string o;
    for (const auto& x : v) o += (o.empty() ? "" : "+") + x;
    return o;
  };
  const auto f = [](double v) { return std::isfinite(v) ? fmt::format("{:.6g}", v) : std::string(); };
  for (const auto& r : results) {
    const auto q = csv_field;
    s += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", q(r.id), q(r.kind), q(r.family), q(r.variant),
                     q(list(r.truth_nodes)), q(r.verdict), q(r.effect), q(list(r.nodes)), f(r.rmse_before_k), f(r.rmse_after_k),
                     f(r.noise_floor_k), f(r.cut()), int(r.family_named), int(r.named), int(r.claimed), int(r.goal),
                     f(r.residual_s), q(r.error));
  }
  return s;
}

}  // namespace btsm::sim::suite
