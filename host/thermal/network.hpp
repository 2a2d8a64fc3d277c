#pragma once
// Thermal network models (lumped RC networks) described by data, not code.
//
//   C_i dT_i/dt = sum_links g_l(w) (T_other - T_i) + Q_i(w) + extra_i(t)
//
// T are node temperatures in degC; links may go to "ambient", the boundary temperature taken from
// the recording's ambient_c column over time. Every conductance and heat source is a sum of
// TERMS, each `value = p * (w / w0)^e` of one named parameter p: a link term of kind Resistance
// contributes g = 1/value (K/W -> W/K), of kind Conductance g = value; a source term contributes
// value watts. A link or source lists its terms separately for the operating mode (speed above
// `operating_above_rpm`) and for natural cooling (at or below); a parameter may appear in both.
//
// The JSON format (see host/thermal/presets/spindle4.json and docs in README "Network JSON"):
// {
//   "name": "...", "speed_ref_rpm": 5000, "operating_above_rpm": 0,
//   "sum_capacitance_J_per_K": 20478.7,          // optional scale gauge (null/absent = none)
//   "parameters": [ {"name": "R12", "unit": "K/W", "nominal": 0.1263, "initial": 0.13 | "auto",
//                    "min": 1e-4, "max": 1e3, "fixed": false, "log": true, "description": ""} ],
//   "nodes": [ {"name": "rear_bearing", "capacitance": "C1"} ],
//   "links": [ {"name": "R12", "between": ["rear_bearing", "housing"],
//               "both":      [ {"resistance": "R12"} ],
//               "operating": [ {"resistance": "rav1", "speed_exponent": -0.5} ],
//               "cooling":   [ {"conductance": "Gc"} ] } ],
//   "sources": [ {"name": "Qf1", "node": "rear_bearing",
//                 "operating": [ {"power": "qf1", "speed_exponent": 1.6667} ] } ],
//   "measurements": [ {"column": "T1", "node": "rear_bearing"} ],
//   "boundaries": ["coolant_c"],                 // optional: further boundary temperature columns
//   "events": ["lid_open"]                       // optional: 0/1 event columns that switch terms
// }
// Cooling-mode terms must have speed_exponent 0 (the speed may be 0 there).
//
// Declared inputs besides speed and ambient (recording columns declared as `boundary_columns` or
// `event_columns`, see declared_columns.hpp). A link may end at a boundary column instead of
// "ambient" ("between": ["housing", "coolant_c"]): that end is held at the recorded temperature,
// exactly as the ambient is. A term may carry "event": "lid_open": it is present only while that
// column is 1 (e.g. a conductance to the room while the lid is open). Both keep the model linear
// and piecewise constant between samples, so the simulation stays exact.
//
// Two model terms beyond conduction and fixed heat, used by the effects the residual loop adds:
//  * a source term may be driven by a temperature difference, {"power": "g", "speed_exponent": 1,
//    "driven_by": ["rear_bearing", "housing"]}: heat g (w/w0)^e (T_rear_bearing - T_housing) W at
//    the source's node (g in W/K; either end may be "ambient"). With ["n", "ambient"] at node n it
//    is heat that grows (g > 0) or falls (g < 0) with the node's own rise. A difference that does
//    not involve the heated node makes the system matrix non-symmetric; the simulator then takes
//    the general matrix exponential instead of the symmetric modal form.
//  * a measurement may drift, {"column": "T1", "node": "rear_bearing", "drift": "d_T1"}: the probe
//    reads d_T1 [K/h] x the hours since the recording's first sample above its node.
//
// Augmented networks (e.g. a residual effect found later) are built by add_parameter() and by
// pushing further Link/Source entries; call validate() afterwards.
#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

