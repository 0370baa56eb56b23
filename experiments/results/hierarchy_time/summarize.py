#!/usr/bin/env python3
"""Tables of experiments/results/hierarchy_time/README.md from draw_split's CSVs.

usage: summarize.py DIR   (DIR holds draw_split.csv and commands.csv)
"""
import csv
import sys
from pathlib import Path

d = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
rows = list(csv.DictReader(open(d / "draw_split.csv")))
ms = lambda v: f"{float(v) * 1e3:,.0f}"

for clock, name in (("cpu", "process CPU ms"), ("gpu", "timestamp ms")):
    print(f"\n### {name}\n")
    print("| scene | camera | variant | commands | mesh trees | billboard trees | indices (M) | select | refine | clear+ground | tree vertex | tree fragment | frame | vertex ns/index | frame: Veg / this |")
    print("|---|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|")
    veg = {(r["scene"], r["camera"]): float(r[f"frame_{clock}_s"]) for r in rows if r["variant"] == "vegetation"}
    for r in rows:
        f = float(r[f"frame_{clock}_s"])
        v = veg.get((r["scene"], r["camera"]))
        idx = int(r["indices"])
        vert = float(r[f"vertex_{clock}_s"])
        print(
            f"| {r['scene']} | {r['camera']} | {r['variant']} | {int(r['commands']):,} | {int(r['mesh_trees']):,} | {int(r['billboard_trees']):,} | {idx / 1e6:.1f} | "
            f"{ms(r[f'select_{clock}_s'])} | {ms(r[f'refine_{clock}_s'])} | {ms(r[f'ground_{clock}_s'])} | {ms(r[f'vertex_{clock}_s'])} | {ms(r[f'fragment_{clock}_s'])} | {ms(f)} | "
            f"{vert / max(idx, 1) * 1e9:.0f} | {'' if v is None else f'{v / f:.2f}x'} |"
        )
    leaks = [(r["variant"], r["no_trees_tree_pixels"], r["no_tree_fragments_tree_pixels"]) for r in rows]
print("\nprobe leaks (tree pixels of no_trees, no_tree_fragments):", sorted(set((a, b) for _, a, b in leaks)))

p = d / "commands.csv"
if p.exists():
    print("\n### Vegetation's visible trees in N commands\n")
    print("| scene | camera | most instances per command | commands | trees | tree vertex, CPU ms | tree vertex, timestamp ms | whole tree part, CPU ms |")
    print("|---|---|--:|--:|--:|--:|--:|--:|")
    series = list(csv.DictReader(open(p)))
    for r in series:
        v_cpu = float(r["no_tree_fragments_cpu_s"]) - float(r["no_trees_cpu_s"])
        v_gpu = float(r["no_tree_fragments_gpu_s"]) - float(r["no_trees_gpu_s"])
        full = float(r["full_cpu_s"]) - float(r["no_trees_cpu_s"])
        c = r["max_instances_per_command"]
        print(f"| {r['scene']} | {r['camera']} | {'all (one per mesh)' if c == '0' else c} | {int(r['commands']):,} | {int(r['trees']):,} | {v_cpu * 1e3:,.0f} | {v_gpu * 1e3:,.0f} | {full * 1e3:,.0f} |")
    by = {}
    for r in series:
        by.setdefault((r["scene"], r["camera"]), []).append(r)
    for k, rs in by.items():
        rs = sorted(rs, key=lambda r: int(r["commands"]))
        a, b = rs[0], rs[-1]
        dn = int(b["commands"]) - int(a["commands"])
        for clock in ("cpu", "gpu"):
            va = float(a[f"no_tree_fragments_{clock}_s"]) - float(a[f"no_trees_{clock}_s"])
            vb = float(b[f"no_tree_fragments_{clock}_s"]) - float(b[f"no_trees_{clock}_s"])
            print(f"\n{k}: per extra command ({clock}): {(vb - va) / max(dn, 1) * 1e6:.2f} us ({a['commands']} -> {b['commands']} commands)")
