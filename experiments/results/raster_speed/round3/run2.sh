#!/bin/bash
# gpu_bench synthetic 1280x720 --reps 3, before/after alternately (stress cut: time box under load).
set -u
B=/tmp/14r_before; A=/tmp/14r_after; O=/tmp/14r_meas
export XDG_RUNTIME_DIR=$(mktemp -d)
for build in before after; do
  if [ $build = before ]; then bin=$B/gpu_bench; else bin=$A/gpu_bench; fi
  echo "gpu_bench $build synthetic 1280x720 start $(date -u +%T) load: $(cut -d' ' -f1-3 /proc/loadavg)" >> $O/log.txt
  nice -n 10 $bin --scenes synthetic --sizes 1280x720 --reps 3 --out $O/gb_${build}_syn1280 > $O/gb_${build}_syn1280.log 2>&1
done
echo "gpu_bench end $(date -u +%T) load: $(cut -d' ' -f1-3 /proc/loadavg)" >> $O/log.txt
