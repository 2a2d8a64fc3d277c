#pragma once
// Which recording column measures which node of a network: the columns a network's measurements
// name, and the mapping a module recording's channel roles decide.
#include "network.hpp"
#include "recording.hpp"

#include <string>
#include <vector>

namespace btsm::thermal {

// Channel index in `rec` of each measurement of `net`; throws naming the missing column.
std::vector<int> measurement_columns(const Network& net, const Recording& rec);
// Which column measures which node, from the recordings' `channel_roles` metadata (written by
// `btsm record` as "T1=rear_bearing,...,T5=shaft"), then `columns` (--column) on top, applied to
// `net` with remap_measurements(). A node named like a thermal role (common/wire_messages.hpp
// is_thermal_role: the spindle4 nodes rear_bearing, housing, front_bearing, shaft) is measured by
// the channel with that role, or by none when no channel has it -- a module recording says itself
// where its probes are. Nodes named in `columns` are left to those. Recordings without the
// metadata, or with roles that are firmware defaults rather than read from the module, contribute
// nothing. Returns what the roles decided (" node=column ...", "(none)" for a dropped node), or ""
// when they decided nothing. Throws std::invalid_argument when recordings disagree (naming the
// node and both files) or as remap_measurements() does.
std::string map_measurements(Network& net, const std::vector<Recording>& recs, const std::vector<std::string>& columns);

// One entry of a fitted model's "channel_map" (model_file.hpp channel_map_json): the column, the
// module role its channel had in the fit's recordings ("" when they carried none) and the node the
// fit measured with it ("" for none).
struct FittedChannel {
  std::string column, module_role, node;
};

// The measurements of `net` whose column `rec` has but with no value in any row: a probe open or
// unplugged for the whole recording (every cell empty). Scored or fitted, such a node gives no
// number ("nan", "--") while its neighbours are worked out as if it had been seen.
std::vector<Measurement> unsampled_measurements(const Network& net, const Recording& rec);
// A warning per unsampled measurement, "REC: column 'T1' (node 'rear_bearing') has no value in any
// row: CONSEQUENCE", for the commands that go on without it (validate, heat).
std::vector<std::string> unsampled_measurement_warnings(const Network& net, const Recording& rec, const std::string& consequence);
// Throws std::invalid_argument when a column `net` measures has no value in any row of any of
// `recs` (a fit "converged" on a node it never saw, and its channel map said the probe measures
// it), naming the column, its node and the files.
void refuse_unsampled_measurements(const Network& net, const std::vector<Recording>& recs);

// A model that already says which column measures which node (a fitted model, scored by validate,
// heat and residual --use-values) against recordings whose channel_roles say where the probes are:
// a role-named node measured by a column the roles give to another role (or to none) would be
// scored against the wrong probe. Nodes named in `columns` (--column) are left to those, and so is
// a node the fit itself mapped against the roles (`fitted`, the model's channel map: fit --column
// shaft=T5 on a spare T5) when the recording's roles say of it what the fit's recordings said. Throws
// std::invalid_argument naming the recording, the node and both columns; `advice` ends the message
// (what the user can do with the command at hand).
void check_mapping_agrees_with_roles(const Network& net, const std::vector<FittedChannel>& fitted,
                                     const std::vector<Recording>& recs, const std::vector<std::string>& columns,
                                     const std::string& advice);

}  // namespace btsm::thermal
