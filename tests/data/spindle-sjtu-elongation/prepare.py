#!/usr/bin/env python3
"""Cut/decimate the SJTU spindle warm-up into the btsm recording format (python3, stdlib only).

usage: python3 prepare.py /work/shared/data/spindle-sjtu-elongation/spindle_elongation_16T.csv
Writes sjtu_fit_0-24h.csv and sjtu_check_24-78h.csv next to this script.
"""
import csv, os, sys

SRC = sys.argv[1] if len(sys.argv) > 1 else "/work/shared/data/spindle-sjtu-elongation/spindle_elongation_16T.csv"
HERE = os.path.dirname(os.path.abspath(__file__))
DECIMATE = 2          # 1 min -> 2 min
SPLIT_MIN = 24 * 60   # fit: rows with t < 24 h; check: the rest
RUN_RPM = 1000        # placeholder "running" value: the real speed is not in the source
TEMPS = ["T0", "T1", "T2", "T3", "T4", "T12", "T13", "T14"]
# The cooling water, declared as a second thermal boundary (`# boundary_columns: coolant_c`). The source
# names seven water sensors T5-T11 (front-bearing water in/out, motor water in/out, jacket front/middle/rear)
# without saying which is which; chosen a priori, not by fit quality: T8, the coolest of the seven over the
# whole run (24.5 degC mean, T6 24.7, the others 25.6-29.5) and the least noisy, i.e. most likely a supply
# (inflow) line from the chiller, before the water picks up the spindle's heat.
COOLANT = "T8"

rows = list(csv.reader(open(SRC, encoding="utf-8-sig", newline="")))
head = [c.strip() for c in rows[0]]
data = [[float(x) for x in r] for r in rows[1:]]
col = {c: i for i, c in enumerate(head)}

def write(name, sel, offset_s, first_is_standstill):
    with open(os.path.join(HERE, name), "w", newline="\n") as f:
        f.write("# source: GitHub ruoheng-du/thermal-expansion-error-prediction, data/thermal expansion error original.csv "
                "(no licence stated), via /work/shared/data/spindle-sjtu-elongation, decimated 1 min -> 2 min\n")
        f.write("# time_s: row index x 60 s (the source has no time column; 1 sample/min per the source report)\n")
        f.write("# speed_rpm: 1000 = placeholder for 'running' (speed not given by the source; one constant operating "
                "condition assumed, switched on at t = 0)\n")
        f.write("# speed_rpm_quantity: running (1000 = on)\n")
        f.write("# ambient_c: T15 (ambient sensor); T0 front bearing inside, T1-T4 front bearing housing, "
                "T12/T13 rear bearing inside/outside, T14 worktable; delta L and the other coolant sensors dropped\n")
        f.write(f"# coolant_c: {COOLANT} (cooling water, most likely the chiller's supply line: the coolest and least "
                "noisy of the seven water sensors T5-T11, whose positions the source does not assign)\n")
        f.write(f"# original_time_offset_s: {offset_s}\n")
        f.write("# boundary_columns: coolant_c\n")
        f.write("time_s,speed_rpm,ambient_c," + ",".join(TEMPS) + ",coolant_c\n")
        for k, i in enumerate(sel):
            r = data[i]
            w = 0 if (first_is_standstill and k == 0) else RUN_RPM
            f.write(f"{i * 60 - offset_s},{w},{r[col['T15']]:.4f}," + ",".join(f"{r[col[c]]:.4f}" for c in TEMPS)
                    + f",{r[col[COOLANT]]:.4f}\n")

idx = list(range(0, len(data), DECIMATE))
fit = [i for i in idx if i * 60 < SPLIT_MIN * 60]
chk = [i for i in idx if i * 60 >= SPLIT_MIN * 60]
write("sjtu_fit_0-24h.csv", fit, 0, True)
write("sjtu_check_24-78h.csv", chk, chk[0] * 60, False)
print(len(fit), len(chk))
