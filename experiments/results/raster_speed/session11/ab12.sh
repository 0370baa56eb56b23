#!/bin/bash
# Reference before/after on the twelve frames of issue 14 (issue 14, session 11): for each frame
# (synthetic and stress; 320x180 and 1280x720; far, medium, close) and each frame_bench binary
# BIN, alternately, one process on two threads draws a warm-up frame and REPS timed frames; prints
# "scene size camera binary fastest median" (draw seconds).
# Usage: ab12.sh REPS BIN...   (e.g. ab12.sh 3 /tmp/fb_base /tmp/fb_new)
reps=$1; shift
for scene in synthetic stress; do for size in 320x180 1280x720; do for cam in far medium close; do
  for b in "$@"; do
    o=${TMPDIR:-/tmp}/ab12/$(basename $b); rm -rf $o
    $b --scene $scene --camera $cam --width ${size%x*} --height ${size#*x} --threads 2 --reps $reps --out $o >/dev/null 2>&1
    t=$(tail -n$reps $o/frame_bench.csv | cut -d, -f4 | sort -n)
    echo "$scene $size $cam $(basename $b) $(echo "$t" | head -1) $(echo "$t" | sed -n "$(( (reps + 1) / 2 ))p")"
  done
done; done; done
