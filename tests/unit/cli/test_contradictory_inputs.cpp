// Inputs that contradict themselves or each other, which the commands took silently with exit 0:
// the P3 rows of the hostile-input probe of 26 Nov. Each is now refused, naming the file and the
// entries that disagree, before any work; the honest variant beside it still passes.
#include "cli_run.hpp"
#include "refusals.hpp"
#include "model_fixture.hpp"

#include "host/io/utf8_text.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <functional>
#include <string>

namespace btsm::test {
namespace {

bool mentions(const CliResult& r, const std::string& s) { return r.err.find(s) != std::string::npos; }

// recording_csv with metadata lines in front and the columns renamed (T1..T4 -> `columns`).
std::string with_meta(const std::string& meta, const std::string& columns = "T1,T2,T3,T4", int rows = 200) {
  std::string s = recording_csv(rows);
  const std::string header = "time_s,speed_rpm,ambient_c,T1,T2,T3,T4";
  s.replace(s.find(header), header.size(), "time_s,speed_rpm,ambient_c," + columns);
  return meta + s;
}

// `# event_columns: T4` with 24.x degC in it, or a boundary column that is not there: residual
// refused them, validate, fit and heat used them as if declared properly.
TEST(Metadata, DeclaredColumnsAreCheckedByEveryCommand) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("event.csv"), with_meta("# event_columns: T4\n"));
  write_text(d.file("boundary.csv"), with_meta("# boundary_columns: coolant_c\n"));
  for (const char* cmd : {"validate model.json event.csv", "fit event.csv --preset spindle4 --sum-c 20478.7 --out m.json",
                          "heat model.json event.csv --out h"}) {
    const CliResult r = run_btsm(d, cmd);
    EXPECT_EQ(r.code, 2) << cmd << "\n" << r.err;
    EXPECT_TRUE(mentions(r, "event.csv") && mentions(r, "event column 'T4' must be 0 or 1") && mentions(r, "data row 1")) << r.err;
  }
  const CliResult b = run_btsm(d, "validate model.json boundary.csv");
  EXPECT_EQ(b.code, 2) << b.err;
  EXPECT_TRUE(mentions(b, "boundary.csv") && mentions(b, "'coolant_c' is not in the header")) << b.err;
}

// Four probes all "rear_bearing": the fit used the last for the rear bearing and left the housing
// and the front bearing unmeasured. An ambient_channel that is no channel, or that channel_roles
// gives another role, dropped the ambient from the model's channel map.
TEST(Metadata, ChannelRolesThatContradictAreRefusedNamingTheChannels) {
  ScratchDir d;
  const std::string fit = "fit rec.csv --preset spindle4 --sum-c 20478.7 --out m.json";
  const struct {
    const char* meta;
    const char* says;
  } cases[] = {
      {"# channel_roles: T1=rear_bearing,T2=rear_bearing,T3=rear_bearing,T4=ambient,T5=rear_bearing\n",
       "role 'rear_bearing' is on two channels, T1 and T2"},
      {"# channel_roles: T1=rear_bearing,T2=housing,T3=front_bearng,T4=ambient,T5=shaft\n", "unknown role 'front_bearng'"},
      {"# channel_roles: T1=rear_bearing,T1=housing,T3=front_bearing,T4=ambient,T5=shaft\n", "channel T1 is listed twice"},
      {"# ambient_channel: T9\n", "'T9' is not a module channel"},
      {"# channel_roles: T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=shaft\n# ambient_channel: T2\n",
       "T2 has the role 'housing'"},
  };
  for (const auto& c : cases) {
    write_text(d.file("rec.csv"), with_meta(c.meta, "T1,T2,T3,T5"));
    const CliResult r = run_btsm(d, fit);
    EXPECT_EQ(r.code, 2) << c.meta << r.err;
    EXPECT_TRUE(mentions(r, "rec.csv") && mentions(r, c.says)) << c.meta << r.err;
  }
  // No roles, but the ambient channel is a column a node measures (spindle4 measures T1..T4).
  write_text(d.file("rec.csv"), with_meta("# ambient_channel: T1\n"));
  const CliResult a = run_btsm(d, fit);
  EXPECT_EQ(a.code, 2) << a.err;
  EXPECT_TRUE(mentions(a, "column 'T1' measures node 'rear_bearing'") && mentions(a, "ambient channel")) << a.err;
  // The honest module recording still maps its probes.
  write_text(d.file("rec.csv"),
             with_meta("# channel_roles: T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=shaft\n# ambient_channel: T4\n",
                       "T1,T2,T3,T5"));
  const CliResult fitted = run_btsm(d, fit + " --iterations 3", 300);
  EXPECT_FALSE(mentions(fitted, "metadata")) << fitted.err;
  EXPECT_TRUE(mentions(fitted, "shaft=T5")) << fitted.err;
}

