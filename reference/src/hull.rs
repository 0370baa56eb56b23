//! The geometry of Eichner's batch hull (E§7, issue 32 item 4): "another type of LOD that turns
//! an entire batch into a single opaque ultra-low-polygon-count mesh, of similar shape to the
//! convex hull of the batch". The colours, the cut and the draw are `forestlod_shared::far`'s.
//!
//! ## Contract
//! [`batch_hull`] takes the batch's trees as boxes (centre, half-size, world space; [`tree_box`]
//! makes one from a tree the way the draw places its mesh) and returns a triangle list that is
//! - **closed and convex**: every edge is shared by exactly two triangles, in opposite
//!   directions; every triangle winds counter-clockwise seen from outside (its normal points
//!   out, the signed volume is positive); every vertex lies behind every face's plane;
//! - **conservative**: every box corner lies inside, so the hull never cuts a tree; every plane
//!   of it stands [`MARGIN_EPS`]` · max(|coordinate|, 1 m)` outside the corners, which covers
//!   rounding the vertices to `f32`;
//! - **small**: at most [`MAX_HULL_TRIANGLES`] triangles (the far level's command encoding,
//!   `forestlod_shared::far`), fewer with a smaller budget ([`build_hull`]);
//! - **deterministic**: one thread, `f64` arithmetic in a fixed order, no hashing order (the
//!   quickhull crate hashes with a fixed seed); the same boxes give the same bits.
//!
//! ## The construction: greedy plane selection
//! The exact hull of the box corners is too rich: on a realistic batch it has far more than 84
//! triangles (module tests' table, `measure_realistic_batches`). So the hull is an
//! **intersection of supporting half-spaces** `n · p ≤ max_corners n · p + margin`, which
//! contains every corner whatever the chosen directions `n` are; only the choice of `n` decides
//! how tight it is:
//! 1. start from the box of all corners (six planes, twelve triangles: one box gives exactly
//!    that box);
//! 2. candidates: the face normals of the exact hull of the corners (the quickhull crate, in
//!    `f32` on coordinates relative to the batch's centre: the crate only proposes directions;
//!    every support is recomputed in `f64` over the boxes, so its rounding never costs
//!    containment) and the 26-DOP's directions (the 12 edge and 8 corner diagonals), which
//!    stand in where the crate declines (flat or degenerate corner sets);
//! 3. repeatedly cut with the candidate whose plane lies deepest inside the current polytope
//!    (the largest `max_vertices n · v − support`), clipping the polytope; a cut that would
//!    exceed the triangle budget, or whose rounding to `f32` would merge two vertices, is
//!    skipped; stop when no candidate cuts deeper than [`MIN_CUT_REL`] of the batch's size.
//!
//! Each step removes the polytope's worst excess over the exact hull (a one-sided Hausdorff
//! distance), so the budget goes where the silhouette is worst: on a slope the tilted top is
//! one plane of the exact hull that no fixed direction set has; on a few trees the greedy ends
//! at the exact hull itself. A triangle list from polygons of `k` vertices has
//! `Σ (k − 2) = 2V − 4` triangles, so the budget is a budget of vertices (≤ 44).
//!
//! Rejected: a fixed k-DOP (the intersection of the half-spaces of a fixed set of directions):
//! the 26-DOP can reach 92 triangles (`4F − 12` for 26 faces), the 18-DOP keeps under the
//! budget but measured looser than the greedy on every batch of the table below, and no fixed
//! set fits a slope. Also rejected: simplifying the exact hull's mesh (edge collapses) loses
//! containment unless each collapse is checked against every corner.
//!
//! Measured (`cargo test -p forestlod-reference --release hull::tests::measure -- --ignored
//! --nocapture`): see [`tests`]' `measure_realistic_batches` and the report's table (volume over
//! the exact hull's, triangles).
//!
//! ## Cost
//! Validation and supports `O(n · C)` for `n` boxes and `C` candidates (the exact hull's faces,
//! usually a few hundred; quickhull is `O(n log n)` on the `8n` corners); the greedy
//! `O(C² · V)` with `V ≤ 44` polytope vertices: a 10⁴-tree batch takes about 0.1 s in release
//! (module test `ten_thousand_trees_are_fast`).
//!
//! ## Numerics
//! Coordinates are taken relative to the centre of the corners' box in `f64` (1e5 m offsets keep
//! their precision); the clip keeps a vertex within a quarter of the smallest cut of a new plane
//! on the polytope instead of making a sliver beside it (it stays outside or on the plane's
//! tolerance band, so containment never suffers); a clip whose topology would not close
//! (numerically impossible cap) is skipped.

