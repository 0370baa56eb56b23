#!/usr/bin/env bash
# Alternating A/B of the main job (issue 14, session 8): BEFORE and AFTER release binaries of
# `forestlod` (no arguments), RUNS runs each (default 3), each in an empty folder under OUT with
# its own XDG_RUNTIME_DIR, under `/usr/bin/time -v`. Writes OUT/ab.csv (variant, run, load
# average at the start, exit code, wall, user, sys, peak RSS KiB, whether the nine images equal
# the first BEFORE run's byte for byte) and OUT/phases.txt (the summary's phase, CPU and memory
# lines). Usage: ab_main_job_s8.sh BEFORE_BIN AFTER_BIN [OUT] [RUNS]
set -u
before=$1; after=$2; out=${3:-/tmp/ab_main_job}; runs=${4:-3}
mkdir -p "$out"
images="color.png depth_preview.png lod.png atlas.png gpu_color.png gpu_lod.png parity_classes.png diff.png depth.exr"
echo "variant,run,load1,load5,load15,rc,wall,user_s,sys_s,max_rss_kib,images_equal" > "$out/ab.csv"
: > "$out/phases.txt"
for i in $(seq 1 "$runs"); do
  for v in before after; do
    if [ $v = before ]; then bin=$before; else bin=$after; fi
    d=$out/$v-$i; rm -rf "$d"; mkdir -p "$d"
    load=$(cut -d' ' -f1-3 /proc/loadavg | tr ' ' ',')
    (cd "$d" && XDG_RUNTIME_DIR=$(mktemp -d) /usr/bin/time -v "$bin" > run.log 2> time.log)
    rc=$?
    wall=$(grep Elapsed "$d/time.log" | awk '{print $NF}')
    user=$(grep "User time" "$d/time.log" | awk '{print $NF}')
    sys=$(grep "System time" "$d/time.log" | awk '{print $NF}')
    rss=$(grep "Maximum resident" "$d/time.log" | awk '{print $NF}')
    same=yes
    for f in $images; do cmp -s "$d/out/$f" "$out/before-1/out/$f" || same=no; done
    echo "$v,$i,$load,$rc,$wall,$user,$sys,$rss,$same" >> "$out/ab.csv"
    grep -E "^phases|^cpu seconds|^resident|^GPU parity" "$d/run.log" | sed "s/^/$v-$i /" >> "$out/phases.txt"
  done
done
cat "$out/ab.csv"
