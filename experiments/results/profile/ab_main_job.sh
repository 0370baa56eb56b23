#!/usr/bin/env bash
# Alternating A/B of the main job: before (7a2c793) and after (this branch), 3 runs each, empty folders.
set -u
out=/tmp/p7/m14/ab; mkdir -p $out
for i in 1 2 3; do
  for v in before after; do
    d=$out/$v-$i; rm -rf $d; mkdir -p $d; cd $d
    export XDG_RUNTIME_DIR=$(mktemp -d)
    load=$(cut -d' ' -f1-3 /proc/loadavg)
    /usr/bin/time -v /tmp/p7/m14/bin/forestlod-$v > run.log 2> time.log
    rc=$?
    wall=$(grep Elapsed time.log | awk '{print $NF}')
    user=$(grep "User time" time.log | awk '{print $NF}')
    sys=$(grep "System time" time.log | awk '{print $NF}')
    rss=$(grep "Maximum resident" time.log | awk '{print $NF}')
    same=yes; for f in color.png depth_preview.png lod.png atlas.png gpu_color.png gpu_lod.png parity_classes.png diff.png depth.exr; do cmp -s out/$f /tmp/p7/m14/runs/before0/out/$f || same=no; done
    echo "$v,$i,$load,$rc,$wall,$user,$sys,$rss,$same" >> $out/ab.csv
    grep -E "^phases" run.log | sed "s/^/$v-$i /" >> $out/phases.txt
    grep -E "^cpu seconds|^resident" run.log | sed "s/^/$v-$i /" >> $out/phases.txt
    grep -E "^GPU parity" run.log | sed "s/^/$v-$i /" >> $out/phases.txt
  done
done
