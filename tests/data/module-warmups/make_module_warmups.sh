#!/usr/bin/env bash
# Regenerates the recordings in this folder: the demo's three identification warm-ups (4 h at
# 4000, 6000, 8000 rpm, each followed by 3 h of natural cooling) recorded with `btsm record` at the
# module's 5 s period from a simulated module (native board, spindle4 plant with its Table 2/3
# values and NO hidden effect, fifth probe on the shaft end, AD7794 noise seed SEED).
# RPMS (three speeds) replaces the demo's speeds: the sigma coverage study runs other experiments.
#   usage: make_module_warmups.sh BTSM OUTDIR [SEED=1] [RPMS=4000,6000,8000]
set -euo pipefail
BTSM=$1; OUT=$2; SEED=${3:-1}; RPMS=${4:-4000,6000,8000}
IFS=, read -r R1 R2 R3 <<< "$RPMS"
mkdir -p "$OUT"
T=$(mktemp -d)
"$BTSM" sim-module --board native --pty "$T/pty" --ch5 shaft --seed "$SEED" \
  --profile "4h@$R1,3h@0,4h@$R2,3h@0,4h@$R3,3h@0,1h@0" > "$T/sim.log" 2>&1 &
SIM=$!
for _ in $(seq 100); do [ -e "$T/pty" ] && break; sleep 0.1; done
for rpm in $R1 $R2 $R3; do
  "$BTSM" record --port "$T/pty" --out "$T/warmup_${rpm}rpm.csv" --duration 25200 > "$T/record_$rpm.log" 2>&1
  sed 's|^# link: serial .*|# link: serial (pty of btsm sim-module)|' "$T/warmup_${rpm}rpm.csv" > "$OUT/warmup_${rpm}rpm.csv"
done
kill "$SIM" 2>/dev/null || true
wait "$SIM" 2>/dev/null || true
rm -rf "$T"
