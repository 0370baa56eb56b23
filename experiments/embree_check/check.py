#!/usr/bin/env python3
"""Cross-check obvhs ray hits against Embree (SPEC §10: "embreex cross-checks obvhs hits on the same
triangles").

Usage: check.py FILE

FILE is written by the Rust side (tests/tests/reference/embree_crosscheck.rs): every triangle of a scene as the
ground truth traces it, a set of rays, and obvhs's nearest hit for each (geometric query: no alpha
test, every triangle opaque and double-sided). This script loads the same triangles into Embree 4 (via
the embreex wheel), casts the same rays and compares.

File layout (little-endian):
    8 bytes   magic b"FLEMBRE1"
    u32       n_tri
    u32       n_ray
    f32       vertices[n_tri][3][3]
    f32       rays[n_ray][6]          origin xyz, direction xyz (not normalized)
    f32       tmax[n_ray]             rays start at t = 0
    f32       obvhs_t[n_ray]          +inf for a miss
    u32       obvhs_tri[n_ray]        0xFFFFFFFF for a miss

Verdict (exit 0 on pass, 1 on fail, 2 on bad input):
  * hit / miss must agree for every ray, and the distances of rays both hit must agree within
    T_REL_TOL * t + T_ABS_TOL;
  * except for **ambiguous** rays (SPEC §8): a ray whose hit point (on the triangle either side hit)
    lies within EDGE_EPS of that triangle's boundary in barycentric terms. There the two libraries'
    edge rules (ours: the watertight test of Woop, Benthin and Wald 2013, edges inclusive, in the
    ground truth's leaf callback; Embree: its own watertight test) may legitimately decide differently: the ray hits the neighbouring triangle at the same t,
    passes through a gap between two cards, or grazes a silhouette. Ambiguous rays are counted and
    must stay below MAX_AMBIGUOUS_FRACTION of all rays.
"""

import struct
import sys

import numpy as np

# Distances are f32 on both sides, from the same f32 inputs but by different formulas (ours: the
# sheared edge functions' t / det of the watertight test; Embree: its own variant), so they differ
# by rounding only: a few ulps of the intermediate products, which scale with the coordinates (the
# ground grid spans kilometres) and with 1 / |cos| of the hit angle. 2e-5 relative is ~170 ulps of
# f32 at t; on `tiny` the worst ray uses about 9 % of the tolerance (2 % before the watertight
# test: both libraries stay within 1.3 mm of the exact f64 distance; the test prints it), so a real
# disagreement (another triangle, a hit through a gap) cannot hide in it: trees are metres apart.
T_REL_TOL = 2e-5
# Absolute floor for hits very near the origin (metres): 0.1 mm.
T_ABS_TOL = 1e-4
# Barycentric distance to a triangle's edge under which a hit is ambiguous: the f32 rounding of
# the barycentrics themselves is ~1e-7 relative to the triangle; 1e-5 is a hundredfold margin.
EDGE_EPS = 1e-5
# At most this fraction of rays may be ambiguous (it is a property of the scene: crossed cards
# and shared edges; more would mean the rays were aimed at edges or the check is broken).
MAX_AMBIGUOUS_FRACTION = 0.01

MISS = 0xFFFFFFFF


def load(path):
    data = open(path, "rb").read()
    if data[:8] != b"FLEMBRE1":
        raise ValueError(f"{path}: not a forestlod Embree cross-check file (magic {data[:8]!r})")
    n_tri, n_ray = struct.unpack_from("<II", data, 8)
    off = 16
    need = off + 4 * (n_tri * 9 + n_ray * 6 + n_ray * 3)
    if len(data) != need:
        raise ValueError(f"{path}: {len(data)} bytes, expected {need} for {n_tri} triangles and {n_ray} rays")

    def take(dtype, count):
        nonlocal off
        a = np.frombuffer(data, dtype=dtype, count=count, offset=off).copy()
        off += 4 * count
        return a

    tris = take("<f4", n_tri * 9).reshape(n_tri, 3, 3)
    rays = take("<f4", n_ray * 6).reshape(n_ray, 6)
    tmax = take("<f4", n_ray)
    t_ob = take("<f4", n_ray)
    id_ob = take("<u4", n_ray)
    return tris, rays, tmax, t_ob, id_ob


