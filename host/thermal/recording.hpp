#pragma once
// Recording CSV: the one file format every area reads and writes.
//
//   # key: value                     (metadata lines, anywhere before the header)
//   time_s,speed_rpm,ambient_c,T1,...,Tn
//   0,6021,25.00,24.9910,24.9982,25.0038,
//
// One row per sample. speed_rpm on row k is the speed held over [t_k, t_k+1) (zero-order hold);
// the temperatures on row k are the state at t_k, in degC; an empty cell is a missing value
// (stored as NaN). ambient_c is the boundary temperature of the network, a time series.
#include <Eigen/Core>

#include <cstddef>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

namespace btsm::thermal {

struct Recording {
  std::string source;                  // file name (or any label) used in error messages
  std::vector<std::string> channels;   // temperature column names after ambient_c (e.g. T1..T4)
  std::vector<double> time_s, speed_rpm, ambient_c;
  Eigen::MatrixXd temp_c;              // rows x channels, degC, NaN = missing
  std::vector<std::pair<std::string, std::string>> meta;  // "# key: value" lines, in order
  // What the reader noticed in lines nothing acts on, and did not refuse ("FILE:LINE: ..."): a
  // malformed '# sensor_fault:' line. Commands print them with reading_warnings().
  std::vector<std::string> warnings;

  std::size_t rows() const { return time_s.size(); }
  // Index of a channel by name, or -1.
  int channel_index(const std::string& name) const;
  // Value of a metadata key, or "" if absent.
  std::string meta_value(const std::string& key) const;
};

// Bounds of the values a recording may hold. Beyond them the arithmetic of fit and simulation
// overflows (a speed of 1e300 rpm raised to a speed exponent, a temperature of 1e155 squared) and
// no real spindle gets there: temperatures at or above absolute zero and below 10,000 degC (every
// material has melted), speeds up to 1,000,000 rpm (the fastest spindles run at a few 100,000).
constexpr double kMinRecordedTempC = -273.15;
constexpr double kMaxRecordedTempC = 10000.0;
constexpr double kMaxRecordedSpeedRpm = 1.0e6;
// Time: |time_s| up to 1e9 s (31 years of module time) and rows at least 1 ms apart (the module
// samples every 1 s at the fastest). Beyond them a replay at the module's 5 s step runs for ever
// and an inverse divides by a step of nanoseconds (57 kW out of 8 K in half a microsecond).
constexpr double kMaxRecordedTimeS = 1.0e9;
constexpr double kMinRecordedStepS = 1.0e-3;
// Size cap of a recording file (about 4 million rows of 5 channels), stated in the error.
constexpr std::size_t kMaxRecordingBytes = std::size_t{256} << 20;

// "" unless `column` is one of the three columns every recording has before its temperature
// columns (time_s, speed_rpm, ambient_c); then why it cannot be a temperature column (measured,
// boundary or event), for a message of the form "column 'time_s' ... is reserved: ...". Without it
// such a column was reported as "no column 'time_s'", and the user looked for a typo.
std::string reserved_column_problem(const std::string& column);

// "" or a warning naming the recording's longest gap between rows when it is both over an hour
// and more than 100 times the rows' usual (median) spacing: a model replayed over the recording runs
// through it with the speed and ambient of the row before held, which a logger that was off did not
// see (a 15-year gap was bridged without a word). Not an error: a stop may be logged sparsely.
std::string long_gap_warning(const Recording& r);

// Reads a recording. Throws io::InputError (a std::invalid_argument)
// "<file>:<line>:<column>: <problem>" on a missing or misplaced mandatory column, a bad,
// non-finite or out-of-bounds number, a wrong cell count, non-increasing time, or an empty file;
// and naming the file when it cannot be read, is not text, or is larger than kMaxRecordingBytes.
// Empty temperature cells are missing values; time, speed and ambient must be present on every row.
Recording read_recording_csv(const std::string& path);
// Same, from text already in memory (`source` names it in errors).
Recording parse_recording_csv(const std::string& text, const std::string& source);

// True when both hold the same samples (time, speed, ambient, columns and every temperature, an
// empty cell equal to an empty cell), whatever their file names and metadata.
bool same_samples(const Recording& a, const Recording& b);
// When (98 % or more of) the rows of `b` repeat a row of `a` at the same place in time, `a`'s times moved
// by one offset: the same speed, and every temperature column they share within 0.5 mK (a copy
// with shifted times, every n-th row, or a nudge below any sensor's resolution). Says how
// ("times shifted by 999980000 s, 1 of every 2 rows"; for a contiguous part of `a`, such as its first
// half, "its rows 1-549 are rows 1-549 of A.csv"); "" otherwise, or when `b` has under 10 rows.
std::string repeated_samples(const Recording& a, const Recording& b);
// Throws std::invalid_argument naming both files when two of `recs` hold the same samples, or one
// repeats the other's (repeated_samples): a recording given twice is fitted with double weight,
// which halves no error but does halve the parameter uncertainties the fit reports.
void refuse_repeated_recordings(const std::vector<Recording>& recs);

// Writes metadata, header and rows (temperatures with 4 decimals, NaN as an empty cell).
void write_recording_csv(const std::string& path, const Recording& rec, int temp_decimals = 4);

// Live recording: metadata first, then the header (on the first row or on flush), then rows.
class RecordingWriter {
 public:
  RecordingWriter() = default;
  ~RecordingWriter();
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  // Opens (truncates) `path` for the given temperature channel names. Throws on failure.
  void open(const std::string& path, const std::vector<std::string>& channels, int temp_decimals = 4);
  bool is_open() const { return file_ != nullptr; }
  // "# key: value"; only before the first row (throws std::logic_error afterwards).
  void write_meta(const std::string& key, const std::string& value);
  // One sample; temps.size() must equal the channel count; NaN = missing.
  void append(double time_s, double speed_rpm, double ambient_c, const std::vector<double>& temps_c);
  void flush();
  void close();
  std::size_t rows_written() const { return rows_; }

 private:
  void write_header_once();
  std::FILE* file_ = nullptr;
  std::string path_;
  std::vector<std::string> channels_;
  int decimals_ = 4;
  bool header_written_ = false;
  std::size_t rows_ = 0;
};

}  // namespace btsm::thermal
