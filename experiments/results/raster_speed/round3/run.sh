#!/bin/bash
# Before/after alternately: gpu_bench --reps 3 and CPU of render --no-gpu.
set -u
B=/tmp/14r_before; A=/tmp/14r_after; O=/tmp/14r_meas
export XDG_RUNTIME_DIR=$(mktemp -d)
echo "start $(date -u +%T) load: $(cut -d' ' -f1-3 /proc/loadavg)" >> $O/log.txt
# CPU: reference alone, whole process, alternately
echo "build,frame,user_s,sys_s,wall_s,load1" > $O/cpu_alternating.csv
for round in 1 2; do
  for frame in "synthetic far" "synthetic close" "stress medium" "stress far"; do
    set -- $frame
    for build in before after; do
      if [ $build = before ]; then bin=$B/forestlod; else bin=$A/forestlod; fi
      d=$(mktemp -d)
      /usr/bin/time -f "%U,%S,%e" -o $d/t nice -n 10 $bin render --no-gpu --scene $1 --camera $2 --out $d/o > $d/log 2>&1
      echo "$build,$1 $2 1280x720 r$round,$(cat $d/t),$(cut -d' ' -f1 /proc/loadavg)" >> $O/cpu_alternating.csv
      mkdir -p $O/img/$build/$1_$2; cp $d/o/*.png $d/o/depth.exr $O/img/$build/$1_$2/ 2>/dev/null
      rm -rf $d
    done
  done
done
echo "cpu done $(date -u +%T) load: $(cut -d' ' -f1-3 /proc/loadavg)" >> $O/log.txt
for size in 1280x720 320x180; do
  for build in before after; do
    if [ $build = before ]; then bin=$B/gpu_bench; else bin=$A/gpu_bench; fi
    echo "gpu_bench $build $size start $(date -u +%T) load: $(cut -d' ' -f1-3 /proc/loadavg)" >> $O/log.txt
    nice -n 10 $bin --scenes synthetic,stress --sizes $size --reps 3 --out $O/gb_${build}_$size > $O/gb_${build}_$size.log 2>&1
  done
done
echo "end $(date -u +%T) load: $(cut -d' ' -f1-3 /proc/loadavg)" >> $O/log.txt
