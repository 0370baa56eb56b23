#!/bin/bash
# idle A/B: main vs 14r, reference frame CPU and wall, alternating
out=/tmp/s8/ab14r.csv; echo "frame,bin,round,ref_frame_wall,ref_frame_cpu,user,sys,wall" > $out
frames=("close|render --no-gpu --camera close" "medium|render --no-gpu" "stress320|render --no-gpu --scene stress --width 320 --height 180")
for r in 1 2 3 4; do
 for f in "${frames[@]}"; do name=${f%%|*}; args=${f#*|}
  for b in main 14r; do
   [ $((r%2)) = 0 ] && b=$([ $b = main ] && echo 14r || echo main)
   d=$(mktemp -d); cd $d
   XDG_RUNTIME_DIR=$d /usr/bin/time -f "TIME %U %S %e" /tmp/s8/fl-$b $args --out o > log 2>&1
   w=$(grep -o "reference frame [0-9.]* s" log | head -1 | awk '{print $3}')
   c=$(grep "^cpu seconds" log | grep -o "reference frame [0-9.]*" | awk '{print $3}')
   t=$(grep ^TIME log | awk '{print $2","$3","$4}')
   echo "$name,$b,$r,$w,$c,$t" >> $out
   mkdir -p /tmp/s8/img/$name/$b; cp o/*.png /tmp/s8/img/$name/$b/ 2>/dev/null
   cd /; rm -rf $d
  done
 done
done
