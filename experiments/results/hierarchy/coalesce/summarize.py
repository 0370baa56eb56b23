"""Tables of experiments/results/hierarchy/coalesce.md from the coalesce sweep's CSV.

python3 experiments/results/hierarchy/coalesce/summarize.py experiments/results/hierarchy/coalesce/coalesce.csv
"""
import collections
import csv
import sys

rows = list(csv.DictReader(open(sys.argv[1])))
g = collections.defaultdict(list)
for r in rows:
    g[(r["camera"], r["hierarchy"], r["coalesce"], r["variant"])].append(r)


def one(key, col):
    rs = g.get(key, [])
    v = [float(r[col]) for r in rs if r[col] not in ("", None)]
    return sum(v) / len(v) if v else float("nan")


print("| camera | hierarchy | coalesce | commands | trees drawn | ours frame s | ours GPU draw s | Vegetation frame s (same set) | Vegetation / ours | FLIP |")
print("|---|---|---|--:|--:|--:|--:|--:|--:|--:|")
for cam in sorted({k[0] for k in g}):
    for h in sorted({k[1] for k in g}):
        for c in ["off", "on"]:
            o, v = (cam, h, c, "ours"), (cam, h, c, "vegetation")
            if o not in g:
                continue
            fo, fv = one(o, "frame_s"), one(v, "frame_s")
            print(
                f"| {cam} | {h} | {c} | {one(o, 'commands'):.0f} | {one(o, 'trees_drawn'):.0f} | {fo:.2f} | {one(o, 'gpu_draw_s'):.2f} | {fv:.2f} | {fv / fo:.2f}x | {one(o, 'flip_mean'):.4f} |"
            )
print()
print("| camera | hierarchy | commands off -> on | ours frame on / off | (Vegetation/ours) on / off |")
print("|---|---|--:|--:|--:|")
for cam in sorted({k[0] for k in g}):
    for h in sorted({k[1] for k in g}):
        off, on = (cam, h, "off", "ours"), (cam, h, "on", "ours")
        if off not in g or on not in g:
            continue
        r_off = one((cam, h, "off", "vegetation"), "frame_s") / one(off, "frame_s")
        r_on = one((cam, h, "on", "vegetation"), "frame_s") / one(on, "frame_s")
        print(
            f"| {cam} | {h} | {one(off, 'commands'):.0f} -> {one(on, 'commands'):.0f} | {one(on, 'frame_s') / one(off, 'frame_s'):.2f} | {r_on / r_off:.2f} |"
        )
