#!/bin/bash
# Reference frame CPU seconds, three builds alternately: before (main), after (round 3), noconst (round 3 without the constant-varying shortcut).
O=/tmp/14r_meas; export XDG_RUNTIME_DIR=$(mktemp -d)
scene=$1; cam=$2; w=$3; h=$4; rounds=$5
for r in $(seq $rounds); do
  for build in before after nobucket; do
    d=$(mktemp -d)
    nice -n 10 /tmp/14r_$build/forestlod render --no-gpu --scene $scene --camera $cam --width $w --height $h --out $d/o > $d/log 2>&1
    echo "$build,$scene $cam ${w}x$h r$r,$(grep -o 'reference frame [0-9.]*' $d/log | tail -1 | cut -d' ' -f3),$(cut -d' ' -f1 /proc/loadavg)" >> $O/ab4.csv
    rm -rf $d
  done
done
