#!/usr/bin/env python3
"""Tables of hierarchy_paths/README.md from a hierarchy_paths.csv: per pose and hierarchy the
work counters, times, memory beside E Eq. 4.1 and accuracy, and whether every accuracy figure
equals the grid's on the same pose and backend. usage: summarize.py CSV [CSV...]"""
import csv
import sys

rows = [r for p in sys.argv[1:] for r in csv.DictReader(open(p))]
acc = ["flip_mean", "flip_p99", "coverage_error", "lod_flip_mean", "lod_changed"]
pose = lambda r: (r["scene"], r["backend"], r["camera"], r["yaw_deg"], r["distance_m"])
grid = {pose(r): r for r in rows if r["hierarchy"] == "grid" and r["variant"] == "ours"}
# Vegetation does not read `hierarchy`: the sweep repeats it once per axis value; keep the first.
seen = set()
rows = [r for r in rows if r["variant"] == "ours" or (pose(r) not in seen and not seen.add(pose(r)))]
print("| scene | backend | camera | yaw / distance | variant | nodes visited | commands | trees drawn | trees_outside_view | select ms | GPU select ms (timestamps) | frame s | memory MB | FLIP mean | LOD FLIP mean | accuracy = grid's |")
print("|---|---|---|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|---|")
same_all = True
for r in rows:
    g = grid.get(pose(r))
    veg = r["variant"] != "ours"
    same = g is not None and all(r[k] == g[k] for k in acc)
    same_all &= same or veg
    where = r["yaw_deg"] if r["camera"] == "close" else r["distance_m"]
    gs = r["gpu_select_s"]
    print(
        f"| {r['scene']} | {r['backend']} | {r['camera']} | {float(where):g} | {'Vegetation' if veg else r['hierarchy']} | {int(r['batches_tested']):,} | {int(r['commands']):,} | {int(r['trees_drawn']):,} | {int(r['trees_outside_view']):,} | "
        f"{float(r['select_s']) * 1e3:.1f} | {'' if gs == '' else f'{float(gs) * 1e3:.1f}'} | {float(r['frame_s']):.2f} | {int(r['memory_bytes']) / 1e6:.2f} | {float(r['flip_mean']):.4f} | {float(r['lod_flip_mean']):.4f} | {'(baseline)' if veg else 'yes' if same else 'NO'} |"
    )
print(f"\nevery row's accuracy ({', '.join(acc)}) equals the grid's on the same pose (ours only): {same_all}")