use std::collections::{BTreeMap, BTreeSet};

use forestlod_shared::{MAX_HULL_TRIANGLES, MeshMeta};
use glam::DVec3;
use glam_quickhull::Vec3A;

use crate::scene::Instance;

/// A box: centre and half-size (every component `≥ 0`), world space.
pub type HullBox = ([f32; 3], [f32; 3]);

/// A triangle: three positions, counter-clockwise seen from outside.
pub type Triangle = [[f32; 3]; 3];

/// Every plane of the hull stands this many times `max(|coordinate|, 1 m)` outside the corners:
/// four `f32` epsilons, so rounding a vertex to `f32` (half an ulp per coordinate, at most
/// `0.87 ε |x|` away) leaves every corner inside.
pub const MARGIN_EPS: f64 = 4.0 * f32::EPSILON as f64;

/// A cut must reach this fraction of the batch's size (the diagonal of the corners' box) into
/// the polytope: a shallower cut moves the silhouette by under a pixel wherever the batch is far
/// (a far node covers fewer than `far_pixels` pixels, well under 1000 across), and would make
/// faces so small that `f32` rounding tilts their planes.
pub const MIN_CUT_REL: f64 = 1e-3;

/// The smallest cut is at least this many `f32` epsilons of the largest coordinate, so that at
/// large offsets (1e5 m) new faces stay far wider than an ulp.
pub const MIN_CUT_EPS: f64 = 64.0 * f32::EPSILON as f64;

/// A bad batch.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum HullError {
    /// No boxes.
    #[error("batch hull: no boxes (a batch holds at least one tree)")]
    Empty,
    /// A box with a NaN or infinite component.
    #[error("batch hull: box {index} has a non-finite {field} {value:?}")]
    NonFinite {
        /// The box's index.
        index: usize,
        /// `"centre"` or `"half-size"`.
        field: &'static str,
        /// The offending value.
        value: [f32; 3],
    },
    /// A box with a negative half-size component.
    #[error("batch hull: box {index} has a negative half-size {value:?}")]
    NegativeExtent {
        /// The box's index.
        index: usize,
        /// The offending half-size.
        value: [f32; 3],
    },
    /// A box reaching beyond what `f32` vertices can hold.
    #[error("batch hull: box {index} reaches {reach:e} m, beyond the f32 range of the vertices")]
    OutOfRange {
        /// The box's index.
        index: usize,
        /// Its largest `|centre| + half-size`.
        reach: f64,
    },
    /// A triangle budget under a box's twelve.
    #[error("batch hull: a budget of {0} triangles is under the 12 of a box")]
    Budget(u32),
}

/// A built hull and what the construction knows of it.
#[derive(Clone, Debug, PartialEq)]
pub struct BatchHull {
    /// The triangles (module docs).
    pub triangles: Vec<Triangle>,
    /// Planar faces (polygons) the triangles fan.
    pub faces: usize,
    /// The largest depth, m, by which the hull reaches beyond a candidate plane (module docs,
    /// step 3): how far the hull stands outside the exact hull of the corners (plus the margin),
    /// at most on the candidates' directions.
    pub excess: f64,
}

