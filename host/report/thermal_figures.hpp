#pragma once
// The figures drawn from a thermal network and a recording, in the common style (plot_style.hpp),
// shared by `btsm validate`, `btsm heat` and the demo so the same data always look the same.
// Library btsm_thermal_figures (it needs btsm_thermal; btsm_report itself stays generic).
#include "host/report/plot.hpp"
#include "host/thermal/heat_inverse.hpp"
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"
#include "host/thermal/validate.hpp"

#include <string>
#include <vector>

namespace btsm::report {

// Colours keyed by the network's node names, in node order: every figure of one network agrees.
FigureOptions network_figure_options(const thermal::Network& net);

// The recording's speed column under its time axis. A recording whose speed_rpm column holds
// another input declares it with "# speed_rpm_quantity: NAME (UNIT)" (e.g. "heater power (W)" in
// a converted data set): the panel is titled with NAME and its y axis labelled "NAME (UNIT)". A
// "# speed_rpm: ..." description alone becomes the (wrapped) title, with no unit claimed.
Plot recording_speed_panel(const thermal::Recording& rec);

// The stretches each declared event column of the recording (`# event_columns:`, e.g. lid_open)
// is 1, as spans over time (h) labelled "COLUMN = 1". A row's value holds until the next row (as
// the speed does), so a run of 1s spans from its first row's time to the next row's time after it.
std::vector<Span> event_spans(const thermal::Recording& rec);
// Adds the recording's event spans to every panel whose x axis is time (kTimeAxis).
void add_event_spans(std::vector<Plot>& panels, const thermal::Recording& rec);

// Measured vs the model's prediction per measured node, the residual per node, and the speed;
// the recording's declared events shaded on each.
// `title` names the recording. Measurements whose column the recording lacks are left out.
std::vector<Plot> validation_figure(const thermal::Network& net, const thermal::Recording& rec,
                                    const thermal::RecordingValidation& v, const std::string& title);

// `btsm heat`: the estimated heat per source node, measured vs fitted temperatures, residuals,
// speed, and (when alpha was chosen by a rule) the criterion over alpha with the chosen alpha
// marked; the recording's declared events shaded on the time panels. `columns` are the measured
// columns in the problem's order.
std::vector<Plot> heat_figure(const thermal::Network& net, const thermal::Recording& rec,
                              const thermal::InverseProblem& p, const thermal::HeatInverseResult& r,
                              const std::vector<std::string>& columns, const std::string& method);

}  // namespace btsm::report