def barycentric_margin(tris, tri_ids, origins, dirs, t):
    """Smallest barycentric coordinate (f64) of the hit point on each given triangle: < 0 outside,
    near 0 on an edge."""
    v = tris[tri_ids].astype(np.float64)
    p = origins.astype(np.float64) + dirs.astype(np.float64) * t.astype(np.float64)[:, None]
    v0, v1, v2 = v[:, 0], v[:, 1], v[:, 2]
    e1, e2, ep = v1 - v0, v2 - v0, p - v0
    d11 = np.einsum("ij,ij->i", e1, e1)
    d12 = np.einsum("ij,ij->i", e1, e2)
    d22 = np.einsum("ij,ij->i", e2, e2)
    dp1 = np.einsum("ij,ij->i", ep, e1)
    dp2 = np.einsum("ij,ij->i", ep, e2)
    den = d11 * d22 - d12 * d12
    den = np.where(den == 0.0, 1e-300, den)
    b1 = (d22 * dp1 - d12 * dp2) / den
    b2 = (d11 * dp2 - d12 * dp1) / den
    return np.minimum(np.minimum(b1, b2), 1.0 - b1 - b2)


def main(argv):
    if len(argv) != 2:
        print(__doc__)
        return 2
    try:
        tris, rays, tmax, t_ob, id_ob = load(argv[1])
    except (OSError, ValueError) as e:
        print(f"error: {e}")
        return 2
    try:
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh
    except ImportError as e:
        print(f"error: embreex is not importable ({e}); install it with `python3 -m pip install embreex numpy`")
        return 2

    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, np.ascontiguousarray(tris, dtype=np.float32))
    origins = np.ascontiguousarray(rays[:, :3], dtype=np.float32)
    dirs = np.ascontiguousarray(rays[:, 3:], dtype=np.float32)
    res = scene.run(origins, dirs, dists=np.ascontiguousarray(tmax, dtype=np.float32), output=1)
    id_em = res["primID"].astype(np.int64)
    t_em = res["tfar"].astype(np.float64)
    hit_em = id_em >= 0
    hit_ob = id_ob != MISS
    n = len(rays)

    # Ambiguity: the hit point on the triangle either side hit is within EDGE_EPS of its edge.
    ambiguous = np.zeros(n, dtype=bool)
    if hit_ob.any():
        idx = np.nonzero(hit_ob)[0]
        m = barycentric_margin(tris, id_ob[idx].astype(np.int64), origins[idx], dirs[idx], t_ob[idx])
        ambiguous[idx] |= m < EDGE_EPS
    if hit_em.any():
        idx = np.nonzero(hit_em)[0]
        m = barycentric_margin(tris, id_em[idx], origins[idx], dirs[idx], t_em[idx])
        ambiguous[idx] |= m < EDGE_EPS

    both = hit_em & hit_ob
    dt = np.zeros(n)
    dt[both] = np.abs(t_em[both] - t_ob[both].astype(np.float64))
    tol = T_REL_TOL * np.maximum(t_em, 0.0) + T_ABS_TOL
    hit_disagree = hit_em != hit_ob
    t_disagree = both & (dt > tol)
    bad = (hit_disagree | t_disagree) & ~ambiguous
    amb_disagree = (hit_disagree | t_disagree) & ambiguous
    rel = np.zeros(n)
    rel[both] = dt[both] / np.maximum(t_em[both], 1e-30)
    same_tri = both & (id_em == id_ob.astype(np.int64))
    clean = both & ~ambiguous

    print(f"embree cross-check of {argv[1]}")
    print(f"  triangles {len(tris)}, rays {n}")
    print(f"  hits: obvhs {int(hit_ob.sum())}, embree {int(hit_em.sum())}, both {int(both.sum())}, "
          f"same triangle {int(same_tri.sum())}")
    print(f"  hit/miss agreement: {n - int(hit_disagree.sum())}/{n} rays")
    print(f"  distance |dt| over rays both hit: max {dt[both].max() if both.any() else 0.0:.3e} m, "
          f"max relative {rel[both].max() if both.any() else 0.0:.3e}; "
          f"non-ambiguous max {dt[clean].max() if clean.any() else 0.0:.3e} m "
          f"(tolerance {T_REL_TOL:g}·t + {T_ABS_TOL:g} m)")
    print(f"  ambiguous rays (hit within {EDGE_EPS:g} barycentric of an edge): {int(ambiguous.sum())}, "
          f"of which disagreeing {int(amb_disagree.sum())}")
    if both.any():
        print(f"  worst |dt| / tolerance: {float((dt[both] / tol[both]).max()):.4f}")
    print(f"  disagreements outside the ambiguous set: {int(bad.sum())}")
    for i in np.nonzero(bad)[0][:10]:
        print(f"    ray {i}: obvhs t={t_ob[i]} tri={int(id_ob[i]) if hit_ob[i] else None}, "
              f"embree t={t_em[i]} tri={int(id_em[i]) if hit_em[i] else None}")
    ok = not bad.any() and ambiguous.sum() <= MAX_AMBIGUOUS_FRACTION * n
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