/// The batch hull of `boxes` with the far level's budget, [`MAX_HULL_TRIANGLES`] (module docs).
pub fn batch_hull(boxes: &[HullBox]) -> Result<Vec<Triangle>, HullError> {
    Ok(build_hull(boxes, MAX_HULL_TRIANGLES)?.triangles)
}

/// The world-space box of a tree's mesh: the mesh's local box scaled, rotated by the yaw about
/// +Z and translated (as [`crate::scene::tree_sphere`] places its sphere), the half-size
/// rounded up to the next `f32` so that the box holds the mesh.
pub fn tree_box(instance: &Instance, mesh: &MeshMeta) -> HullBox {
    let s = instance.scale as f64;
    let lo = mesh.bbox_min.map(|x| x as f64 * s);
    let hi = mesh.bbox_max.map(|x| x as f64 * s);
    let c = [0, 1, 2].map(|k| (lo[k] + hi[k]) * 0.5);
    let h = [0, 1, 2].map(|k| (hi[k] - lo[k]) * 0.5);
    let (sn, cs) = (instance.yaw as f64).sin_cos();
    let p = instance.position.map(|x| x as f64);
    let centre = [
        p[0] + cs * c[0] - sn * c[1],
        p[1] + sn * c[0] + cs * c[1],
        p[2] + c[2],
    ];
    let half = [
        cs.abs() * h[0] + sn.abs() * h[1],
        sn.abs() * h[0] + cs.abs() * h[1],
        h[2],
    ];
    // The centre rounds to f32 by at most half an ulp: widen the half-size by that.
    let centre32 = centre.map(|x| x as f32);
    let half32 = [0, 1, 2].map(|k| {
        let slack = (centre32[k] as f64 - centre[k]).abs();
        f32_at_least(half[k] + slack)
    });
    (centre32, half32)
}

/// Rounds a non-negative `f64` up to the nearest `f32` not below it.
fn f32_at_least(x: f64) -> f32 {
    let y = x as f32;
    if (y as f64) < x {
        f32::from_bits(y.to_bits() + 1)
    } else {
        y
    }
}

/// The batch hull of `boxes` with at most `max_triangles` triangles (`≥ 12`; module docs).
pub fn build_hull(boxes: &[HullBox], max_triangles: u32) -> Result<BatchHull, HullError> {
    if max_triangles < 12 {
        return Err(HullError::Budget(max_triangles));
    }
    let frame = Frame::new(boxes)?;
    let candidates = candidates(boxes, &frame);
    let supports: Vec<f64> = candidates
        .iter()
        .map(|&n| frame.support(n) + frame.margin)
        .collect();

    let mut poly = Poly::cuboid(frame.lo - frame.margin, frame.hi + frame.margin);
    let mut alive = vec![true; candidates.len()];
    loop {
        let mut best: Option<(usize, f64)> = None;
        for (j, n) in candidates.iter().enumerate() {
            if !alive[j] {
                continue;
            }
            let gap = poly.reach(*n) - supports[j];
            if gap <= frame.min_cut {
                // The polytope only shrinks: this candidate never cuts deep enough again.
                alive[j] = false;
                continue;
            }
            if best.is_none_or(|(_, g)| gap > g) {
                best = Some((j, gap));
            }
        }
        let Some((j, _)) = best else { break };
        alive[j] = false;
        if let Some(next) = poly.clip(candidates[j], supports[j], frame.min_cut * 0.25)
            && next.triangle_count() <= max_triangles as usize
            && next.rounds_apart(frame.origin)
        {
            poly = next;
        }
    }
    let excess = candidates
        .iter()
        .zip(&supports)
        .map(|(n, s)| poly.reach(*n) - s + frame.margin)
        .fold(0.0f64, f64::max);
    Ok(BatchHull {
        triangles: poly.triangles(frame.origin),
        faces: poly.faces.len(),
        excess,
    })
}

