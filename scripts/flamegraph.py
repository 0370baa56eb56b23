#!/usr/bin/env python3
"""Folded stacks (`frame;frame;... count` per line, as perf's stackcollapse.py writes them) to a
static SVG flame graph: root at the bottom, each frame as wide as its share of the samples.
Development tool for issue 14's profiles (scripts/profile-main-job); nothing else uses it.

usage: flamegraph.py FOLDED TITLE > OUT.svg
"""
import html
import sys
import zlib

ROW = 16
WIDTH = 1600
MIN_PX = 2.0  # frames narrower than this (pixels) are not drawn


def main():
    folded, title = sys.argv[1], sys.argv[2]
    root = {"children": {}, "count": 0}
    for line in open(folded, encoding="utf-8", errors="replace"):
        stack, _, count = line.rstrip("\n").rpartition(" ")
        if not stack or not count.isdigit():
            continue
        n = int(count)
        node = root
        node["count"] += n
        for frame in stack.split(";"):
            node = node["children"].setdefault(frame, {"children": {}, "count": 0})
            node["count"] += n
    total = max(root["count"], 1)
    rects = []
    depth_max = 0

    def walk(node, x, depth):
        nonlocal depth_max
        for name, child in sorted(node["children"].items()):
            w = child["count"] / total * WIDTH
            if w >= MIN_PX:
                rects.append((x, depth, w, name, child["count"]))
                depth_max = max(depth_max, depth)
                walk(child, x, depth + 1)
            x += w

    walk(root, 0.0, 0)
    height = (depth_max + 3) * ROW
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{height}" '
        f'font-family="monospace" font-size="11">',
        f'<rect width="100%" height="100%" fill="#fdfdf8"/>',
        f'<text x="4" y="13">{html.escape(title)} ({total} samples; width = share of samples, '
        f"hover for the frame)</text>",
    ]
    for x, depth, w, name, count in rects:
        y = height - (depth + 1) * ROW
        h = zlib.crc32(name.encode())
        color = f"rgb({205 + h % 50},{90 + (h >> 8) % 110},{40 + (h >> 16) % 50})"
        label = html.escape(name if len(name) <= 300 else name[:297] + "...")
        pct = 100.0 * count / total
        out.append(
            f'<g><title>{label} ({count} samples, {pct:.1f}%)</title>'
            f'<rect x="{x:.1f}" y="{y}" width="{w:.1f}" height="{ROW - 1}" fill="{color}"/>'
        )
        chars = int(w / 6.6)
        if chars >= 3:
            text = name if len(name) <= chars else name[: chars - 2] + ".."
            out.append(f'<text x="{x + 2:.1f}" y="{y + 11}">{html.escape(text)}</text>')
        out.append("</g>")
    out.append("</svg>")
    print("\n".join(out))


if __name__ == "__main__":
    main()
