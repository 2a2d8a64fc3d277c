#!/bin/bash
# make_recordings.sh OUTDIR SEED [EFFECT|fault=FAULT ...]
# The paper's identification procedure recorded as tools/gen_reference_data.py records it (the format
# of tests/data/tnm-reference): five 6 h warm-ups at 4006..8028 rpm with 4 h of natural cooling and a
# 3001/5018/7028 rpm stepwise check (2 h each, 3 h cooling), 25 degC, 5 s rows, white noise
# sigma 5 mK (awk's generator seeded with SEED), T1..T3 the bearing/housing probes, T4 the shaft node
# only while stopped. The truth comes from `btsm sim-module --truth-out` with the hidden effects
# (its plant without effects equals the generator's to 5 uK). Needs: bash, awk, btsm ($BTSM).
set -e
B=${BTSM:-btsm}
out=$1; seed=$2; shift 2
mkdir -p "$out"
eff=()
for e in "$@"; do case "$e" in fault=*) eff+=(--fault "${e#fault=}");; *) eff+=(--effect "$e");; esac; done
i=0
for run in warmup_4006rpm:6h@4006,4h@0 warmup_5013rpm:6h@5013,4h@0 warmup_6021rpm:6h@6021,4h@0 \
           warmup_7023rpm:6h@7023,4h@0 warmup_8028rpm:6h@8028,4h@0 stepwise_3001_5018_7028:2h@3001,2h@5018,2h@7028,3h@0; do
  name=${run%%:*}; prof=${run#*:}; i=$((i+1))
  "$B" sim-module --pty "/tmp/refgen-$$" --no-wait --profile "$prof" --ambient 25 \
    --truth-out "$out/.truth_$name.csv" --truth-period 5 "${eff[@]}" > /dev/null 2>&1
  # columns of the truth file: 1 time_s, 2 speed_rpm, 4-6 T1..T3 (probe points, probe effects
  # included), 12 node_shaft
  awk -F, -v seed=$((seed*10+i)) 'BEGIN{srand(seed); print "time_s,speed_rpm,ambient_c,T1,T2,T3,T4"}
    function g(  u1,u2){ u1=rand(); if(u1<1e-12)u1=1e-12; u2=rand(); return sqrt(-2*log(u1))*cos(6.283185307179586*u2) }
    /^[0-9]/{ t4 = ($2==0) ? sprintf("%.4f", $12+0.005*g()) : "";
      printf "%g,%g,%.2f,%.4f,%.4f,%.4f,%s\n", $1,$2,25,$4+0.005*g(),$5+0.005*g(),$6+0.005*g(),t4 }' \
    "$out/.truth_$name.csv" > "$out/$name.csv"
done
rm -f "$out"/.truth_*.csv