/// The batch in local coordinates.
struct Frame {
    /// World position of the local origin (the centre of the corners' box).
    origin: DVec3,
    /// The corners' box, local.
    lo: DVec3,
    hi: DVec3,
    /// Box centres (local) and half-sizes.
    centres: Vec<DVec3>,
    halves: Vec<DVec3>,
    /// Plane margin (module docs).
    margin: f64,
    /// The smallest cut.
    min_cut: f64,
}

impl Frame {
    fn new(boxes: &[HullBox]) -> Result<Self, HullError> {
        if boxes.is_empty() {
            return Err(HullError::Empty);
        }
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        let mut big = 1.0f64;
        for (index, (c, h)) in boxes.iter().enumerate() {
            if c.iter().any(|x| !x.is_finite()) {
                return Err(HullError::NonFinite {
                    index,
                    field: "centre",
                    value: *c,
                });
            }
            if h.iter().any(|x| !x.is_finite()) {
                return Err(HullError::NonFinite {
                    index,
                    field: "half-size",
                    value: *h,
                });
            }
            if h.iter().any(|x| *x < 0.0) {
                return Err(HullError::NegativeExtent { index, value: *h });
            }
            let c = DVec3::from(c.map(|x| x as f64));
            let h = DVec3::from(h.map(|x| x as f64));
            let reach = (c.abs() + h).max_element();
            // Room for the margin and the smallest cut on top (a hundredth of f32's range).
            if reach > f32::MAX as f64 * 0.01 {
                return Err(HullError::OutOfRange { index, reach });
            }
            big = big.max(reach);
            lo = lo.min(c - h);
            hi = hi.max(c + h);
        }
        let origin = (lo + hi) * 0.5;
        let size = (hi - lo).length();
        let margin = MARGIN_EPS * big;
        Ok(Self {
            origin,
            lo: lo - origin,
            hi: hi - origin,
            centres: boxes
                .iter()
                .map(|(c, _)| DVec3::from(c.map(|x| x as f64)) - origin)
                .collect(),
            halves: boxes
                .iter()
                .map(|(_, h)| DVec3::from(h.map(|x| x as f64)))
                .collect(),
            margin,
            min_cut: (MIN_CUT_REL * size).max(MIN_CUT_EPS * big),
        })
    }

