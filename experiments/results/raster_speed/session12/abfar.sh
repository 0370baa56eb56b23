#!/bin/bash
# The `far` frames (sky and ground, about 1 ms) before/after (issue 14, session 12): for each round,
# size (320x180, 1280x720) and frame_bench binary BIN, alternately, one process on two threads draws
# a warm-up and 60 timed frames of synthetic `far`; prints "size binary fastest median" (seconds).
# Usage: abfar.sh ROUNDS BIN...
rounds=$1; shift
for r in $(seq $rounds); do for size in 320x180 1280x720; do for b in "$@"; do
  o=${TMPDIR:-/tmp}/abfar/$(basename $b); rm -rf $o
  $b --scene synthetic --camera far --width ${size%x*} --height ${size#*x} --threads 2 --reps 60 --out $o >/dev/null 2>&1
  t=$(tail -n60 $o/frame_bench.csv | cut -d, -f4 | sort -n)
  echo "$size $(basename $b) $(echo "$t" | head -1) $(echo "$t" | sed -n 30p)"
done; done; done