// A recording whose channel_roles put the bearings on other channels than the model was fitted
// with (probes re-mounted, or a swapped cable noted in the header) was scored node by node against
// the wrong probes, exit 0: validate, heat and residual with the model's own values refuse it,
// naming the node and both channels. The recording that agrees still passes.
TEST(Metadata, ProbesElsewhereThanTheModelSaysAreRefusedWhereAModelIsScored) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("swap.csv"), with_meta("# channel_roles: T1=front_bearing,T2=housing,T3=rear_bearing,T4=shaft,T5=ambient\n"));
  write_text(d.file("noshaft.csv"), with_meta("# channel_roles: T1=rear_bearing,T2=housing,T3=front_bearing,T4=spare,T5=ambient\n"));
  write_text(d.file("agree.csv"), with_meta("# channel_roles: T1=rear_bearing,T2=housing,T3=front_bearing,T4=shaft,T5=ambient\n"));
  write_text(d.file("check.csv"), "# source: check\n" + with_meta("# channel_roles: T1=rear_bearing,T2=housing,T3=front_bearing,T4=shaft,T5=ambient\n", "T1,T2,T3,T4", 240));
  const std::string swapped = "its channel_roles put node 'front_bearing' on T1, but the model measures it with T3 (T3 is rear_bearing there)";
  expect_refusals(d, {{"validate model.json swap.csv", swapped},
                      {"heat model.json swap.csv", swapped},
                      {"reduce model.json --speeds 4000,6000 --calibrate-bands swap.csv --out r.json", swapped},
                      {"residual --network model.json --use-values --fit swap.csv --check check.csv", swapped},
                      {"validate model.json noshaft.csv", "put node 'shaft' on no channel, but the model measures it with T4 (T4 is spare there)"}});
  const CliResult ok = run_btsm(d, "validate model.json agree.csv");
  EXPECT_EQ(ok.code, 0) << ok.err;
  // --column says which, as for fit: the user's word over the header's.
  const CliResult said = run_btsm(d, "residual --network model.json --use-values --fit swap.csv --check check.csv "
                                      "--column rear_bearing=T1 --column front_bearing=T3 --effects sensor_lag --threads 1", 300);
  EXPECT_EQ(said.code, 0) << said.err;
  EXPECT_TRUE(mentions(said, "rear_bearing=T1 front_bearing=T3")) << said.err;
}

// The same recording twice was fitted with double weight (sigmas understated); residual scored its
// "held-out" check on the fit recording itself.
TEST(Repeats, TheSameRecordingTwiceIsRefused) {
  ScratchDir d;
  write_text(d.file("a.csv"), recording_csv(200));
  write_text(d.file("copy.csv"), "# source: a copy\n" + recording_csv(200));
  const CliResult f = run_btsm(d, "fit a.csv copy.csv --preset spindle4 --sum-c 20478.7 --out m.json");
  EXPECT_EQ(f.code, 2) << f.err;
  EXPECT_TRUE(mentions(f, "copy.csv: holds the same samples as a.csv")) << f.err;
  EXPECT_FALSE(file_exists(d.file("m.json")));
  const CliResult r = run_btsm(d, "residual --preset spindle4 --fit a.csv --check copy.csv");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_TRUE(mentions(r, "copy.csv") && mentions(r, "held out")) << r.err;
}

