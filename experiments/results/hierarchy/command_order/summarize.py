#!/usr/bin/env python3
"""Tables of experiments/results/hierarchy/command_order.md.

usage: summarize.py DIR...   (each DIR holds a draw_split.csv; a command_order_fragments.csv is
tabled too where present)
"""
import csv
import sys
from pathlib import Path

ms = lambda v: f"{float(v) * 1e3:,.0f}"
for d in map(Path, sys.argv[1:] or ["."]):
    p = d / "draw_split.csv"
    if p.exists():
        rows = list(csv.DictReader(open(p)))
        print(f"\n### {p} (process CPU ms; timestamp ms in brackets)\n")
        print("| camera | variant | commands | select | tree vertex | tree fragment | frame | frame: Veg / this |")
        print("|---|---|--:|--:|--:|--:|--:|--:|")
        veg = {r["camera"]: float(r["frame_cpu_s"]) for r in rows if r["variant"] == "vegetation"}
        for r in rows:
            f = float(r["frame_cpu_s"])
            v = veg.get(r["camera"])
            print(
                f"| {r['camera']} | {r['variant']} | {int(r['commands']):,} | {ms(r['select_cpu_s'])} ({ms(r['select_gpu_s'])}) | "
                f"{ms(r['vertex_cpu_s'])} ({ms(r['vertex_gpu_s'])}) | {ms(r['fragment_cpu_s'])} ({ms(r['fragment_gpu_s'])}) | "
                f"{ms(f)} ({ms(r['frame_gpu_s'])}) | {'' if v is None else f'{v / f:.2f}x'} |"
            )
    p = d / "command_order_fragments.csv"
    if p.exists():
        rows = list(csv.DictReader(open(p)))
        print(f"\n### {p}\n")
        print("| camera | hierarchy | commands | covered | shaded node | shaded front-to-back | ratio | written node | written front-to-back |")
        print("|---|---|--:|--:|--:|--:|--:|--:|--:|")
        by = {}
        for r in rows:
            by.setdefault((r["camera"], r["hierarchy"]), {})[r["command_order"]] = r
        for (cam, h), o in by.items():
            a, b = o["node"], o["front-to-back"]
            print(
                f"| {cam} | {h} | {int(a['commands']):,} | {int(a['fragments_covered']):,} | {int(a['fragments_shaded']):,} | "
                f"{int(b['fragments_shaded']):,} | {int(b['fragments_shaded']) / int(a['fragments_shaded']):.2f} | "
                f"{int(a['fragments_written']):,} | {int(b['fragments_written']):,} |"
            )