    /// `max_corners n · p` (local).
    fn support(&self, n: DVec3) -> f64 {
        let a = n.abs();
        self.centres
            .iter()
            .zip(&self.halves)
            .map(|(c, h)| n.dot(*c) + a.dot(*h))
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Every box corner, local, in `f32` for the hull crate.
    fn corners(&self) -> Vec<Vec3A> {
        let mut out = Vec::with_capacity(self.centres.len() * 8);
        for (c, h) in self.centres.iter().zip(&self.halves) {
            for k in 0..8 {
                let s = DVec3::new(
                    if k & 1 == 0 { -1.0 } else { 1.0 },
                    if k & 2 == 0 { -1.0 } else { 1.0 },
                    if k & 4 == 0 { -1.0 } else { 1.0 },
                );
                let p = *c + s * *h;
                out.push(Vec3A::new(p.x as f32, p.y as f32, p.z as f32));
            }
        }
        out
    }
}

/// The candidate directions (module docs, step 2): unit, without the axes (the start box has
/// them), the 26-DOP's diagonals first, then the exact hull's face normals in the crate's order.
fn candidates(_boxes: &[HullBox], frame: &Frame) -> Vec<DVec3> {
    let mut out = Vec::new();
    for x in [-1.0, 0.0, 1.0] {
        for y in [-1.0, 0.0, 1.0] {
            for z in [-1.0f64, 0.0, 1.0] {
                let zeros = [x, y, z].iter().filter(|v| **v == 0.0).count();
                if zeros < 2 {
                    out.push(DVec3::new(x, y, z).normalize());
                }
            }
        }
    }
    let extent = frame.hi - frame.lo;
    // The crate needs a solid: corners spanning every axis (it declines flat sets).
    if extent.min_element() > frame.min_cut {
        let corners = frame.corners();
        if let Ok(mesh) = quickhull::ConvexTriangleMesh::try_from_points(&corners, None) {
            let v = mesh.vertices();
            for t in mesh.indices() {
                let [a, b, c] = t.map(|i| {
                    let p = v[i as usize];
                    DVec3::new(p.x as f64, p.y as f64, p.z as f64)
                });
                let n = (b - a).cross(c - a);
                let len = n.length();
                if len > 0.0 && len.is_finite() {
                    let n = n / len;
                    // Axis normals are the start box's; skip them.
                    if n.abs().max_element() < 1.0 - 1e-12 {
                        out.push(n);
                    }
                }
            }
        }
    }
    out
}

/// A convex polytope: vertices (local, `f64`) and faces, each a ring of vertex indices
/// counter-clockwise seen from outside.
#[derive(Clone, Debug)]
struct Poly {
    verts: Vec<DVec3>,
    faces: Vec<Vec<u32>>,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Side {
    In,
    On,
    Out,
}

impl Poly {
    /// The box `[lo, hi]`.
    fn cuboid(lo: DVec3, hi: DVec3) -> Self {
        let verts = (0..8)
            .map(|k| {
                DVec3::new(
                    if k & 1 == 0 { lo.x } else { hi.x },
                    if k & 2 == 0 { lo.y } else { hi.y },
                    if k & 4 == 0 { lo.z } else { hi.z },
                )
            })
            .collect();
        let faces = vec![
            vec![0, 4, 6, 2], // -x
            vec![1, 3, 7, 5], // +x
            vec![0, 1, 5, 4], // -y
            vec![2, 6, 7, 3], // +y
            vec![0, 2, 3, 1], // -z
            vec![4, 5, 7, 6], // +z
        ];
        Self { verts, faces }
    }