// Probe 5 (P2-11): a copy with its times shifted, every 2nd row of it, or its T1 nudged by 0.1 mK
// passed as another recording: the "held-out" check was the fit recording, and fit counted it twice.
TEST(Repeats, AShiftedThinnedOrNudgedCopyIsRefused) {
  ScratchDir d;
  write_text(d.file("a.csv"), recording_csv(200));
  write_text(d.file("shifted.csv"), recording_csv(200, [](int, int col, const std::string& text) {
               return col == 0 ? std::to_string(std::stoll(text) + 999980000LL) : text;
             }));
  std::string thinned;
  int line = 0;
  for (std::size_t at = 0, end; (end = recording_csv(200).find('\n', at)) != std::string::npos; at = end + 1, ++line)
    if (line < 2 || line % 2 == 0) thinned += recording_csv(200).substr(at, end - at + 1);
  write_text(d.file("thinned.csv"), thinned);
  write_text(d.file("nudged.csv"), recording_csv(200, [](int, int col, const std::string& text) {
               char buf[32];
               std::snprintf(buf, sizeof buf, "%.4f", std::stod(text) + 1e-4);
               return col == 3 ? std::string(buf) : text;
             }));
  expect_refusals(d, {{"residual --preset spindle4 --fit a.csv --check shifted.csv",
                       "the check recording repeats the samples of the fit recording a.csv (times shifted by 999980000 s"},
                      {"residual --preset spindle4 --fit a.csv --check thinned.csv", "1 of every 2 rows"},
                      {"residual --preset spindle4 --fit a.csv --check nudged.csv", "200 of its 200 rows equal to within 0.5 mK"},
                      {"residual --preset spindle4 --fit thinned.csv --check a.csv", "the check recording holds the samples of the fit"},
                      {"fit a.csv shifted.csv --preset spindle4 --out m.json", "shifted.csv: repeats the samples of a.csv"}});
  EXPECT_FALSE(file_exists(d.file("m.json")));
}

// A network measuring one column at two nodes was accepted (the validate table showed T1 twice);
// a node named with an ESC and a newline was printed raw into the terminal.
TEST(Networks, OneColumnForTwoNodesAndControlCharactersInNamesAreRefused) {
  ScratchDir d;
  write_text(d.file("rec.csv"), recording_csv(200));
  nlohmann::json m = nlohmann::json::parse(spindle4_model_json());
  for (auto& meas : m["network"]["measurements"])
    if (meas["column"] == "T2") meas["column"] = "T1";
  write_text(d.file("dup.json"), m.dump(2));
  const CliResult dup = run_btsm(d, "validate dup.json rec.csv");
  EXPECT_EQ(dup.code, 2) << dup.err;
  EXPECT_TRUE(mentions(dup, "one column cannot measure two nodes")) << dup.err;
  nlohmann::json c = nlohmann::json::parse(spindle4_model_json());
  const std::string bad = "hous\x1b[2Jing\n";
  c["network"]["nodes"][1]["name"] = bad;
  for (auto& meas : c["network"]["measurements"])
    if (meas["node"] == "housing") meas["node"] = bad;
  for (auto& l : c["network"]["links"])
    for (auto& end : l["between"])
      if (end == "housing") end = bad;
  write_text(d.file("ctrl.json"), c.dump(2));
  const CliResult ctrl = run_btsm(d, "validate ctrl.json rec.csv");
  EXPECT_EQ(ctrl.code, 2) << ctrl.err;
  EXPECT_TRUE(mentions(ctrl, "control character")) << ctrl.err;
  EXPECT_EQ(ctrl.err.find('\x1b'), std::string::npos) << "the ESC is shown escaped";
  write_text(d.file("ctrl.csv"), "time_s,speed_rpm,ambient_c,T\x1b" "1\n0,0,20,20\n");
  const CliResult h = run_btsm(d, "heat spindle4 ctrl.csv");
  EXPECT_EQ(h.code, 2) << h.err;
  EXPECT_TRUE(mentions(h, "ctrl.csv:1:4") && mentions(h, "control character")) << h.err;
}

