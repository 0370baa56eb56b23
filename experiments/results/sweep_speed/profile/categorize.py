#!/usr/bin/env python3
"""Flat perf profile (no call stacks: the release binary has no frame pointers or debug info) to
folded stacks `category;dso;symbol count` for scripts/flamegraph.py, and a category table on
stderr. Categories by symbol name only, so they are approximate: anonymous closures
(`core::ops::function::impls...call_mut`) and libm/libc functions are shared by the truth
tracer, the rasterizer and FLIP and are kept in their own rows, not guessed.

usage: perf report -i DATA --no-children --sort dso,symbol --stdio -n -g none \
           | categorize.py > FOLDED
"""
import re
import sys

RULES = [
    ("ground truth: BVH build", r"obvhs::(ploc|bvh2|cwbvh::bvh2_to_cwbvh|cwbvh::builder)|reinsertion|PlocBuilder"),
    ("ground truth: tracing", r"ground_truth::|obvhs::"),
    ("texture sampling (truth alpha test and rasterizer)", r"sampler::|decode_texel"),
    ("reference rasterizer and selection", r"forestlod_reference::(raster|draw|select|baselines|refine|pipeline|cull|hierarchy)|FragmentShader|vertex_stage|setup_triangle"),
    ("scene, prepare, bake", r"forestlod_reference::(scene|mips|bake|texture|billboard)|forestlod_shared::"),
    ("FLIP (nv_flip)", r"FLIP::|flip_"),
    ("PNG encoding", r"png::|miniz|fdeflate|crc32|adler|deflate"),
    ("GPU driver (lavapipe / llvmpipe)", r"lvp_|llvmpipe|lp_|libvulkan|libLLVM|gallivm|vk"),
    ("anonymous closures (truth, raster, metrics)", r"core::ops::function::impls|Map<I,F>|Folder::consume_iter|bridge_producer"),
    ("libm (powf, sincos, ... shared)", r"^libm"),
    ("allocation and copies (libc, kernel)", r"^libc|\[kernel"),
]


def main():
    cats = {}
    for line in sys.stdin:
        m = re.match(r"\s+([0-9.]+)%\s+(\d+)\s+(\S+)\s+\[[.k]\]\s+(.*?)\s*$", line)
        if not m:
            continue
        n, dso, sym = int(m.group(2)), m.group(3), m.group(4).rstrip(" -").strip()
        key = f"{dso} {sym}"
        cat = next((c for c, pat in RULES if re.search(pat, key) or re.search(pat, sym)), "other")
        cats[cat] = cats.get(cat, 0) + n
        sym = sym.replace(";", ":").replace(" ", "_")
        print(f"{cat};{dso};{sym} {n}")
    total = sum(cats.values()) or 1
    for c, n in sorted(cats.items(), key=lambda kv: -kv[1]):
        print(f"{100 * n / total:5.1f}%  {n:6d}  {c}", file=sys.stderr)


main()