    /// `max_vertices n · v`.
    fn reach(&self, n: DVec3) -> f64 {
        self.verts
            .iter()
            .map(|v| n.dot(*v))
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Triangles of the fans: `Σ (k − 2)`.
    fn triangle_count(&self) -> usize {
        self.faces.iter().map(|f| f.len() - 2).sum()
    }

    /// The polytope cut by `n · p ≤ s`; vertices within `tol` of the plane stay. `None` when
    /// nothing is cut, everything would be, or the cap does not close (module docs, Numerics).
    fn clip(&self, n: DVec3, s: f64, tol: f64) -> Option<Self> {
        let d: Vec<f64> = self.verts.iter().map(|v| n.dot(*v) - s).collect();
        let side: Vec<Side> = d
            .iter()
            .map(|&x| {
                if x > tol {
                    Side::Out
                } else if x < -tol {
                    Side::In
                } else {
                    Side::On
                }
            })
            .collect();
        if !side.contains(&Side::Out) || !side.contains(&Side::In) {
            return None;
        }
        let mut verts = self.verts.clone();
        let mut on_plane: Vec<bool> = side.iter().map(|s| *s == Side::On).collect();
        let mut cuts: BTreeMap<(u32, u32), u32> = BTreeMap::new();
        let mut faces = Vec::with_capacity(self.faces.len() + 1);
        for ring in &self.faces {
            if !ring.iter().any(|&v| side[v as usize] == Side::In) {
                continue;
            }
            let mut out = Vec::with_capacity(ring.len() + 1);
            for k in 0..ring.len() {
                let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
                let (sa, sb) = (side[a as usize], side[b as usize]);
                if sa != Side::Out {
                    out.push(a);
                }
                if (sa == Side::In && sb == Side::Out) || (sa == Side::Out && sb == Side::In) {
                    let key = (a.min(b), a.max(b));
                    let id = *cuts.entry(key).or_insert_with(|| {
                        let (p, q) = (key.0 as usize, key.1 as usize);
                        let t = d[p] / (d[p] - d[q]);
                        verts.push(self.verts[p] + (self.verts[q] - self.verts[p]) * t);
                        on_plane.push(true);
                        (verts.len() - 1) as u32
                    });
                    out.push(id);
                }
            }
            faces.push(out);
        }
        // The cap: the edges left without a twin, reversed, chained into one ring.
        let mut edges = BTreeSet::new();
        for ring in &faces {
            for k in 0..ring.len() {
                edges.insert((ring[k], ring[(k + 1) % ring.len()]));
            }
        }
        let mut next: BTreeMap<u32, u32> = BTreeMap::new();
        for &(a, b) in &edges {
            if !edges.contains(&(b, a)) {
                if !on_plane[a as usize] || !on_plane[b as usize] || next.insert(b, a).is_some() {
                    return None;
                }
            }
        }
        let (&start, _) = next.first_key_value()?;
        let mut cap = vec![start];
        let mut at = next[&start];
        while at != start {
            if cap.len() > next.len() {
                return None;
            }
            cap.push(at);
            at = *next.get(&at)?;
        }
        if cap.len() != next.len() || cap.len() < 3 {
            return None;
        }
        faces.push(cap);
        // Keep the vertices in use, in index order.
        let mut map = vec![u32::MAX; verts.len()];
        for ring in &faces {
            for &v in ring {
                map[v as usize] = 0;
            }
        }
        let mut kept = Vec::new();
        for (i, m) in map.iter_mut().enumerate() {
            if *m == 0 {
                *m = kept.len() as u32;
                kept.push(verts[i]);
            }
        }
        for ring in &mut faces {
            for v in ring.iter_mut() {
                *v = map[*v as usize];
            }
        }
        let poly = Self {
            verts: kept,
            faces,
        };
        poly.is_closed().then_some(poly)
    }

    /// Every directed edge once, with its twin; rings of three or more; Euler's `V − E + F = 2`.
    fn is_closed(&self) -> bool {
        let mut edges = BTreeSet::new();
        for ring in &self.faces {
            if ring.len() < 3 {
                return false;
            }
            for k in 0..ring.len() {
                if !edges.insert((ring[k], ring[(k + 1) % ring.len()])) {
                    return false;
                }
            }
        }
        edges.iter().all(|&(a, b)| edges.contains(&(b, a)))
            && self.verts.len() + self.faces.len() == edges.len() / 2 + 2
    }

    /// Whether the vertices stay apart once rounded to `f32` world positions.
    fn rounds_apart(&self, origin: DVec3) -> bool {
        let mut p: Vec<[u32; 3]> = self
            .verts
            .iter()
            .map(|v| world(origin, *v).map(f32::to_bits))
            .collect();
        p.sort_unstable();
        p.windows(2).all(|w| w[0] != w[1])
    }

    /// Each face fanned from its first vertex, in `f32` world positions.
    fn triangles(&self, origin: DVec3) -> Vec<Triangle> {
        let w: Vec<[f32; 3]> = self.verts.iter().map(|v| world(origin, *v)).collect();
        let mut out = Vec::with_capacity(self.triangle_count());
        for ring in &self.faces {
            for k in 1..ring.len() - 1 {
                out.push([
                    w[ring[0] as usize],
                    w[ring[k] as usize],
                    w[ring[k + 1] as usize],
                ]);
            }
        }
        out
    }
}

/// A local vertex in `f32` world coordinates.
fn world(origin: DVec3, v: DVec3) -> [f32; 3] {
    (origin + v).to_array().map(|x| x as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_box_is_that_box() {
        let b = ([1.0, 2.0, 3.0], [0.5, 1.0, 2.0]);
        let h = build_hull(&[b], MAX_HULL_TRIANGLES).unwrap();
        assert_eq!(h.triangles.len(), 12);
        assert_eq!(h.faces, 6);
    }
}