// Messages quoted what they were given raw (hostile-input probe 6): a header cell, a number cell, a
// parameter a network refers to, a file name and the values of --nodes, --effects, --effect and
// --channels reached the terminal with their ESC, CR and newline. Each is shown escaped now,
// and every message stays one line.
TEST(Networks, ControlCharactersQuotedFromAnyInputAreShownEscaped) {
  ScratchDir d;
  const std::string rec = recording_csv(200);
  write_text(d.file("rec.csv"), rec);
  write_text(d.file("model.json"), spindle4_model_json());
  std::string first = rec;
  first.replace(first.find("time_s,"), 6, "time\x1b[2Js");
  write_text(d.file("first.csv"), first);
  std::string cell = rec;
  cell.replace(cell.find("6000"), 4, "60\x1b[31m\r00");
  write_text(d.file("cell.csv"), cell);
  nlohmann::json m = nlohmann::json::parse(spindle4_model_json());
  m["network"]["links"][0]["both"][0]["resistance"] = "R12\nbtsm validate: all fine";
  write_text(d.file("ref.json"), m.dump(2));
  write_text(d.file("esc\x1b[2J.csv"), rec);
  write_text(d.file("other.csv"), recording_csv(220));  // a check that is no copy of the fit: --effects is read
  const struct {
    std::string args, says;
  } cases[] = {
      {"validate model.json first.csv", "found 'time\\x1b[2Js'"},
      {"validate model.json cell.csv", "bad number '60\\x1b[31m\\r00'"},
      {"validate ref.json rec.csv", "unknown parameter 'R12\\nbtsm validate: all fine'"},
      {"validate model.json 'gone\x1b[2J.csv'", "gone\\x1b[2J.csv"},
      {"heat model.json rec.csv --nodes 'shaft\x1b[2J'", "no node 'shaft\\x1b[2J'"},
      {"heat model.json rec.csv --nodes 'shaft\nbtsm heat: done'", "no node 'shaft\\nbtsm heat: done'"},
      {"residual --preset spindle4 --fit rec.csv --check other.csv --effects 'x\x1b[2J'", "unknown effect 'x\\x1b[2J'"},
      {"sim-module --pty p --duration 1 --effect 'x\x1b[2J'", "effect 'x\\x1b[2J'"},
      {"reduce model.json --speeds 4000,6000 --out r.json --channels 'a\x1b[2J,b,c,d,e'", "'a\\x1b[2J' (channel 1)"},
  };
  for (const auto& c : cases) {
    const CliResult r = run_btsm(d, c.args);
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.err;
    EXPECT_TRUE(mentions(r, c.says)) << c.args << "\n" << r.err;
    EXPECT_EQ(r.err.find_first_of("\x1b\r"), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_EQ(r.err.find("\nbtsm validate: all"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("\nbtsm heat: done"), std::string::npos) << r.err;
  }
  // A file name a glob brings in is shown escaped on the progress and warning lines too.
  const CliResult w = run_btsm(d, "validate model.json 'esc\x1b[2J.csv'");
  EXPECT_EQ(w.code, 0) << w.err;
  EXPECT_TRUE(mentions(w, "reading esc\\x1b[2J.csv")) << w.err;
  EXPECT_EQ(w.err.find('\x1b'), std::string::npos) << w.err;
  // The one helper: DEL, the C1 CSI (U+009B) and a byte that is no UTF-8 are shown too; UTF-8 text
  // and backslashes stay as they are.
  EXPECT_EQ(io::printable("a\x7f" "b\xC2\x9B" "c\xB0" "d\t20 \xC2\xB0" "C\\"), "a\\x7fb\\u009bc\\xb0d\\t20 \xC2\xB0" "C\\");
}

// A network field given as null took its default silently (probe 6): "min": null became 1e-9, a
// term's "speed_exponent": null made a heat source that grows with speed^1.67 a constant one.
// null is refused, naming the field and its entry; a parameter's value too. A sigma of null is
// what `fit` writes for one it could not tell, and still passes.
TEST(Networks, NullWhereANumberBelongsIsRefusedNotTakenAsTheDefault) {
  ScratchDir d;
  write_text(d.file("rec.csv"), recording_csv(200));
  const nlohmann::json base = nlohmann::json::parse(spindle4_model_json());
  const auto with = [&](const std::string& name, const std::function<void(nlohmann::json&)>& edit) {
    nlohmann::json m = base;
    edit(m);
    write_text(d.file(name), m.dump(2));
  };
  with("min.json", [](nlohmann::json& m) { m["network"]["parameters"][3]["min"] = nullptr; });
  with("exponent.json", [](nlohmann::json& m) { m["network"]["sources"][0]["operating"][0]["speed_exponent"] = nullptr; });
  with("speed.json", [](nlohmann::json& m) { m["network"]["speed_ref_rpm"] = nullptr; });
  with("value.json", [](nlohmann::json& m) { m["parameters"]["R34"] = nullptr; });
  with("sigma.json", [](nlohmann::json& m) { m["sigma"]["R34"] = nullptr; });
  write_text(d.file("net.json"), [&] {
    nlohmann::json n = base["network"];
    n["parameters"][3]["nominal"] = nullptr;
    return n.dump(2);
  }());
  expect_refusals(d, {{"validate min.json rec.csv", "min.json (network): parameter 'R34': field 'min' is null, expected a number"},
                      {"validate exponent.json rec.csv", "source 'Qf1'.operating[0]: field 'speed_exponent' is null, expected a number"},
                      {"validate speed.json rec.csv", "speed.json (network): top level: field 'speed_ref_rpm' is null"},
                      {"validate value.json rec.csv", "value.json: parameters: 'R34' is null, expected a number"},
                      {"heat net.json rec.csv --noise 0.01", "net.json: parameter 'R34': field 'nominal' is null"}});
  const CliResult sigma = run_btsm(d, "validate sigma.json rec.csv");
  EXPECT_EQ(sigma.code, 0) << sigma.err;
}

// A node named "sh,aft", "sh=aft" or " shaft" was taken (probe 6), and then could not be named:
// `--nodes sh,aft` asked for nodes "sh" and "aft", heat's CSV header gained a column, --column
// sh=aft=T4 split at the first '='. Such names, of nodes and of the columns a network or a
// recording names, are refused where they are read, with the name and the file.
TEST(Networks, NamesThatCouldNotBeNamedAgainAreRefused) {
  ScratchDir d;
  const std::string rec = recording_csv(200);
  write_text(d.file("rec.csv"), rec);
  const std::string model = spindle4_model_json();
  const auto renamed = [&](const std::string& from, const std::string& to) {
    std::string m = model;
    for (std::size_t at = m.find(from); at != std::string::npos; at = m.find(from, at + to.size())) m.replace(at, from.size(), to);
    return m;
  };
  write_text(d.file("comma.json"), renamed("\"shaft\"", "\"sh,aft\""));
  write_text(d.file("equals.json"), renamed("\"shaft\"", "\"sh=aft\""));
  write_text(d.file("blank.json"), renamed("\"shaft\"", "\" shaft\""));
  write_text(d.file("column.json"), renamed("\"T4\"", "\"T4 \""));
  std::string header = rec;
  header.replace(header.find(",T4\n"), 4, ",T=4\n");
  write_text(d.file("header.csv"), header);
  write_text(d.file("model.json"), model);
  expect_refusals(d, {{"validate comma.json rec.csv", "comma.json (network): network 'spindle4': node \"sh,aft\": contains ','"},
                      {"validate equals.json rec.csv", "equals.json (network): network 'spindle4': node \"sh=aft\": contains '='"},
                      {"heat blank.json rec.csv", "blank.json (network): network 'spindle4': node \" shaft\": starts or ends with a blank"},
                      {"validate column.json rec.csv", "measurement column \"T4 \": starts or ends with a blank"},
                      {"validate model.json header.csv", "header.csv:2:7: header: column 'T=4' contains '='"}});
}

// A named pipe nobody writes to: every reader blocked in open() for ever.
TEST(Inputs, ANamedPipeWithoutAWriterIsAnErrorNotAHang) {
  ScratchDir d;
  ASSERT_EQ(::mkfifo(d.file("fifo.csv").c_str(), 0600), 0);
  write_text(d.file("model.json"), spindle4_model_json());
  const CliResult r = run_btsm(d, "validate model.json fifo.csv", 20);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_TRUE(mentions(r, "fifo.csv") && mentions(r, "named pipe")) << r.err;
}

// A residual base fit that is no model (the spindle never turned): "unexplained", exit 0, where
// fit refuses the same data. And lists that name nothing meant "all" (--effects ,) or the default.
TEST(Inputs, ADegenerateBaseAndEmptyListsAreRefused) {
  ScratchDir d;
  write_text(d.file("still.csv"), recording_csv(200, [](int, int col, const std::string& text) {
               return col == 1 ? std::string("0") : col >= 3 ? std::string("20.0000") : text;
             }));
  write_text(d.file("rec.csv"), recording_csv(200));
  const CliResult r = run_btsm(d, "residual --preset spindle4 --fit still.csv --check rec.csv --threads 1", 300);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(mentions(r, "no usable model")) << r.err;
  EXPECT_TRUE(r.out.empty()) << "no verdict printed: " << r.out;
  const CliResult e = run_btsm(d, "residual --preset spindle4 --fit still.csv --check rec.csv --effects ,");
  EXPECT_EQ(e.code, 2) << e.err;
  EXPECT_TRUE(mentions(e, "names no effect family")) << e.err;
  const CliResult n = run_btsm(d, "heat spindle4 rec.csv --nodes ,");
  EXPECT_EQ(n.code, 2) << n.err;
  EXPECT_TRUE(mentions(n, "names no node")) << n.err;
  const CliResult s = run_btsm(d, "sim-module --pty p --duration 1e306h");
  EXPECT_EQ(s.code, 2) << s.err;
  EXPECT_TRUE(mentions(s, "--duration") && mentions(s, "31 years")) << s.err;
}

// A spreadsheet's "Unicode" CSV was reported as "NUL byte at offset 3"; heat said "steps of 60 s"
// of hourly samples, whose steps are the sample intervals.
TEST(Inputs, Utf16TextAndStepsStretchedToTheSamplesAreNamed) {
  ScratchDir d;
  const std::string text = recording_csv(20);
  std::string utf16 = "\xFF\xFE";
  for (const char c : text) utf16 += std::string(1, c) + std::string(1, '\0');
  write_text(d.file("unicode.csv"), utf16);
  write_text(d.file("model.json"), spindle4_model_json());
  const CliResult u = run_btsm(d, "validate model.json unicode.csv");
  EXPECT_EQ(u.code, 2) << u.err;
  EXPECT_TRUE(mentions(u, "unicode.csv: UTF-16 text") && mentions(u, "save it as UTF-8")) << u.err;
  write_text(d.file("hourly.csv"), recording_csv(60, [](int row, int col, const std::string& text) {
               return col == 0 ? std::to_string(3600 * row) : text;
             }));
  const CliResult h = run_btsm(d, "heat model.json hourly.csv --noise 0.01", 120);
  EXPECT_EQ(h.code, 0) << h.err;
  EXPECT_NE(h.out.find("one per sample interval (mean 3600 s): --step 60 s is shorter"), std::string::npos) << h.out;
}

// What the readers said of other encodings (probe 6): UTF-32 with its byte order mark was "UTF-16
// text", UTF-16 big-endian and UTF-32 without a mark "not a text file (NUL byte ...)", and a
// Latin-1 "°C" (the one byte 0xB0) passed into a column name or came back raw from the JSON
// parser. Each is named now; a UTF-8 byte order mark still passes, in a CSV as in a JSON.
TEST(Inputs, EveryEncodingIsNamedAndAUtf8ByteOrderMarkPasses) {
  ScratchDir d;
  const std::string text = recording_csv(200);
  const auto wide = [&](int width, bool big, const std::string& mark) {
    std::string out = mark;
    for (const char c : text)
      for (int k = 0; k < width; ++k) out += (big ? k == width - 1 : k == 0) ? c : '\0';
    return out;
  };
  write_text(d.file("be16.csv"), wide(2, true, ""));
  write_text(d.file("le32bom.csv"), wide(4, false, std::string("\xFF\xFE\0\0", 4)));
  write_text(d.file("be32.csv"), wide(4, true, ""));
  std::string latin1 = text;
  latin1.replace(latin1.find(",T4"), 3, ",T4 \xB0" "C");
  write_text(d.file("latin1.csv"), latin1);
  std::string json = spindle4_model_json();
  write_text(d.file("model.json"), json);
  write_text(d.file("rec.csv"), text);
  json.replace(json.find("btsm-thermal-model-1"), 4, "\xB0tsm");
  write_text(d.file("latin1.json"), json);
  expect_refusals(d, {{"validate model.json be16.csv", "be16.csv: UTF-16 text (big-endian, no byte order mark)"},
                      {"validate model.json le32bom.csv", "le32bom.csv: UTF-32 text (little-endian, byte order mark FF FE 00 00)"},
                      {"validate model.json be32.csv", "be32.csv: UTF-32 text (big-endian, no byte order mark)"},
                      {"validate model.json latin1.csv", "latin1.csv: not valid UTF-8 at byte 54 (0xB0, line 2)"},
                      {"validate latin1.json rec.csv", "latin1.json: not valid UTF-8 at byte "}});
  const CliResult raw = run_btsm(d, "validate latin1.json latin1.csv");
  EXPECT_EQ(raw.err.find('\xB0'), std::string::npos) << "the byte is named, not quoted";
  write_text(d.file("bom.csv"), "\xEF\xBB\xBF" + text);
  write_text(d.file("bom.json"), "\xEF\xBB\xBF" + spindle4_model_json());
  const CliResult bom = run_btsm(d, "validate bom.json bom.csv");
  EXPECT_EQ(bom.code, 0) << bom.err;
}

// The second probe (27 Nov, 537 cases): values at the edge that ended in exit 0 with a wrong result
// -- heat --noise 1e-7 (2.5e80 K residuals), a one-row check ("none", RMSE 0.0000), --sum-c 3 J/K
// below what the capacitances' bounds allow ("converged" at 4 J/K), rtd --r0 1e308 (inf),
// --truth-period 1e-9 (13 GB) -- and metadata lines given twice with different values.
TEST(Inputs, EdgeValuesOfTheSecondProbeAreRefused) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("rec.csv"), recording_csv(200));
  write_text(d.file("one.csv"), recording_csv(1));
  write_text(d.file("three.csv"), recording_csv(3));
  write_text(d.file("twice.csv"), "# channel_roles: T1=rear_bearing,T2=housing,T3=front_bearing,T4=shaft\n"
                                  "# channel_roles: T1=housing,T2=rear_bearing,T3=front_bearing,T4=shaft\n" +
                                      recording_csv(20));
  expect_refusals(d, {
      {"heat model.json rec.csv --noise 1e-7", "--noise"},
      {"residual --preset spindle4 --fit rec.csv --check one.csv", "one.csv: a check recording needs at least 10 rows"},
      {"residual --preset spindle4 --fit rec.csv --check three.csv", "three.csv: a check recording needs at least 10 rows"},
      {"fit rec.csv --preset spindle4 --sum-c 3 --out m.json", "cannot be reached"},
      {"fit rec.csv --preset spindle4 --sum-c 1e300 --out m.json", "cannot be reached"},
      {"rtd t2r --r0 1e308 850", "--r0"},
      {"sim-module --pty p --truth-out t.csv --truth-period 1e-9 --duration 1m", "--truth-period"},
      {"validate model.json twice.csv", "given twice with different values"},
      {"residual --network model.json --fit rec.csv --check three.csv", "add --use-values"},
  });
  EXPECT_FALSE(file_exists(d.file("m.json")));
  EXPECT_FALSE(file_exists(d.file("t.csv")));
}

