#!/bin/bash
# run_cases.sh CASES_FILE OUTROOT : for each ID|FAMILY|EFFECT line (draw_cases.py), the recordings
# (make_recordings.sh, noise seed 1000+ID) and `btsm residual --preset spindle4 --json` on them;
# one result line per case appended to OUTROOT/results.txt (a case with an answer is skipped, so a
# stopped run resumes). Needs bash, awk, python3 (to read the JSON answer), btsm ($BTSM).
here=$(cd "$(dirname "$0")" && pwd)
B=${BTSM:-btsm}
cases=$1; root=$2; mkdir -p "$root"
while IFS='|' read -r id fam eff; do
  d=$root/$id; [ -f "$d/r.json" ] && continue
  if [ -n "$eff" ]; then "$here/make_recordings.sh" "$d" $((1000+10#$id)) "$eff"; else "$here/make_recordings.sh" "$d" $((1000+10#$id)); fi
  s=$(date +%s.%N)
  (cd "$d" && "$B" residual --fit warmup_*.csv --check stepwise_3001_5018_7028.csv --preset spindle4 --json > r.json.part 2> r.log &&
     mv r.json.part r.json)
  e=$(date +%s.%N)
  python3 - "$d" "$id" "$fam" "$eff" "$(echo "$e - $s" | bc)" >> "$root/results.txt" <<'PY'
import json, sys
d, i, fam, eff, wall = sys.argv[1:]
try:
    r = json.load(open(d + "/r.json"))
    b, a = r["rmse_before_K"], r["rmse_after_K"]
    print(f"{i} | {fam:32s} | {eff:52s} | {r['verdict']:11s} {r['effect']}@{'+'.join(r['nodes'])} | {b:.4f} -> {a:.4f} x{b/a:.1f} | {float(wall):.0f} s")
except Exception as ex:
    print(f"{i} | {fam} | {eff} | ERROR {ex} | {float(wall):.0f} s")
PY
done < "$cases"
