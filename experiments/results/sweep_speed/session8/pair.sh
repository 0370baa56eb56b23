#!/usr/bin/env bash
# pair.sh OUT OLDBIN NEWBIN sweep...   (runs both binaries on the "new" toml of sweep_speed, alternately; writes runs.csv like sweep-suite-time)
set -u
out=$1; old=$2; new=$3; shift 3
T=/work/wt14t/experiments/results/sweep_speed/toml/new
mkdir -p $out/toml/old $out/toml/new
csv=$out/runs.csv
[[ -f $csv ]] || echo "sweep,binary,order,exit,wall_s,user_s,sys_s,cpu_s,max_rss_mb,load1_before,load1_after,frames,sweep_wall_s,started_utc,extra_args" > $csv
export XDG_RUNTIME_DIR=$(mktemp -d)
for s in "$@"; do
  name=${s%%:*}; extra=${s#*:}; [[ $extra == $s ]] && extra=
  cp $T/$name.toml $out/toml/old/; cp $T/$name.toml $out/toml/new/
  for which in old new; do
    bin=$old; [[ $which == new ]] && bin=$new
    d=$out/runs/$name/$which; rm -rf $d; mkdir -p $d
    lb=$(cut -d' ' -f1 /proc/loadavg)
    nice -n 10 /usr/bin/time -v -o $d/time.txt $bin sweep $T/$name.toml $extra --out $d/out > $d/stdout.txt 2> $d/stderr.txt; rc=$?
    f() { grep -F "$1" $d/time.txt | head -1 | awk -F': ' '{print $2}'; }
    u=$(f "User time (seconds)"); sy=$(f "System time (seconds)"); r=$(f "Maximum resident set size (kbytes)")
    w=$(f "Elapsed (wall clock) time" | awk -F: '{ if (NF == 3) print $1 * 3600 + $2 * 60 + $3; else print $1 * 60 + $2 }')
    echo "$name,$which,0,$rc,$w,$u,$sy,$(awk "BEGIN{printf \"%.2f\", $u+$sy}"),$(awk "BEGIN{printf \"%.1f\", $r/1024}"),$lb,$(cut -d' ' -f1 /proc/loadavg),,,$(date -u +%FT%TZ),$extra" >> $csv
    echo "$name $which rc=$rc cpu=$(awk "BEGIN{printf \"%.2f\", $u+$sy}") wall=$w"
  done
done