// A hand-edited channel map naming two ambient channels made the spare probe the ambient; one
// listing a channel twice was resolved by its last entry.
TEST(Inputs, AChannelMapThatSaysTwoThingsIsRefused) {
  ScratchDir d;
  nlohmann::json m = nlohmann::json::parse(spindle4_model_json());
  m["channel_map"] = nlohmann::json::array({{{"channel", 1}, {"node", "rear_bearing"}},
                                            {{"channel", 4}, {"node", "ambient"}},
                                            {{"channel", 5}, {"node", "ambient"}}});
  write_text(d.file("two.json"), m.dump(2));
  m["channel_map"] = nlohmann::json::array({{{"channel", 1}, {"node", "rear_bearing"}}, {{"channel", 1}, {"node", "housing"}}});
  write_text(d.file("twice.json"), m.dump(2));
  expect_refusals(d, {{"reduce two.json --speeds 4000,6000 --force --out r.json", "names two ambient channels (4 and 5)"},
                      {"reduce twice.json --speeds 4000,6000 --force --out r.json", "lists channel 1 twice"}});
  EXPECT_FALSE(file_exists(d.file("r.json")));
}

// A network parameter nothing uses was "enters non-linearly; give it an initial value": no start
// helps a parameter no data can see.
TEST(Networks, AParameterNothingUsesIsNamedAsSuch) {
  ScratchDir d;
  write_text(d.file("rec.csv"), recording_csv(200));
  nlohmann::json m = nlohmann::json::parse(spindle4_model_json());
  m["network"]["parameters"].push_back({{"name", "unused"}, {"unit", "W/K"}, {"min", 0.001}, {"max", 10}});
  write_text(d.file("net.json"), m["network"].dump(2));
  expect_refusals(d, {{"fit rec.csv --network net.json --sum-c 20478.7 --out m.json", "'unused' is used by no capacitance"}});
}

