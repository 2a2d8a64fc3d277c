#!/usr/bin/env python3
"""Convert the Incubator DT recordings into the btsm recording format (python3, stdlib only).

usage: python3 prepare.py [/work/shared/data/incubator-dt]
Writes next to this script:
  calib2023_fit_0-55min.csv, calib2023_check_55-111min.csv   (20230501_calibration_empty_system.csv)
  lid2021_fit_0-34min.csv,   lid2021_check_34-323min.csv     (lid_opening_experiment_mar_2021.csv)

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


def write(path, rows, power_w, box, header_lines, offset):
    with open(os.path.join(HERE, path), "w", newline="\n") as f:
        for h in header_lines:
            f.write("# " + h + "\n")
        f.write(f"# original_time_offset_s: {offset:.1f}\n")
        f.write(f"time_s,speed_rpm,ambient_c,box_avg,{box[0]},{box[1]}\n")
        last = None
        for t, on, amb, avg, a, b in rows:
            ts = round(t - offset, 1)
            if last is not None and ts <= last:
                raise SystemExit(f"{path}: time not increasing at {ts}")
            last = ts
            f.write(f"{ts:.1f},{power_w if on else 0},{amb:g},{avg:g},{a:g},{b:g}\n")
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
    "ambient_c: t3 (room sensor); box_avg = average_temperature = (t1 + t2)/2 (the two in-box sensors); fan on except the first 1.6 min",
]
write("calib2023_fit_0-55min.csv", [r for r in rows if r[0] < split], P_2023_W, ("t1", "t2"), common, 0.0)
chk = [r for r in rows if r[0] >= split]
write("calib2023_check_55-111min.csv", chk, P_2023_W, ("t1", "t2"), common, chk[0][0])

# --- 2021 lid-opening experiment: room = t1, box = t2, t3; first lid opening 2053 s after the first sample
rows, t0 = load("lid_opening_experiment_mar_2021.csv", "t1", ("t2", "t3"))
events = list(csv.DictReader(open(os.path.join(SRC, "lid_opening_events_mar_2021.csv"), newline="")))
split = (int(events[0]["time"]) - t0) / 1e9
common = [
    "source: GitHub INTO-CPS-Association/example_digital-twin_incubator @ 2f08c4f6916258582715e6fc705b4c315d55baaa, "
    "software/incubator/datasets/20210321_lid_opening_7pmodel/lid_opening_experiment_mar_2021.csv (no licence found), "
    "via /work/shared/data/incubator-dt; not decimated (3 s steps), times rounded to 0.1 s",
    f"time_s: s since the first sample (unix time {t0} ns)",
    f"speed_rpm: NOT a speed - heater power in W while heater_on, ASSUMED {P_2021_W} W (12.0 V x 10.45 A of the repository's 7-parameter model for this run, "
    "seven_parameters_model/best_parameters.py; not measured), 0 while off",
    "ambient_c: t1 (room sensor); box_avg = average_temperature = (t2 + t3)/2 (the two in-box sensors); fan on throughout",
]
lid = [f"lid events (s since the first sample): " + ", ".join(
    f"{e['code']} {(int(e['time']) - t0) / 1e9:.0f}" for e in events)]
write("lid2021_fit_0-34min.csv", [r for r in rows if r[0] < split], P_2021_W, ("t2", "t3"), common, 0.0)
chk = [r for r in rows if r[0] >= split]
lid_chk = [f"lid events (s since the first sample of THIS file): " + ", ".join(
    f"{e['code']} {(int(e['time']) - t0) / 1e9 - chk[0][0]:.0f}" for e in events)]
write("lid2021_check_34-323min.csv", chk, P_2021_W, ("t2", "t3"), common + lid_chk, chk[0][0])
