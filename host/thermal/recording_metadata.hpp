#pragma once
// The metadata lines of a recording that commands act on, checked when the recording is read:
//
//   # channel_roles: T1=rear_bearing,T2=housing,T3=front_bearing,T4=ambient,T5=shaft
//   # ambient_channel: T4
//   # boundary_columns: ... / # event_columns: ...   (declared_columns.hpp)
//
// `btsm record` writes channel_roles and ambient_channel from the module's configuration (the
// ambient channel's reading is the ambient_c column, not a T column of its own). A fit maps each
// network node named like a role to the channel with that role (column_map.hpp), and the fitted
// model's channel_map names the ambient channel, so a contradiction here would silently measure the
// wrong node or drop the ambient: it is an error naming the file and the entries.
#include "recording.hpp"

#include <string>
#include <utility>
#include <vector>

namespace btsm::thermal {

// The (column, role) pairs of the channel_roles line, in order; empty when the line is absent or
// says the roles are firmware defaults rather than read from the module ("... (firmware defaults,
// not read from the module)"). Throws io::InputError (a std::invalid_argument) naming the file and the entry on a
// malformed entry, an unknown role, a column listed twice, or a measured role (a bearing, the
// housing, the ambient ...) on two columns.
std::vector<std::pair<std::string, std::string>> channel_roles(const Recording& rec);

// The ambient_channel line ("T4"), or "" when absent. Throws naming the file when it does not name
// a module channel T1..T5, or contradicts channel_roles (that channel has another role, or another
// channel is the ambient).
std::string ambient_channel(const Recording& rec);

// Every check of this header and declared_columns.hpp; read_recording_csv() runs it.
void check_recording_metadata(const Recording& rec);

// One warning per metadata line that looks like a key above but is not read as it ("# channel_roles
// = ...", "## channel_roles: ...", "# channel-roles: ...", "# ambient channel: T4"), quoting the
// line: what it says is ignored. Not refused: a '#' line may be a comment saying anything.
std::vector<std::string> metadata_warnings(const Recording& rec);

// What a command says about a recording it read and took: its long gap (long_gap_warning),
// metadata_warnings and the reader's own warnings (Recording::warnings: malformed sensor_fault lines).
std::vector<std::string> reading_warnings(const Recording& rec);

}  // namespace btsm::thermal