// --port naming a regular file, a directory or /dev/null failed as an I/O error (exit 1): there is
// no device there, as with a missing path (exit 3).
TEST(Inputs, APortThatIsNoSerialDeviceIsNoDevice) {
  ScratchDir d;
  write_text(d.file("file.txt"), "not a tty\n");
  expect_refusals(d, {{"info --port file.txt", "not a serial device"}, {"info --port /dev/null", "not a serial device"},
                      {"info --port " + d.path, "a directory, not a serial device"}},
                  3);
}

// A --port that is a symbolic link to nothing waited the 5 s a port that is not there yet gets,
// then said "no such device" (probe 6). /dev/serial/by-id links come and go with their adapter,
// so one that dangles names a device that is gone: exit 3 at once, naming the link's target.
TEST(Inputs, APortLinkToNothingFailsAtOnceNamingItsTarget) {
  ScratchDir d;
  ASSERT_EQ(::symlink(d.file("ttyGONE0").c_str(), d.file("by-id-link").c_str()), 0);
  const auto start = std::chrono::steady_clock::now();
  const CliResult r = run_btsm(d, "info --port by-id-link", 20);
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_TRUE(mentions(r, "by-id-link: a dangling symbolic link to " + d.file("ttyGONE0"))) << r.err;
  EXPECT_LT(took, 2.5);
}