namespace btsm::thermal {

enum class Mode { Operating, Cooling };
const char* mode_name(Mode m);

struct Parameter {
  std::string name;
  std::string unit;             // "K/W", "W/K", "W", "J/K", ... (informative)
  double nominal = std::numeric_limits<double>::quiet_NaN();  // design/literature value (simulation default)
  double initial = 1.0;         // fit start value in `unit`; ignored when initial_auto
  bool initial_auto = true;     // let the fit pipeline find a start
  double min = 1e-9;            // bounds in `unit`
  double max = 1e9;
  bool fixed = false;           // held at `initial` by the fit (also fixes the scale gauge)
  bool log_scale = true;        // fit log(p) (needs min > 0); false for e.g. sources that may be 0
  std::string description;
};

enum class TermKind { Resistance, Conductance, Power };
struct Term {
  int param = -1;               // index into Network::params
  TermKind kind = TermKind::Resistance;
  double speed_exponent = 0.0;  // value = p * (w/w0)^speed_exponent
  int event = -1;               // index into Network::events: present only while that column is 1; -1 = always
  // Source terms only: the heat is value x (T_hot - T_cold), value in W/K (hot/cold: node or kAmbient).
  bool driven = false;
  int hot = 0, cold = 0;
};

constexpr int kAmbient = -1;
// Link end of boundary column k (Network::boundaries[k]): -2, -3, ...
constexpr int boundary_end(int k) { return -2 - k; }
constexpr bool is_boundary_end(int b) { return b <= -2; }
constexpr int boundary_of_end(int b) { return -2 - b; }
constexpr int kMaxEvents = 16;  // event states are keyed as a bit mask

struct Link {
  std::string name;
  int a = 0, b = kAmbient;      // node indices; b may be kAmbient or boundary_end(k)
  std::vector<Term> operating;  // terms present in the operating mode
  std::vector<Term> cooling;    // terms present in natural cooling
};

struct Source {
  std::string name;
  int node = 0;
  std::vector<Term> operating;  // kind Power, watts
  std::vector<Term> cooling;
};

struct Node {
  std::string name;
  int capacitance_param = -1;   // J/K
};

struct Measurement {
  std::string column;           // recording channel name, e.g. "T1"
  int node = 0;
  // K/h: the probe reads this x hours since the recording's first sample too high, plus an offset
  // per recording that nothing tells (how long it drifted before): fitted and evaluated as a
  // nuisance constant per recording, like the initial state; -1 = none
  int drift_param = -1;
};

struct Network {
  std::string name;
  double speed_ref_rpm = 5000.0;       // w0 of the speed laws
  double operating_above_rpm = 0.0;    // speed > this = operating mode
  double sum_capacitance_J_per_K = std::numeric_limits<double>::quiet_NaN();  // gauge, NaN = none
  std::vector<Parameter> params;
  std::vector<Node> nodes;
  std::vector<Link> links;
  std::vector<Source> sources;
  std::vector<Measurement> measurements;
  std::vector<std::string> boundaries;  // further boundary temperature columns (degC), link ends boundary_end(k)
  std::vector<std::string> events;      // event columns (0/1) that switch terms, bit k of an event mask

  bool has_inputs() const { return !boundaries.empty() || !events.empty(); }
  // True when a source term is driven by a temperature difference (see above).
  bool has_driven_terms() const;
  // True when a measurement drifts.
  bool has_drift() const;
  int node_count() const { return static_cast<int>(nodes.size()); }
  int param_count() const { return static_cast<int>(params.size()); }
  int param_index(const std::string& name) const;   // -1 if absent
  int node_index(const std::string& name) const;    // -1 if absent
  bool has_probe(int node) const;                   // some measurement reads this node
  Mode mode_at(double speed_rpm) const { return speed_rpm > operating_above_rpm ? Mode::Operating : Mode::Cooling; }
  // Appends a parameter (name must be new); returns its index.
  int add_parameter(const Parameter& p);
  // Throws std::invalid_argument naming the offending entry if indices, bounds or exponents are bad.
  void validate() const;
  // Parameter names in order.
  std::vector<std::string> param_names() const;
};

// The continuous-time model at one speed (and event state):
//   C dT/dt = -G T + g_amb T_amb + G_bnd T_bnd + heat_w + extra.
struct NodeMatrices {
  Eigen::VectorXd capacitance;          // J/K
  Eigen::MatrixXd G;                    // W/K, symmetric, includes links to ambient/boundaries on the diagonal
  Eigen::VectorXd ambient_conductance;  // W/K per node
  Eigen::MatrixXd boundary_conductance; // W/K, nodes x boundaries (empty columns without boundaries)
  Eigen::VectorXd heat_w;               // W per node from the sources
  Eigen::MatrixXd source_to_node;       // nodes x sources: column s = unit vector of source s's node
  Eigen::VectorXd source_w;             // W per source
};
// `event_mask` bit k = Network::events[k] is on.
NodeMatrices assemble(const Network& net, const Eigen::VectorXd& params, double speed_rpm, unsigned event_mask = 0);

// Limits of the reader. A network JSON is a description a person writes: these are far above any
// real one (spindle4: 4 nodes, 23 parameters) and keep a hostile file from asking for matrices
// of millions of nodes or speed laws that overflow (|speed_exponent| <= 10).
constexpr std::size_t kMaxNetworkBytes = std::size_t{16} << 20;
constexpr std::size_t kMaxNetworkNodes = 128;
constexpr std::size_t kMaxNetworkParameters = 1024;
constexpr std::size_t kMaxNetworkLinks = 1024;  // also the limit for sources
constexpr std::size_t kMaxNetworkTermsPerList = 16;
constexpr double kMaxSpeedExponent = 10.0;

// Reads a network file (at most kMaxNetworkBytes, JSON nested at most io::kMaxJsonDepth).
// Throws std::invalid_argument (io::InputError for an unreadable file) naming file and entry.
Network load_network(const std::string& json_path);
Network network_from_json(const nlohmann::json& j, const std::string& source);
nlohmann::json network_to_json(const Network& net);
// Built-in presets: "spindle4" (Lo, Hu & Chang 2018, heat balances A2 + Eq. 21).
Network preset_network(const std::string& name);
std::vector<std::string> preset_names();
// Which recording column measures which node, changed on the command line: each spec is
// "NODE=COLUMN" (e.g. "shaft=T5" for a module whose ch5 probe sits on the shaft end, or
// "shaft=" to drop the node's measurement). Throws std::invalid_argument naming the spec.
void remap_measurements(Network& net, const std::vector<std::string>& specs);
// Default values: `nominal` where given (the paper's Tables 2/3 for spindle4), else a numeric
// `initial`, else NaN.
Eigen::VectorXd default_parameters(const Network& net);

}  // namespace btsm::thermal
