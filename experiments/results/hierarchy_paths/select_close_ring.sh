#!/bin/bash
cd /work/wt13b
for s in stress patchy; do for h in grid quadtree octree; do for y in 0 90 180 270; do
  echo "=== $s $h $y"
  nice -n 10 target/debug/forestlod select --scene $s --hierarchy $h --camera close --yaw $y --list 0 2>&1 | grep -v "^  \["
done; done; done
