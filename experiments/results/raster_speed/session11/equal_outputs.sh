#!/bin/bash
# Issue 14, session 11: every output of `forestlod render --no-gpu` of six frames byte-identical between two builds (cmp), and every integer counter of metrics.json equal.
# Usage: equal_outputs.sh BIN_A BIN_B (forestlod binaries): render --no-gpu several frames with both, cmp every output image and metrics counters
A=$1; B=$2; ok=0; export W=${TMPDIR:-/tmp}
for spec in "synthetic far 1280 720" "synthetic medium 1280 720" "synthetic close 1280 720" "stress medium 640 360" "stress close 320 180" "synthetic medium 320 180"; do
  set -- $spec
  for bin in A B; do eval exe=\$$bin; rm -rf ${TMPDIR:-/tmp}/eq_$bin; $exe render --scene $1 --camera $2 --width $3 --height $4 --no-gpu --out ${TMPDIR:-/tmp}/eq_$bin >${TMPDIR:-/tmp}/eq_$bin.log 2>&1 || echo "FAIL $bin $spec"; done
  for f in color.png depth_preview.png lod.png depth.exr; do cmp -s ${TMPDIR:-/tmp}/eq_A/$f ${TMPDIR:-/tmp}/eq_B/$f || { echo "DIFF $spec $f"; ok=1; }; done
  python3 - <<'PY' || ok=1
import json,os,sys
a=json.load(open(os.environ['W']+'/eq_A/metrics.json')); b=json.load(open(os.environ['W']+'/eq_B/metrics.json'))
def walk(x,y,p=''):
    bad=0
    if isinstance(x,dict):
        for k in x:
            if any(t in k for t in ('_s','time','seconds','memory_mb','resident','cpu','wall','phases','peak')): continue
            bad+=walk(x[k],y.get(k) if isinstance(y,dict) else None,p+'.'+k)
    elif x!=y and not isinstance(x,float):
        print('counter differs',p,x,y); bad+=1
    return bad
sys.exit(1 if walk(a,b) else 0)
PY
  echo "done $spec"
done
exit $ok
