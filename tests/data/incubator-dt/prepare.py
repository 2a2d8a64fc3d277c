#!/usr/bin/env python3
"""Convert the Incubator DT recordings into the btsm recording format (python3, stdlib only).

usage: python3 prepare.py [/work/shared/data/incubator-dt]
Writes next to this script:
  calib2023_fit_0-55min.csv, calib2023_check_55-111min.csv   (20230501_calibration_empty_system.csv)
  lid2021_events_fit_0-170min.csv, lid2021_events_check_170-323min.csv
                                                             (lid_opening_experiment_mar_2021.csv with the logged
                                                              lid state as a declared event column, fit part with
                                                              6 openings)
  lid2021_fit_0-34min.csv, lid2021_check_34-323min.csv       (the first cut, at the first opening: no opening
                                                              in the fit part, no event column)

Input mapping (the network format has one input column, `speed_rpm`, and sources proportional to
(speed_rpm / speed_ref_rpm)^e): speed_rpm := electrical heater power in W while heater_on, else 0.
"""
import csv, os, sys

SRC = sys.argv[1] if len(sys.argv) > 1 else "/work/shared/data/incubator-dt"
HERE = os.path.dirname(os.path.abspath(__file__))

# 2023: 12.16 V (source README) x mean of the 11 supply-current readings of 2023-06-05 (1.5388 A) = 18.71 W
P_2023_W = 18.71
# 2021: not measured; the repository's 7-parameter model calibrated on this run uses V_heater 12.0 V x I_heater 10.45 A = 125.4 W (ASSUMED)
P_2021_W = 125.4


def load(name, amb, box):
    rows = list(csv.DictReader(open(os.path.join(SRC, name), newline="")))
    t0 = int(rows[0]["time"])
    out = []
    for r in rows:
        t = (int(r["time"]) - t0) / 1e9
        out.append((t, r["heater_on"] == "True", float(r[amb]), float(r["average_temperature"]), float(r[box[0]]), float(r[box[1]])))
    return out, t0


def write(path, rows, power_w, box, header_lines, offset, lid_intervals=None):
    """lid_intervals: [(open_s, close_s)] in the same time base as rows; when given, a declared 0/1 event
    column `lid_open` is written. Like speed_rpm, an event cell on row k holds over [t_k, t_k+1), so a row
    is 1 when the lid was open at its time stamp."""
    with open(os.path.join(HERE, path), "w", newline="\n") as f:
        for h in header_lines:
            f.write("# " + h + "\n")
        f.write(f"# original_time_offset_s: {offset:.1f}\n")
        if lid_intervals is not None:
            f.write("# event_columns: lid_open\n")
        f.write(f"time_s,speed_rpm,ambient_c,box_avg,{box[0]},{box[1]}" + (",lid_open" if lid_intervals is not None else "") + "\n")
        last = None
        for t, on, amb, avg, a, b in rows:
            ts = round(t - offset, 1)
            if last is not None and ts <= last:
                raise SystemExit(f"{path}: time not increasing at {ts}")
            last = ts
            line = f"{ts:.1f},{power_w if on else 0},{amb:g},{avg:g},{a:g},{b:g}"
            if lid_intervals is not None:
                line += ",1" if any(o <= t < c for o, c in lid_intervals) else ",0"
            f.write(line + "\n")
    print(path, len(rows))


# --- 2023 calibration, empty closed box: room = t3, box = t1, t2
rows, t0 = load("20230501_calibration_empty_system.csv", "t3", ("t1", "t2"))
split = 3300.0
common = [
    "source: GitHub INTO-CPS-Association/example_digital-twin_incubator @ 2f08c4f6916258582715e6fc705b4c315d55baaa, "
    "software/incubator/datasets/20230501_calibration_empty_system/20230501_calibration_empty_system.csv (no licence found), "
    "via /work/shared/data/incubator-dt; not decimated (irregular 1-7.5 s steps kept, times rounded to 0.1 s)",
    f"time_s: s since the first sample (unix time {t0} ns)",
    f"speed_rpm: NOT a speed - electrical heater power in W while heater_on (12.16 V x 1.5388 A = {P_2023_W} W, "
    "measured 2023-06-05 with heater + fan on), 0 while off",
    "speed_rpm_quantity: heater power (W)",
    "ambient_c: t3 (room sensor); box_avg = average_temperature = (t1 + t2)/2 (the two in-box sensors); fan on except the first 1.6 min",
]
write("calib2023_fit_0-55min.csv", [r for r in rows if r[0] < split], P_2023_W, ("t1", "t2"), common, 0.0)
chk = [r for r in rows if r[0] >= split]
write("calib2023_check_55-111min.csv", chk, P_2023_W, ("t1", "t2"), common, chk[0][0])

