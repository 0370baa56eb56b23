#!/bin/bash
# Alternating A/B of the reference frame with `frame_bench` (issue 14, session 10): for each of
# ROUNDS rounds, each camera of CAMERAS (comma-separated) and each frame_bench binary BIN, one
# process draws the synthetic 1280x720 frame on one thread, a warm-up and then four timed frames;
# prints "binary camera round fastest-draw-seconds".
# Usage: abfb.sh ROUNDS CAMERAS BIN...   (e.g. abfb.sh 4 close,medium /tmp/fb_base /tmp/fb_v2)
rounds=$1; cams=$2; shift 2
for i in $(seq 1 $rounds); do for c in ${cams//,/ }; do for b in "$@"; do
  o=${TMPDIR:-/tmp}/abo/$(basename $b)$c$i; rm -rf $o
  $b --camera $c --threads 1 --reps 4 --out $o >/dev/null 2>&1
  echo "$(basename $b) $c $i $(tail -n4 $o/frame_bench.csv | cut -d, -f4 | sort -n | head -1)"
done; done; done
