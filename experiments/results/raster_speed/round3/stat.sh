#!/bin/bash
# User-space instructions, cycles and branch misses of the whole `render --no-gpu` process, before/after alternately (counts do not depend on load).
O=/tmp/14r_meas; export XDG_RUNTIME_DIR=$(mktemp -d)
echo "build,frame,instructions_u,cycles_u,branch_misses_u,user_s" > $O/perf_stat.csv
for frame in "synthetic close 1280 720" "synthetic far 1280 720" "stress medium 320 180" "stress far 1280 720" "stress medium 1280 720"; do
  set -- $frame
  for build in before after; do
    d=$(mktemp -d)
    perf stat -x, -e instructions:u,cycles:u,branch-misses:u -o $d/s -- nice -n 10 /tmp/14r_$build/forestlod render --no-gpu --scene $1 --camera $2 --width $3 --height $4 --out $d/o > $d/log 2>&1
    i=$(grep instructions $d/s | cut -d, -f1); c=$(grep cycles $d/s | cut -d, -f1); m=$(grep branch-misses $d/s | cut -d, -f1)
    u=$(grep -o "reference frame [0-9.]*" $d/log | tail -1)
    echo "$build,$1 $2 ${3}x$4,$i,$c,$m,$u" >> $O/perf_stat.csv
    rm -rf $d
  done
done