# --- 2021 lid-opening experiment: room = t1, box = t2, t3; first lid opening 2053 s after the first sample
rows, t0 = load("lid_opening_experiment_mar_2021.csv", "t1", ("t2", "t3"))
events = list(csv.DictReader(open(os.path.join(SRC, "lid_opening_events_mar_2021.csv"), newline="")))
common = [
    "source: GitHub INTO-CPS-Association/example_digital-twin_incubator @ 2f08c4f6916258582715e6fc705b4c315d55baaa, "
    "software/incubator/datasets/20210321_lid_opening_7pmodel/lid_opening_experiment_mar_2021.csv (no licence found), "
    "via /work/shared/data/incubator-dt; not decimated (3 s steps), times rounded to 0.1 s",
    f"time_s: s since the first sample (unix time {t0} ns)",
    f"speed_rpm: NOT a speed - heater power in W while heater_on, ASSUMED {P_2021_W} W (12.0 V x 10.45 A of the repository's 7-parameter model for this run, "
    "seven_parameters_model/best_parameters.py; not measured), 0 while off",
    "speed_rpm_quantity: heater power (W)",
    "ambient_c: t1 (room sensor); box_avg = average_temperature = (t2 + t3)/2 (the two in-box sensors); fan on throughout",
]
# The first cut, kept as the counter-example: fit on everything before the first lid opening (no opening,
# no event column), check from the first opening on (the event times relative to it in its header).
split = (int(events[0]["time"]) - t0) / 1e9
write("lid2021_fit_0-34min.csv", [r for r in rows if r[0] < split], P_2021_W, ("t2", "t3"), common, 0.0)
chk = [r for r in rows if r[0] >= split]
lid_chk = [f"lid events (s since the first sample of THIS file): " + ", ".join(
    f"{e['code']} {(int(e['time']) - t0) / 1e9 - chk[0][0]:.0f}" for e in events)]
write("lid2021_check_34-323min.csv", chk, P_2021_W, ("t2", "t3"), common + lid_chk, chk[0][0])

# --- cut so that the fit part holds openings, with the logged lid state as a declared
# event column. The fit part ends at 170 min (10,200 s): six openings (34, 61, 86, 111, 137, 162 min) and the cup
# of water put in at 137 min; the check part (170-323 min) holds the seventh opening and the water's removal
# (294 min). Open/close come from the events file (10 s resolution, entered by hand during the experiment).
opens = [(int(e["time"]) - t0) / 1e9 for e in events if e["code"] == "lid_open"]
closes = [(int(e["time"]) - t0) / 1e9 for e in events if e["code"] == "lid_close"]
if len(opens) != len(closes) or any(c <= o for o, c in zip(opens, closes)):
    raise SystemExit("lid events: open/close do not pair up")
lid_intervals = list(zip(opens, closes))
split = 170 * 60.0
objects = ", ".join(f"{e['code']} {(int(e['time']) - t0) / 1e9:.0f}" for e in events if e["code"].startswith("object"))
ev_common = common + [
    "lid_open: 1 while the lid was open per the experiment's events.csv (lid_open/lid_close, same folder, "
    "times entered to 10 s), else 0; declared below as an event column",
    f"not in any column: a cup of water put into the box and taken out (s since the first sample of the run): {objects}",
]
write("lid2021_events_fit_0-170min.csv", [r for r in rows if r[0] < split], P_2021_W, ("t2", "t3"), ev_common, 0.0,
      lid_intervals)
chk = [r for r in rows if r[0] >= split]
write("lid2021_events_check_170-323min.csv", chk, P_2021_W, ("t2", "t3"), ev_common, chk[0][0],
      lid_intervals)
