#!/usr/bin/env python3
"""Table of the close ring's selection counters (reference backend, `forestlod select`) from
select_close_ring.log (written by select_close_ring.sh). usage: select_ring.py LOG > CSV + table"""
import re
import sys
from collections import defaultdict

text = open(sys.argv[1] if len(sys.argv) > 1 else "select_close_ring.log").read()
rows = []
for block in text.split("=== ")[1:]:
    head, body = block.split("\n", 1)
    scene, h, yaw = head.split()
    num = lambda pat: int(re.search(pat, body).group(1))
    nodes = re.search(r"hierarchy \S+: (\d+) nodes, (\d+) leaves", body)
    rows.append(dict(
        scene=scene, hierarchy=h, yaw=int(yaw),
        nodes=int(nodes.group(1)) if nodes else 0,
        leaves=int(nodes.group(2)) if nodes else num(r"trees, (\d+) batches"),
        visited=num(r"batches tested (\d+)"),
        commands=num(r"commands (\d+)"),
        drawn=num(r"tree instances drawn (\d+)"),
        need0=num(r"(\d+) trees need LOD0"),
        need1=num(r"(\d+) need LOD1"),
        grouped_ms=float(re.search(r"grouped ([\d.]+) ms", body).group(1)),
        per_tree_ms=float(re.search(r"per-tree ([\d.]+) ms", body).group(1)),
    ))
with open("select_close_ring.csv", "w") as f:
    keys = list(rows[0])
    f.write(",".join(keys) + "\n")
    for r in rows:
        f.write(",".join(str(r[k]) for k in keys) + "\n")
agg = defaultdict(list)
for r in rows:
    agg[(r["scene"], r["hierarchy"])].append(r)
print("| scene | hierarchy | nodes (leaves) | nodes visited | commands | tree instances drawn | oracle (LOD0 + LOD1) | drawn / oracle | select ms (reference, one-shot, median) | per-tree cull ms (median) |")
print("|---|---|--:|--:|--:|--:|--:|--:|--:|--:|")
med = lambda v: sorted(v)[len(v) // 2]
for (s, h), rs in agg.items():
    m = lambda k: sum(r[k] for r in rs) / len(rs)
    oracle = m("need0") + m("need1")
    print(f"| {s} | {h} | {rs[0]['nodes']:,} ({rs[0]['leaves']:,}) | {m('visited'):,.0f} | {m('commands'):,.0f} | {m('drawn'):,.0f} | {oracle:,.0f} | {m('drawn') / oracle:.2f}x | {med([r['grouped_ms'] for r in rs]):.1f} | {med([r['per_tree_ms'] for r in rs]):.0f} |")
