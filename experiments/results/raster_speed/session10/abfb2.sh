#!/bin/bash
# abfb.sh with the frame given as frame_bench arguments (issue 14, session 10): for each of
# ROUNDS rounds and each binary, one process, one thread, a warm-up and four timed frames;
# prints "binary round fastest-draw-seconds".
# Usage: abfb2.sh ROUNDS "FRAME_ARGS" BIN...
#   (e.g. abfb2.sh 3 "--scene stress --camera medium --width 320 --height 180" /tmp/fb_base /tmp/fb_new)
rounds=$1; args=$2; shift 2
for i in $(seq 1 $rounds); do for b in "$@"; do
  o=${TMPDIR:-/tmp}/abo2/$(basename $b)$i; rm -rf $o
  $b $args --threads 1 --reps 4 --out $o >/dev/null 2>&1
  echo "$(basename $b) $i $(tail -n4 $o/frame_bench.csv | cut -d, -f4 | sort -n | head -1)"
done; done
