// Recording CSV reader/writer. Errors name file, line and column because recordings are edited by
// hand and produced by several tools.
#include "recording.hpp"
#include "recording_metadata.hpp"
#include "sensor_faults.hpp"

#include "host/io/input_error.hpp"
#include "host/io/input_file.hpp"
#include "host/io/output_file.hpp"
#include "host/io/utf8_text.hpp"

#include <cstdio>
#include <algorithm>
#include <charconv>
#include <cerrno>
#include <cstdlib>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string_view>
#include <stdexcept>
#include <unordered_set>

namespace btsm::thermal {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

[[noreturn]] void fail(const std::string& src, std::size_t line, std::size_t col, const std::string& what) {
  std::ostringstream os;
  os << src << ":" << line;
  if (col > 0) os << ":" << col;
  os << ": " << what;
  throw io::InputError(os.str());
}

std::string trim(const std::string& s) {
  std::size_t a = 0, b = s.size();
  while (a < b && (s[a] == ' ' || s[a] == '\t' || s[a] == '\r')) ++a;
  while (b > a && (s[b - 1] == ' ' || s[b - 1] == '\t' || s[b - 1] == '\r')) --b;
  return s.substr(a, b - a);
}

std::vector<std::string> split_cells(const std::string& line) {
  std::vector<std::string> cells;
  std::string cur;
  for (char c : line) {
    if (c == ',') {
      cells.push_back(trim(cur));
      cur.clear();
    } else {
      cur += c;
    }
  }
  cells.push_back(trim(cur));
  return cells;
}

// Lines that end in a carriage return alone (classic Mac OS, some loggers) are one line to getline:
// named as such, with the conversion, instead of "no header line found".
void refuse_bare_cr_line_ends(const std::string& text, const std::string& src) {
  if (text.find('\n') != std::string::npos) return;
  const auto cr = text.find('\r');
  if (cr == std::string::npos || cr + 1 == text.size()) return;
  fail(src, 1, 0,
       "the lines end in a bare CR (carriage return without a line feed, the classic Mac line end), so the whole file "
       "reads as one line: convert it, e.g. `tr '\\r' '\\n' < " + src + " > converted.csv`");
}

// A cell or line holding a carriage return: lines joined by bare CRs (part of the file converted).
std::string bare_cr_hint(const std::string& text) {
  return text.find('\r') == std::string::npos ? ""
                                               : " (it holds a bare CR: lines that end in a carriage return without a line "
                                                 "feed? convert them, e.g. with `tr '\\r' '\\n'`)";
}

// A header line where a data row belongs: two recordings joined into one file (cat a.csv b.csv),
// which read as "bad number 'time_s'".
[[noreturn]] void refuse_second_header(const std::string& src, std::size_t line, std::size_t first_header,
                                       std::size_t metadata_after_rows) {
  std::string what = "a second header line (the first is line " + std::to_string(first_header) + ")";
  if (metadata_after_rows > 0)
    what += ", after a metadata comment block that starts again at line " + std::to_string(metadata_after_rows);
  fail(src, line, 0, what + ": two recordings joined into one file? give each recording as a file of its own");
}

// A cell as an error message shows it: cut to 40 characters (a line without commas may be huge).
std::string shown(const std::string& cell) { return cell.size() <= 40 ? cell : cell.substr(0, 40) + "..."; }

// '# sensor_fault:' lines say why cells are empty; nothing acts on them (README: comment lines), so
// a malformed one (channel T9, code 'melted', a range backwards or 'nan') is a warning naming its
// line, not a refusal of the recording.
void warn_of_malformed_sensor_fault(Recording& rec, std::size_t line) {
  const auto& [key, value] = rec.meta.back();
  if (key != kSensorFaultKey) return;
  if (const std::string why = sensor_fault_line_problem(value); !why.empty())
    rec.warnings.push_back(rec.source + ":" + std::to_string(line) + ": '# " + key + ": " + shown(value) + "': " + why +
                           "; the line is informative only (why a cell is empty) and is ignored");
}

// Parses a finite number or throws with position. Empty -> NaN only if allow_empty.
double parse_number(const std::string& cell, bool allow_empty, const std::string& src, std::size_t line,
                    std::size_t col, const std::string& column_name) {
  if (cell.empty()) {
    if (allow_empty) return kNaN;
    fail(src, line, col, "column '" + column_name + "' is empty (a value is required)");
  }
  double v = 0.0;
  const char* first = cell.data();
  const char* last = cell.data() + cell.size();
  // from_chars rejects a leading '+': skip it, but only before a number ("+-20" then read as -20)
  if (*first == '+' && last - first > 1 && first[1] != '-') ++first;
  auto [ptr, ec] = std::from_chars(first, last, v);
  if (ec == std::errc::result_out_of_range && ptr == last) {
    // A well-formed number beyond a double: one too small to hold (1e-400) is 0 for any
    // temperature, speed or time; one too large is named as such, not as a "bad number".
    const double s = std::strtod(std::string(first, last).c_str(), nullptr);
    if (s == 0.0) return 0.0;
    fail(src, line, col, "column '" + column_name + "': '" + shown(cell) + "' is beyond the range of a number (+-1.8e308)");
  }
  if (ec != std::errc() || ptr != last)
    fail(src, line, col, "column '" + column_name + "': bad number '" + shown(cell) + "'" + bare_cr_hint(cell));
  if (!std::isfinite(v)) fail(src, line, col, "column '" + column_name + "': non-finite value '" + shown(cell) + "'");
  return v;
}

std::string format_number(double v, int decimals) {
  if (std::isnan(v)) return "";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

std::string format_compact(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

// A temperature (or ambient) inside [kMinRecordedTempC, kMaxRecordedTempC]; NaN (missing) passes.
double check_temperature(double v, const std::string& cell, const std::string& src, std::size_t line, std::size_t col,
                         const std::string& column_name) {
  if (v < kMinRecordedTempC)
    fail(src, line, col, "column '" + column_name + "': " + shown(cell) + " degC is below absolute zero (-273.15 degC)");
  if (v > kMaxRecordedTempC)
    fail(src, line, col, "column '" + column_name + "': " + shown(cell) + " degC is above the " +
                             format_compact(kMaxRecordedTempC) + " degC a recording may hold");
  return v;
}

}  // namespace

std::string reserved_column_problem(const std::string& column) {
  const char* what = column == "time_s"      ? "the recording's time (s)"
                     : column == "speed_rpm" ? "the spindle speed (rpm)"
                     : column == "ambient_c" ? "the ambient temperature, the network's boundary, always used as such"
                                             : nullptr;
  if (what == nullptr) return "";
  return std::string("is reserved: ") + what +
         " (time_s, speed_rpm and ambient_c are the first three columns of every recording, never a temperature column)";
}

int Recording::channel_index(const std::string& name) const {
  for (std::size_t i = 0; i < channels.size(); ++i)
    if (channels[i] == name) return static_cast<int>(i);
  return -1;
}

std::string Recording::meta_value(const std::string& key) const {
  for (const auto& kv : meta)
    if (kv.first == key) return kv.second;
  return "";
}

Recording parse_recording_csv(const std::string& text, const std::string& source) {
  Recording rec;
  rec.source = source;
  // A spreadsheet saving "CSV UTF-8" starts the file with a byte-order mark; it is not part of the
  // first column's name, and refusing the header over an invisible mark helps nobody.
  static constexpr std::string_view kUtf8Bom = "\xEF\xBB\xBF";
  std::istringstream in(std::string_view(text).substr(0, kUtf8Bom.size()) == kUtf8Bom ? text.substr(kUtf8Bom.size()) : text);
  refuse_bare_cr_line_ends(text, source);
  std::string raw;
  std::size_t line_no = 0, header_line = 0;
  std::size_t comments_after_rows = 0;  // where the comment lines since the last data row start (0: none)
  bool have_header = false;
  std::vector<std::vector<double>> temps;
  while (std::getline(in, raw)) {
    ++line_no;
    const std::string line = trim(raw);
    if (line.empty()) continue;
    if (line[0] == '#') {
      const std::string body = trim(line.substr(1));
      const auto colon = body.find(':');
      if (colon == std::string::npos)
        rec.meta.emplace_back(body, "");
      else
        rec.meta.emplace_back(trim(body.substr(0, colon)), trim(body.substr(colon + 1)));
      warn_of_malformed_sensor_fault(rec, line_no);
      if (!temps.empty() && comments_after_rows == 0) comments_after_rows = line_no;
      continue;
    }
    auto cells = split_cells(line);
    if (have_header && cells[0] == "time_s") refuse_second_header(source, line_no, header_line, comments_after_rows);
    if (!have_header) {
      static const char* kFixed[3] = {"time_s", "speed_rpm", "ambient_c"};
      for (std::size_t c = 0; c < 3; ++c) {
        if (c >= cells.size() || cells[c] != kFixed[c])
          fail(source, line_no, c + 1,
               std::string("header: expected column '") + kFixed[c] + "' here, found '" +
                   (c < cells.size() ? shown(cells[c]) : std::string("<nothing>")) +
                   "' (header must start time_s,speed_rpm,ambient_c)");
      }
      if (cells.size() < 4) fail(source, line_no, 4, "header: no temperature column after ambient_c");
      std::unordered_set<std::string> seen;  // a set, not pairwise compares: a header may be huge
      for (std::size_t c = 3; c < cells.size(); ++c) {
        if (cells[c].empty()) fail(source, line_no, c + 1, "header: empty column name");
        if (io::has_control_char(cells[c]))
          fail(source, line_no, c + 1, "header: column " + std::to_string(c + 1) + "'s name contains a control character");
        // ',' and outer blanks a header cannot hold; '=' would split `# channel_roles: COLUMN=ROLE`
        if (const std::string why = io::name_problem(cells[c]); !why.empty())
          fail(source, line_no, c + 1, "header: column '" + shown(cells[c]) + "' " + why);
        if (!seen.insert(cells[c]).second) fail(source, line_no, c + 1, "header: duplicate column '" + shown(cells[c]) + "'");
        rec.channels.push_back(cells[c]);
      }
      have_header = true;
      header_line = line_no;
      continue;
    }
    const std::size_t ncol = 3 + rec.channels.size();
    if (cells.size() != ncol) {
      std::ostringstream os;
      os << "expected " << ncol << " cells, found " << cells.size();
      if (cells.size() < ncol) os << " (missing column '" << (cells.size() >= 3 ? rec.channels[cells.size() - 3] : "ambient_c") << "')";
      fail(source, line_no, std::min(cells.size(), ncol) + (cells.size() < ncol ? 1 : 1), os.str() + bare_cr_hint(line));
    }
    const double t = parse_number(cells[0], false, source, line_no, 1, "time_s");
    if (!rec.time_s.empty() && !(t > rec.time_s.back()))
      fail(source, line_no, 1, "column 'time_s': time does not increase (" + shown(cells[0]) + " after " +
                                   format_compact(rec.time_s.back()) + ")");
    if (std::abs(t) > kMaxRecordedTimeS)
      fail(source, line_no, 1, "column 'time_s': " + shown(cells[0]) + " s is beyond the +-" + format_compact(kMaxRecordedTimeS) +
                                   " s a recording may hold");
    // The limit itself passes: 0.009 - 0.008 is 0.000999... in binary, so allow the rounding of the two times.
    if (!rec.time_s.empty() &&
        t - rec.time_s.back() < kMinRecordedStepS - 4 * std::numeric_limits<double>::epsilon() * std::max(std::abs(t), std::abs(rec.time_s.back())))
      fail(source, line_no, 1, "column 'time_s': " + shown(cells[0]) + " is less than " + format_compact(kMinRecordedStepS) +
                                   " s after the row before (" + format_compact(rec.time_s.back()) + "): a duplicated timestamp?");
    const double w = parse_number(cells[1], false, source, line_no, 2, "speed_rpm");
    if (w < 0) fail(source, line_no, 2, "column 'speed_rpm': negative speed '" + shown(cells[1]) + "'");
    if (w > kMaxRecordedSpeedRpm)
      fail(source, line_no, 2, "column 'speed_rpm': " + shown(cells[1]) + " rpm is above the " + format_compact(kMaxRecordedSpeedRpm) +
                                   " rpm a recording may hold");
    const double amb = check_temperature(parse_number(cells[2], false, source, line_no, 3, "ambient_c"), cells[2], source,
                                         line_no, 3, "ambient_c");
    rec.time_s.push_back(t);
    rec.speed_rpm.push_back(w);
    rec.ambient_c.push_back(amb);
    std::vector<double> row(rec.channels.size());
    for (std::size_t c = 0; c < rec.channels.size(); ++c)
      row[c] = check_temperature(parse_number(cells[3 + c], true, source, line_no, 4 + c, rec.channels[c]), cells[3 + c],
                                 source, line_no, 4 + c, rec.channels[c]);
    temps.push_back(std::move(row));
    comments_after_rows = 0;
  }
  if (!have_header) fail(source, line_no, 0, "no header line 'time_s,speed_rpm,ambient_c,...' found");
  if (temps.empty()) fail(source, line_no, 0, "no data rows");
  rec.temp_c.resize(static_cast<Eigen::Index>(temps.size()), static_cast<Eigen::Index>(rec.channels.size()));
  for (std::size_t r = 0; r < temps.size(); ++r)
    for (std::size_t c = 0; c < rec.channels.size(); ++c)
      rec.temp_c(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = temps[r][c];
  check_recording_metadata(rec);  // declared columns, channel roles: every command sees the same errors
  return rec;
}

std::string long_gap_warning(const Recording& r) {
  if (r.rows() < 3) return "";
  std::vector<double> spacing(r.rows() - 1);
  for (std::size_t k = 0; k + 1 < r.rows(); ++k) spacing[k] = r.time_s[k + 1] - r.time_s[k];
  const auto widest = std::max_element(spacing.begin(), spacing.end());
  const std::size_t at = static_cast<std::size_t>(widest - spacing.begin());
  const double gap = *widest;
  std::nth_element(spacing.begin(), spacing.begin() + static_cast<long>(spacing.size() / 2), spacing.end());
  const double median = spacing[spacing.size() / 2];
  if (!(gap > 3600.0 && gap > 100.0 * median)) return "";
  char text[320];
  std::snprintf(text, sizeof text,
                "%s: a gap of %.4g h between the rows at t = %.10g s and %.10g s, %.3g times the rows' usual spacing "
                "of %.4g s: the model runs through it with the speed (%.0f rpm) and ambient of the row before held",
                io::printable(r.source).c_str(), gap / 3600.0, r.time_s[at], r.time_s[at + 1], gap / median, median, r.speed_rpm[at]);
  return text;
}

Recording read_recording_csv(const std::string& path) {
  return parse_recording_csv(io::read_input_file(path, kMaxRecordingBytes, "recording CSV"), path);
}

bool same_samples(const Recording& a, const Recording& b) {
  if (a.rows() != b.rows() || a.channels != b.channels) return false;
  if (a.time_s != b.time_s || a.speed_rpm != b.speed_rpm || a.ambient_c != b.ambient_c) return false;
  for (Eigen::Index k = 0; k < a.temp_c.size(); ++k) {
    const double x = a.temp_c.data()[k], y = b.temp_c.data()[k];
    if (!(x == y || (std::isnan(x) && std::isnan(y)))) return false;
  }
  return true;
}

std::string repeated_samples(const Recording& a, const Recording& b) {
  constexpr double kTolK = 5e-4;      // below every sensor's resolution here (the AD7794 chain: ~1 mK)
  // of b's rows: a synthetic run whose temperatures ignore the speed shares 90 % of its rows with
  // another cut of itself; a copy shares them all
  constexpr double kShare = 0.98;
  constexpr int kMaxAnchors = 20;     // rows of `a` tried as b's first row
  if (b.rows() < 10 || a.rows() < 2) return "";
  std::vector<std::pair<Eigen::Index, Eigen::Index>> cols;  // (a's, b's) shared temperature columns
  for (std::size_t c = 0; c < b.channels.size(); ++c)
    for (std::size_t d = 0; d < a.channels.size(); ++d)
      if (a.channels[d] == b.channels[c]) cols.emplace_back(static_cast<Eigen::Index>(d), static_cast<Eigen::Index>(c));
  if (cols.empty()) return "";
  const auto same_row = [&](std::size_t i, std::size_t k) {
    if (a.speed_rpm[i] != b.speed_rpm[k]) return false;
    for (const auto& [ca, cb] : cols) {
      const double x = a.temp_c(static_cast<Eigen::Index>(i), ca), y = b.temp_c(static_cast<Eigen::Index>(k), cb);
      if (!(std::abs(x - y) <= kTolK || (std::isnan(x) && std::isnan(y)))) return false;
    }
    return true;
  };
  int anchors = 0;
  for (std::size_t j = 0; j < a.rows() && anchors < kMaxAnchors; ++j) {
    if (!same_row(j, 0)) continue;
    ++anchors;
    const double offset = a.time_s[j] - b.time_s[0];
    std::size_t matched = 0, i = j;
    // the first and last matched rows, of b and of a: as many rows apart in both = a contiguous part
    std::size_t first_b = 0, last_b = 0, first_a = 0, last_a = 0;
    for (std::size_t k = 0; k < b.rows(); ++k) {
      const double t = b.time_s[k] + offset, tol = 1e-9 * std::max(1.0, std::abs(t)) + 1e-6;
      while (i + 1 < a.rows() && a.time_s[i] < t - tol) ++i;  // both sorted by time
      if (std::abs(a.time_s[i] - t) <= tol && same_row(i, k)) {
        if (matched++ == 0) first_b = k, first_a = i;
        last_b = k, last_a = i;
      }
    }
    if (static_cast<double>(matched) < kShare * static_cast<double>(b.rows())) continue;
    std::string how;
    char text[160];
    if (offset != 0.0) {
      std::snprintf(text, sizeof text, "times shifted by %.10g s", -offset);
      how = text;
    }
    const char* sep = how.empty() ? "" : ", ";
    // The first half of a recording is one of its parts, not "1 of every 2 rows" (a thinning).
    const bool part = last_a - first_a == last_b - first_b && b.rows() < a.rows();
    if (part) {
      std::snprintf(text, sizeof text, "%sits rows %zu-%zu are rows %zu-%zu of ", sep, first_b + 1, last_b + 1, first_a + 1, last_a + 1);
      how += text + a.source;
      if (matched == b.rows()) {
        std::snprintf(text, sizeof text, ", equal to within %.1f mK", kTolK * 1e3);
        return how + text;
      }
      sep = ", ";
    } else if (const double per = static_cast<double>(a.rows()) / static_cast<double>(b.rows()); per >= 1.5) {
      std::snprintf(text, sizeof text, "%s1 of every %.0f rows", sep, per);
      how += text;
      sep = ", ";
    }
    std::snprintf(text, sizeof text, "%s%zu of its %zu rows equal to within %.1f mK", sep, matched, b.rows(), kTolK * 1e3);
    return how + text;
  }
  return "";
}

void refuse_repeated_recordings(const std::vector<Recording>& recs) {
  for (std::size_t i = 0; i < recs.size(); ++i)
    for (std::size_t j = i + 1; j < recs.size(); ++j) {
      if (same_samples(recs[i], recs[j]))
        throw std::invalid_argument(recs[j].source + ": holds the same samples as " + recs[i].source +
                                    "; a recording given twice counts twice (its weight doubled, the parameter "
                                    "uncertainties understated): give each recording once");
      for (const auto& [x, y] : {std::pair<std::size_t, std::size_t>{i, j}, {j, i}})
        if (const std::string how = repeated_samples(recs[x], recs[y]); !how.empty())
          throw std::invalid_argument(recs[y].source + ": repeats the samples of " + recs[x].source + " (" + how +
                                      "); a recording given twice counts twice (its weight doubled, the parameter "
                                      "uncertainties understated): give each recording once");
    }
}

void write_recording_csv(const std::string& path, const Recording& rec, int temp_decimals) {
  RecordingWriter w;
  w.open(path, rec.channels, temp_decimals);
  for (const auto& kv : rec.meta) w.write_meta(kv.first, kv.second);
  std::vector<double> row(rec.channels.size());
  for (std::size_t r = 0; r < rec.rows(); ++r) {
    for (std::size_t c = 0; c < row.size(); ++c)
      row[c] = rec.temp_c(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c));
    w.append(rec.time_s[r], rec.speed_rpm[r], rec.ambient_c[r], row);
  }
  w.close();
}

RecordingWriter::~RecordingWriter() {
  if (file_) std::fclose(file_);
}

void RecordingWriter::open(const std::string& path, const std::vector<std::string>& channels, int temp_decimals) {
  close();
  if (channels.empty()) throw std::invalid_argument(path + ": a recording needs at least one temperature channel");
  for (const auto& c : channels)
    if (c.empty() || c.find(',') != std::string::npos || c.find('\n') != std::string::npos)
      throw std::invalid_argument(path + ": bad channel name '" + c + "'");
  // Through the output helper: fopen blocked for ever on a named pipe no program reads (record held
  // the module's link meanwhile), and its failure named no reason.
  file_ = io::open_output_stream(path, "recording");
  path_ = path;
  channels_ = channels;
  decimals_ = temp_decimals;
  header_written_ = false;
  rows_ = 0;
}

void RecordingWriter::write_meta(const std::string& key, const std::string& value) {
  if (!file_) throw std::logic_error("RecordingWriter: not open");
  if (header_written_) throw std::logic_error(path_ + ": metadata must come before the first row");
  if (key.find('\n') != std::string::npos || value.find('\n') != std::string::npos || key.find(':') != std::string::npos)
    throw std::invalid_argument(path_ + ": metadata key/value must be one line and the key must not contain ':'");
  std::fprintf(file_, "# %s: %s\n", key.c_str(), value.c_str());
}

void RecordingWriter::write_header_once() {
  if (header_written_) return;
  std::fputs("time_s,speed_rpm,ambient_c", file_);
  for (const auto& c : channels_) std::fprintf(file_, ",%s", c.c_str());
  std::fputc('\n', file_);
  header_written_ = true;
}

void RecordingWriter::append(double time_s, double speed_rpm, double ambient_c, const std::vector<double>& temps_c) {
  if (!file_) throw std::logic_error("RecordingWriter: not open");
  if (temps_c.size() != channels_.size())
    throw std::invalid_argument(path_ + ": row has " + std::to_string(temps_c.size()) + " temperatures, expected " +
                                std::to_string(channels_.size()));
  if (!std::isfinite(time_s) || !std::isfinite(speed_rpm) || !std::isfinite(ambient_c))
    throw std::invalid_argument(path_ + ": time, speed and ambient must be finite");
  write_header_once();
  std::string line = format_compact(time_s) + "," + format_compact(speed_rpm) + "," + format_number(ambient_c, 3);
  for (double t : temps_c) {
    line += ',';
    if (std::isfinite(t)) line += format_number(t, decimals_);
  }
  line += '\n';
  if (std::fputs(line.c_str(), file_) < 0) throw std::runtime_error(path_ + ": write failed");
  ++rows_;
}

void RecordingWriter::flush() {
  if (!file_) return;
  write_header_once();
  // A full disk (or /dev/full) shows here, not in fputs, which only fills the buffer.
  if (std::fflush(file_) != 0) throw std::runtime_error(path_ + ": write failed: " + std::strerror(errno));
}

void RecordingWriter::close() {
  if (!file_) return;
  write_header_once();
  const bool flushed = std::fflush(file_) == 0;
  const int err = errno;
  const bool closed = std::fclose(file_) == 0;
  file_ = nullptr;
  if (!flushed || !closed) throw std::runtime_error(path_ + ": write failed: " + std::strerror(flushed ? errno : err));
}

}  // namespace btsm::thermal
