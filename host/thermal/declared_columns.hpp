#pragma once
// Declared extra columns of a recording: inputs, never a node's measurement.
//
//   # boundary_columns: coolant_c            a further thermal boundary (degC), e.g. coolant or chiller
//                                            water: a link may end there (network.hpp "boundaries")
//   # event_columns: lid_open                0/1 switch events (a door or lid open, a pump on): a term
//                                            may be present only while the event is 1 ("events")
//
// Several columns are separated by commas. The command-line options --boundary COL / --event COL
// declare them for files without the metadata; declare_columns() merges both into the metadata, so
// a recording written back keeps them. A column may be declared once, as one kind.
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"

#include <string>
#include <vector>

namespace btsm::thermal {

inline constexpr const char* kBoundaryColumnsKey = "boundary_columns";
inline constexpr const char* kEventColumnsKey = "event_columns";

// The columns declared in the metadata (in order, trimmed, duplicates removed).
std::vector<std::string> boundary_columns(const Recording& rec);
std::vector<std::string> event_columns(const Recording& rec);
// True when `column` is declared as a boundary or an event.
bool is_declared_column(const Recording& rec, const std::string& column);

// Checks the declarations in the metadata: each column is in the header, not declared as both
// kinds, boundary cells are all present, event cells are 0 or 1. Throws io::InputError
// naming the file, the column and (for a bad cell) its time and row. Every recording read is
// checked (read_recording_csv), so no command uses a declaration residual would refuse.
void check_declared_columns(const Recording& rec);

// Adds the command-line declarations to the metadata and checks every declaration as
// check_declared_columns() does; `rec` is unchanged when that throws.
void declare_columns(Recording& rec, const std::vector<std::string>& boundaries, const std::vector<std::string>& events);

// Throws std::invalid_argument when the network measures a column the recording declares as a
// boundary or an event (a declared column is an input, never a node's temperature).
void check_measurements_not_declared(const Network& net, const Recording& rec);

}  // namespace btsm::thermal
