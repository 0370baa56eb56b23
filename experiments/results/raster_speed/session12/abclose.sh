#!/bin/bash
# Reference before/after on one frame (issue 14, session 12): for each round and each frame_bench
# binary BIN, alternately, one process on two threads draws a warm-up frame and three timed frames;
# prints "scene size camera binary fastest median" (draw seconds).
# Usage: abclose.sh ROUNDS SCENE WxH CAMERA BIN...  (e.g. abclose.sh 3 synthetic 1280x720 close /tmp/fb_a /tmp/fb_b)
rounds=$1; scene=$2; size=$3; cam=$4; shift 4
for r in $(seq $rounds); do for b in "$@"; do
  o=${TMPDIR:-/tmp}/abc/$(basename $b); rm -rf $o
  $b --scene $scene --camera $cam --width ${size%x*} --height ${size#*x} --threads 2 --reps 3 --out $o >/dev/null 2>&1
  t=$(tail -n3 $o/frame_bench.csv | cut -d, -f4 | sort -n)
  echo "$scene $size $cam $(basename $b) $(echo "$t" | head -1) $(echo "$t" | sed -n 2p)"
done; done