// Two rows at rest "calibrated" the detector and wrote the blob.
TEST(Inputs, DetectorBandsNeedAnHourOfRunning) {
  ScratchDir d;
  write_text(d.file("model.json"), spindle4_model_json());
  write_text(d.file("short.csv"), recording_csv(2));
  const CliResult r = run_btsm(d, "reduce model.json --speeds 4000,6000 --calibrate-bands short.csv --out r.json --blob m.bin", 300);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_TRUE(mentions(r, "min of running")) << r.err;
  EXPECT_FALSE(file_exists(d.file("m.bin")));
}

// A reduced-model JSON whose blob_hex says one model and whose scheduled_model table another was
// flashed as the blob said: the table a user checked was not what the module got.
TEST(Inputs, AReducedModelWhoseBlobContradictsItsTableIsNotFlashed) {
  ScratchDir d;
  nlohmann::json j = reduced_spindle4_json(d);
  const CliResult honest = run_btsm(d, "flash-model r.json --port /nonexistent/tty");
  EXPECT_FALSE(mentions(honest, "contradicts")) << honest.err;
  j["scheduled_model"]["breakpoints"][1]["speed_rpm"] = 4500;
  write_text(d.file("speed.json"), j.dump(2));
  const CliResult s = run_btsm(d, "flash-model speed.json --port /nonexistent/tty");
  EXPECT_EQ(s.code, 2) << s.err;
  EXPECT_TRUE(mentions(s, "speed.json") && mentions(s, "contradicts \"scheduled_model\"") && mentions(s, "breakpoint 1")) << s.err;
  j = nlohmann::json::parse(read_text(d.file("r.json")));
  j["scheduled_model"]["breakpoints"][2]["a"][0] = 0.5;
  write_text(d.file("pole.json"), j.dump(2));
  const CliResult p = run_btsm(d, "flash-model pole.json --port /nonexistent/tty");
  EXPECT_EQ(p.code, 2) << p.err;
  EXPECT_TRUE(mentions(p, "pole")) << p.err;
}

}  // namespace
}  // namespace btsm::test
