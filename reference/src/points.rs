//! Celba's point-based tree LOD, CPU preprocessing and selection (issue 33 item 1; C§4.4.3,
//! Alg. 5, Alg. 6, C§4.6.3). The contract (placement, hierarchy, order, both selection rules,
//! the safe change distance, and the design of the point command path) is
//! `forestlod_shared::points`'s module docs; the formulas live there. Here:
//!
//! - [`place_points`]: a mesh's points on opaque texels (C§4.4.4's fix), deterministic
//!   (hashes, no RNG state), bounded (`retries` tries, then an opaque texel centre).
//! - [`build_mesh_points`]: Alg. 5 per grid cell, merged points with union areas (Alg. 6 or
//!   exact), area order and cut order, the whole-tree node (C§4.4.3's uplift points) and the
//!   first non-discardable triangle; [`build_points`] for every mesh (rayon over meshes, results
//!   in mesh order: identical for any thread count).
//! - [`select_tree`] (one tree at one depth, either rule), [`batch_range`] (a batch's
//!   conservative range by binary search), [`representation_counts`] (how often each placed
//!   point is represented: interval mode's holes and doubles), [`mesh_change_distance`].
//!
//! - [`PointLod`]: what the draw reads under `lod1 = points` (`crate::draw` expands each kept
//!   record to a square; the WGSL twin comes later).

use forestlod_shared::ParamError;
use forestlod_shared::color::{linear_to_srgb, srgb_to_linear, unorm8};
use forestlod_shared::points::{
    NO_PARENT, PointParams, PointRecord, PointSelect, ROOT_PARENT_AREA, UnionMode, area_per_depth2,
    change_distance, cut_keep, cut_range, hash_unit, interval_keep, interval_range,
    largest_remainder, pack_normal, pack_rgba8, point_hash, square_xz, texel_opaque,
    triangle_sample, union_area, unpack_normal, unpack_rgba8,
};
use rayon::prelude::*;

use crate::scene::TreeMesh;

/// Most texel-centre samples a triangle's coverage count visits (a triangle whose texture
/// footprint is larger is sampled on a coarser grid of this many points).
pub const MAX_COVERAGE_SAMPLES: u64 = 1 << 20;

/// Where a placed point came from: its triangle (index into the mesh's triangle list), the
/// barycentric weights of corners 1 and 2, and the `uv` they give.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointSource {
    /// Triangle index (`indices[3t..3t + 3]`).
    pub triangle: u32,
    /// Barycentric weights of corners 1 and 2.
    pub bary: [f32; 2],
    /// Texture coordinate at the point.
    pub uv: [f32; 2],
}

/// A placed point before the hierarchy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlacedPoint {
    /// Mesh-local position.
    pub pos: [f32; 3],
    /// Unit face normal.
    pub normal: [f32; 3],
    /// Its texel's colour (sRGB RGBA8).
    pub rgba: [u8; 4],
    /// Its share of the triangle's opaque area, m².
    pub area: f32,
    /// Where it lies (`None` for a whole-tree copy).
    pub source: Option<PointSource>,
}

/// The point hierarchy of one mesh (module docs of `forestlod_shared::points`).
#[derive(Clone, Debug, PartialEq)]
pub struct MeshPoints {
    /// Records in area order (ascending).
    pub records: Vec<PointRecord>,
    /// Children of each record (area-order indices; empty for a placed point).
    pub children: Vec<Vec<u32>>,
    /// The source of each placed point (`None` for merged points).
    pub source: Vec<Option<PointSource>>,
    /// Placed points per Alg. 5 group, in build order.
    pub groups: Vec<u32>,
    /// The cut order: area-order indices sorted by `parent_area` (stable).
    pub cut_order: Vec<u32>,
    /// `parent_area` in cut order (the cut's binary-search keys).
    pub cut_keys: Vec<f32>,
    /// Opaque area of each triangle (area × coverage × `scale_factor²`), triangle order.
    pub triangle_areas: Vec<f32>,
    /// Area of the first non-discardable triangle (C§4.4.3, slip (d)); 0 if all may go.
    pub keep_triangle_area: f32,
    /// Area-order indices of the records copied into the whole-tree node.
    pub uplifted: Vec<u32>,
    /// The whole-tree node's own hierarchy (C§4.4.3; `None` when `uplift` copies nothing).
    pub whole_tree: Option<Box<MeshPoints>>,
}

impl MeshPoints {
    /// Area of every record, area order.
    pub fn areas(&self) -> Vec<f32> {
        self.records.iter().map(|r| r.area).collect()
    }
    /// Area-order indices of the placed points.
    pub fn placed(&self) -> impl Iterator<Item = u32> + '_ {
        self.source
            .iter()
            .enumerate()
            .filter(|(_, s)| s.is_some())
            .map(|(i, _)| i as u32)
    }
    /// Area-order indices of the placed points below record `i` (itself if placed).
    pub fn leaves_below(&self, i: u32) -> Vec<u32> {
        let mut out = Vec::new();
        let mut stack = vec![i];
        while let Some(n) = stack.pop() {
            let c = &self.children[n as usize];
            if c.is_empty() {
                out.push(n);
            } else {
                stack.extend(c.iter().copied());
            }
        }
        out.sort_unstable();
        out
    }
    /// Memory of the records a draw would upload, bytes (records and the cut permutation).
    pub fn gpu_bytes(&self) -> usize {
        self.records.len() * (core::mem::size_of::<PointRecord>() + 4)
    }
}

/// The triangles of `mesh` as corner indices.
fn triangles(mesh: &TreeMesh) -> impl Iterator<Item = [usize; 3]> + '_ {
    mesh.indices
        .chunks_exact(3)
        .map(|t| [t[0] as usize, t[1] as usize, t[2] as usize])
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn length(a: [f32; 3]) -> f32 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// The level-0 texel of `uv`, as stored (sRGB RGBA8): nearest, clamp-to-edge, the addressing
/// of [`crate::sampler::Texture::nearest`] (tested equal there, `points_properties`), which
/// returns the decoded texel; placement needs the stored bytes for the colour.
pub fn texel_at(mesh: &TreeMesh, uv: [f32; 2]) -> [u8; 4] {
    let (w, h) = (mesh.texture.width, mesh.texture.height);
    let clamp = |x: f32, n: u32| (x.floor().max(0.0) as u64).min(n as u64 - 1) as u32;
    mesh.texture
        .get(clamp(uv[0] * w as f32, w), clamp(uv[1] * h as f32, h))
}

/// `uv` at barycentric weights `(b1, b2)` of triangle `t` of `mesh` (`f32`, as placement
/// computes it).
pub fn uv_at(mesh: &TreeMesh, t: [usize; 3], bary: [f32; 2]) -> [f32; 2] {
    let b0 = 1.0 - bary[0] - bary[1];
    let [a, b, c] = t.map(|k| mesh.uvs[k]);
    [
        a[0] * b0 + b[0] * bary[0] + c[0] * bary[1],
        a[1] * b0 + b[1] * bary[0] + c[1] * bary[1],
    ]
}

fn pos_at(mesh: &TreeMesh, t: [usize; 3], bary: [f32; 2]) -> [f32; 3] {
    let b0 = 1.0 - bary[0] - bary[1];
    let [a, b, c] = t.map(|k| mesh.positions[k]);
    core::array::from_fn(|i| a[i] * b0 + b[i] * bary[0] + c[i] * bary[1])
}

/// A triangle's texture coverage (module docs): the fraction of the texel centres inside its
/// `uv` footprint whose texel passes the alpha test, and the barycentric weights of the opaque
/// ones (the placement's fallback). A footprint with no texel centre inside is sampled at its
/// centroid.
pub fn triangle_coverage(mesh: &TreeMesh, t: [usize; 3], cutoff: f32) -> (f64, Vec<[f32; 2]>) {
    let (w, h) = (mesh.texture.width as f64, mesh.texture.height as f64);
    let p = t.map(|k| [mesh.uvs[k][0] as f64 * w, mesh.uvs[k][1] as f64 * h]);
    let (x0, x1) = (
        p.iter().map(|q| q[0]).fold(f64::INFINITY, f64::min),
        p.iter().map(|q| q[0]).fold(f64::NEG_INFINITY, f64::max),
    );
    let (y0, y1) = (
        p.iter().map(|q| q[1]).fold(f64::INFINITY, f64::min),
        p.iter().map(|q| q[1]).fold(f64::NEG_INFINITY, f64::max),
    );
    let det = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
    let bary = |x: f64, y: f64| -> Option<[f64; 2]> {
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let (dx, dy) = (x - p[0][0], y - p[0][1]);
        let b1 = (dx * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * dy) / det;
        let b2 = ((p[1][0] - p[0][0]) * dy - dx * (p[1][1] - p[0][1])) / det;
        (b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0).then_some([b1, b2])
    };
    let opaque_at = |b: [f64; 2]| {
        let bb = [b[0] as f32, b[1] as f32];
        texel_opaque(texel_at(mesh, uv_at(mesh, t, bb))[3], cutoff).then_some(bb)
    };
    let (mut inside, mut opaque) = (0u64, Vec::new());
    if x1.is_finite() && y1.is_finite() && x0.is_finite() && y0.is_finite() {
        let (i0, i1) = ((x0 - 0.5).ceil(), (x1 - 0.5).floor());
        let (j0, j1) = ((y0 - 0.5).ceil(), (y1 - 0.5).floor());
        let (nx, ny) = ((i1 - i0 + 1.0).max(0.0), (j1 - j0 + 1.0).max(0.0));
        let step = ((nx * ny) / MAX_COVERAGE_SAMPLES as f64)
            .sqrt()
            .ceil()
            .max(1.0);
        let mut j = j0;
        while j <= j1 {
            let mut i = i0;
            while i <= i1 {
                if let Some(b) = bary(i + 0.5, j + 0.5) {
                    inside += 1;
                    opaque.extend(opaque_at(b));
                }
                i += step;
            }
            j += step;
        }
    }
    if inside == 0 {
        inside = 1;
        opaque.extend(opaque_at([1.0 / 3.0, 1.0 / 3.0]));
    }
    (opaque.len() as f64 / inside as f64, opaque)
}

/// The points of `mesh` (module docs of `forestlod_shared::points`, "Placement"), in placement
/// order (triangle by triangle), and the opaque area of each triangle. Valid `params`.
pub fn place_points(mesh: &TreeMesh, params: &PointParams) -> (Vec<PlacedPoint>, Vec<f32>) {
    let tris: Vec<[usize; 3]> = triangles(mesh).collect();
    let scale2 = (params.scale_factor as f64) * (params.scale_factor as f64);
    let mut covers = Vec::with_capacity(tris.len());
    let mut weights = Vec::with_capacity(tris.len());
    let mut normals = Vec::with_capacity(tris.len());
    for &t in &tris {
        let [a, b, c] = t.map(|k| mesh.positions[k]);
        let n = cross(sub(b, a), sub(c, a));
        let len = length(n);
        let area = 0.5 * len as f64;
        let (cov, opaque) = triangle_coverage(mesh, t, params.alpha_cutoff);
        weights.push(area * cov);
        normals.push(if len > 0.0 {
            n.map(|x| x / len)
        } else {
            [0.0, 0.0, 1.0]
        });
        covers.push(opaque);
    }
    let shares = largest_remainder(&weights, params.n_pts);
    let mut points = Vec::with_capacity(params.n_pts as usize);
    for (ti, &t) in tris.iter().enumerate() {
        let n = shares[ti];
        if n == 0 || covers[ti].is_empty() {
            continue;
        }
        let area = (weights[ti] / n as f64 * scale2) as f32;
        for j in 0..n {
            let mut found = None;
            for r in 0..params.retries {
                let u = (j as f32 + hash_unit(point_hash(ti as u32, j, 2 * r, 0x51))) / n as f32;
                let v = hash_unit(point_hash(ti as u32, j, 2 * r + 1, 0x51));
                let bary = triangle_sample(u.min(1.0), v);
                let uv = uv_at(mesh, t, bary);
                if texel_opaque(texel_at(mesh, uv)[3], params.alpha_cutoff) {
                    found = Some((bary, uv));
                    break;
                }
            }
            if found.is_none() {
                // The fallback: an opaque texel centre of the triangle, by hash; checked again
                // on the interpolated `uv` (f32), next one if rounding moved it off the texel.
                let opaque = &covers[ti];
                let start = point_hash(ti as u32, j, u32::MAX, 0x52) as usize % opaque.len();
                found = (0..opaque.len()).find_map(|k| {
                    let bary = opaque[(start + k) % opaque.len()];
                    let uv = uv_at(mesh, t, bary);
                    texel_opaque(texel_at(mesh, uv)[3], params.alpha_cutoff).then_some((bary, uv))
                });
            }
            let Some((bary, uv)) = found else { continue };
            points.push(PlacedPoint {
                pos: pos_at(mesh, t, bary),
                normal: normals[ti],
                rgba: texel_at(mesh, uv),
                area,
                source: Some(PointSource {
                    triangle: ti as u32,
                    bary,
                    uv,
                }),
            });
        }
    }
    let tri_areas = weights.iter().map(|&w| (w * scale2) as f32).collect();
    (points, tri_areas)
}

/// A node of the hierarchy while it is built (creation order).
struct Node {
    record: PointRecord,
    children: Vec<u32>,
    source: Option<PointSource>,
}

/// Builds the Alg. 5 tree over `perm[lo..hi]` (indices of `pts`), appending merged nodes to
/// `nodes` (placed points are nodes `0..pts.len()`), and returns the subtree's top node.
fn alg5(
    pts: &[PlacedPoint],
    perm: &mut [u32],
    nodes: &mut Vec<Node>,
    groups: &mut Vec<u32>,
    max_group: usize,
    union: UnionMode,
) -> u32 {
    if perm.len() <= max_group {
        groups.push(perm.len() as u32);
        if perm.len() == 1 {
            return perm[0];
        }
        let children = perm.to_vec();
        return merge(pts, perm, children, nodes, union);
    }
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for &i in perm.iter() {
        for k in 0..3 {
            lo[k] = lo[k].min(pts[i as usize].pos[k]);
            hi[k] = hi[k].max(pts[i as usize].pos[k]);
        }
    }
    let ext = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
        0
    } else if ext[1] >= ext[2] {
        1
    } else {
        2
    };
    let mid = lo[axis] + 0.5 * ext[axis];
    // Stable partition by the plane through the middle of the longest side (Alg. 5).
    let (mut left, mut right): (Vec<u32>, Vec<u32>) =
        perm.iter().partition(|&&i| pts[i as usize].pos[axis] < mid);
    if left.is_empty() || right.is_empty() {
        // All on one side (coincident along the axis): halve the list ordered along it.
        let mut all = perm.to_vec();
        all.sort_by(|&a, &b| {
            pts[a as usize].pos[axis]
                .total_cmp(&pts[b as usize].pos[axis])
                .then(a.cmp(&b))
        });
        right = all.split_off(all.len() / 2);
        left = all;
    }
    let m = left.len();
    perm[..m].copy_from_slice(&left);
    perm[m..].copy_from_slice(&right);
    let (pl, pr) = perm.split_at_mut(m);
    let a = alg5(pts, pl, nodes, groups, max_group, union);
    let b = alg5(pts, pr, nodes, groups, max_group, union);
    merge(pts, perm, vec![a, b], nodes, union)
}

/// A merged point over the placed points `below` with `children` (module docs): mean
/// position, area-weighted normal and colour, union area clamped to at least the largest child.
fn merge(
    pts: &[PlacedPoint],
    below: &[u32],
    children: Vec<u32>,
    nodes: &mut Vec<Node>,
    union: UnionMode,
) -> u32 {
    let mut pos = [0.0f64; 3];
    let mut normal = [0.0f64; 3];
    let mut colour = [0.0f64; 4];
    let mut weight = 0.0f64;
    let mut squares = Vec::with_capacity(below.len());
    for &i in below {
        let p = &pts[i as usize];
        let w = p.area as f64;
        for k in 0..3 {
            pos[k] += p.pos[k] as f64;
            normal[k] += w * p.normal[k] as f64;
        }
        for (k, c) in colour.iter_mut().enumerate() {
            let linear = if k < 3 {
                srgb_to_linear(p.rgba[k]) as f64
            } else {
                p.rgba[3] as f64 / 255.0
            };
            *c += w * linear;
        }
        weight += w;
        squares.push(square_xz(p.pos, p.area));
    }
    let n = below.len() as f64;
    let pos = pos.map(|x| (x / n) as f32);
    let nl = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
    let normal = if nl > 0.0 {
        normal.map(|x| (x / nl) as f32)
    } else {
        [0.0, 0.0, 1.0]
    };
    let c = |x: f64| {
        if weight > 0.0 {
            (x / weight) as f32
        } else {
            0.0
        }
    };
    let rgba = [
        linear_to_srgb(c(colour[0])),
        linear_to_srgb(c(colour[1])),
        linear_to_srgb(c(colour[2])),
        unorm8(c(colour[3])),
    ];
    let largest = children
        .iter()
        .map(|&k| nodes[k as usize].record.area)
        .fold(0.0f32, f32::max);
    let area = (union_area(&squares, union) as f32).max(largest);
    let leaves = children
        .iter()
        .map(|&k| nodes[k as usize].record.leaves)
        .sum();
    nodes.push(Node {
        record: PointRecord {
            pos,
            area,
            lower: area,
            parent_area: ROOT_PARENT_AREA,
            normal: pack_normal(normal),
            rgba8: pack_rgba8(rgba),
            parent: NO_PARENT,
            leaves,
            _pad: [0; 2],
        },
        children,
        source: None,
    });
    (nodes.len() - 1) as u32
}

/// The hierarchy of `pts` (module docs of `forestlod_shared::points`): grid cells, Alg. 5 with
/// groups of `max_group`, merged points, area order with parents, cut order.
pub fn build_hierarchy(
    pts: &[PlacedPoint],
    grid: [u32; 3],
    max_group: u32,
    union: UnionMode,
) -> MeshPoints {
    let mut nodes: Vec<Node> = pts
        .iter()
        .map(|p| Node {
            record: PointRecord {
                pos: p.pos,
                area: p.area,
                lower: 0.0,
                parent_area: ROOT_PARENT_AREA,
                normal: pack_normal(p.normal),
                rgba8: pack_rgba8(p.rgba),
                parent: NO_PARENT,
                leaves: 1,
                _pad: [0; 2],
            },
            children: Vec::new(),
            source: p.source,
        })
        .collect();
    // Grid cells over the points' AABB (C§4.4.3 step 5), x fastest.
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in pts {
        for k in 0..3 {
            lo[k] = lo[k].min(p.pos[k]);
            hi[k] = hi[k].max(p.pos[k]);
        }
    }
    let cell_of = |p: &PlacedPoint| -> usize {
        let c = |k: usize| {
            let g = grid[k] as f32;
            let ext = hi[k] - lo[k];
            if ext > 0.0 {
                (((p.pos[k] - lo[k]) / ext * g).floor().max(0.0) as u32).min(grid[k] - 1) as usize
            } else {
                0
            }
        };
        c(0) + grid[0] as usize * (c(1) + grid[1] as usize * c(2))
    };
    let cells = (grid[0] * grid[1] * grid[2]) as usize;
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); cells];
    for (i, p) in pts.iter().enumerate() {
        members[cell_of(p)].push(i as u32);
    }
    let mut groups = Vec::new();
    for mut perm in members.into_iter().filter(|m| !m.is_empty()) {
        alg5(
            pts,
            &mut perm,
            &mut nodes,
            &mut groups,
            max_group.max(1) as usize,
            union,
        );
    }
    // Parents in creation order.
    let mut parent = vec![NO_PARENT; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        for &c in &n.children {
            parent[c as usize] = i as u32;
        }
    }
    // Area order: ascending, ties by creation order (stable sort).
    let mut order: Vec<u32> = (0..nodes.len() as u32).collect();
    order.sort_by(|&a, &b| {
        nodes[a as usize]
            .record
            .area
            .total_cmp(&nodes[b as usize].record.area)
    });
    let mut rank = vec![0u32; nodes.len()];
    for (r, &i) in order.iter().enumerate() {
        rank[i as usize] = r as u32;
    }
    let mut records = Vec::with_capacity(nodes.len());
    let mut children = Vec::with_capacity(nodes.len());
    let mut source = Vec::with_capacity(nodes.len());
    for &i in &order {
        let n = &nodes[i as usize];
        let mut rec = n.record;
        let p = parent[i as usize];
        if p != NO_PARENT {
            rec.parent = rank[p as usize];
            rec.parent_area = nodes[p as usize].record.area;
        }
        records.push(rec);
        children.push(n.children.iter().map(|&c| rank[c as usize]).collect());
        source.push(n.source);
    }
    let mut cut_order: Vec<u32> = (0..records.len() as u32).collect();
    cut_order.sort_by(|&a, &b| {
        records[a as usize]
            .parent_area
            .total_cmp(&records[b as usize].parent_area)
    });
    let cut_keys = cut_order
        .iter()
        .map(|&i| records[i as usize].parent_area)
        .collect();
    MeshPoints {
        records,
        children,
        source,
        groups,
        cut_order,
        cut_keys,
        triangle_areas: Vec::new(),
        keep_triangle_area: 0.0,
        uplifted: Vec::new(),
        whole_tree: None,
    }
}

/// The area of the first non-discardable triangle (C§4.4.3; slip (d)): triangles ranked by area
/// descending, the first `floor(cutoff·n)` may vanish; 0 when all may.
pub fn keep_triangle_area(tri_areas: &[f32], cutoff: f32) -> f32 {
    let mut sorted = tri_areas.to_vec();
    sorted.sort_by(|a, b| b.total_cmp(a));
    let skip = (cutoff as f64 * sorted.len() as f64).floor() as usize;
    sorted.get(skip).copied().unwrap_or(0.0)
}

/// The point LOD of one mesh (module docs): placement, the cell-level hierarchy, the
/// whole-tree node and the triangle kept at the change. Checks `params` first.
pub fn build_mesh_points(mesh: &TreeMesh, params: &PointParams) -> Result<MeshPoints, ParamError> {
    params.validate()?;
    let (pts, tri_areas) = place_points(mesh, params);
    let mut set = build_hierarchy(&pts, params.grid, params.max_group, params.union);
    set.keep_triangle_area = keep_triangle_area(&tri_areas, params.triangle_cutoff);
    set.triangle_areas = tri_areas;
    // The whole-tree node (C§4.4.3): copies of the biggest `uplift` fraction of the records,
    // merged again with one point per group.
    let count =
        ((params.uplift as f64 * set.records.len() as f64).ceil() as usize).min(set.records.len());
    if count > 0 {
        let first = set.records.len() - count;
        set.uplifted = (first as u32..set.records.len() as u32).collect();
        let copies: Vec<PlacedPoint> = set.records[first..]
            .iter()
            .map(|r| {
                let c = unpack_rgba8(r.rgba8);
                PlacedPoint {
                    pos: r.pos,
                    normal: unpack_normal(r.normal),
                    rgba: c,
                    area: r.area,
                    source: None,
                }
            })
            .collect();
        set.whole_tree = Some(Box::new(build_hierarchy(
            &copies,
            [1, 1, 1],
            1,
            params.union,
        )));
    }
    Ok(set)
}

/// [`build_mesh_points`] for every mesh, in parallel over meshes, in mesh order (identical for
/// any thread count).
pub fn build_points(
    meshes: &[TreeMesh],
    params: &PointParams,
) -> Result<Vec<MeshPoints>, ParamError> {
    params.validate()?;
    meshes
        .par_iter()
        .map(|m| build_mesh_points(m, params))
        .collect()
}

/// The per-depth² area factors of one detail setting for a metric constant `c`
/// ([`area_per_depth2`] of `min_point` and `max_point`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointThresholds {
    /// `min_point / C`.
    pub k_min: f32,
    /// `max_point / C`.
    pub k_max: f32,
}

impl PointThresholds {
    /// From screen areas in pixels and the metric constant `c`.
    pub fn new(c: f64, min_px: f32, max_px: f32) -> Self {
        Self {
            k_min: area_per_depth2(c, min_px),
            k_max: area_per_depth2(c, max_px),
        }
    }
}

/// The records (area order, ascending) one tree of scale `scale` at view depth `depth` draws.
pub fn select_tree(
    set: &MeshPoints,
    mode: PointSelect,
    depth: f32,
    scale: f32,
    th: PointThresholds,
) -> Vec<u32> {
    set.records
        .iter()
        .enumerate()
        .filter(|(_, r)| match mode {
            PointSelect::Interval => interval_keep(r.area, scale, depth, th.k_min, th.k_max),
            PointSelect::Cut => cut_keep(r.lower, r.parent_area, scale, depth, th.k_max),
        })
        .map(|(i, _)| i as u32)
        .collect()
}

/// A batch's conservative range (trees at depths `[lo, hi]`, scales `[s_min, s_max]`), in the
/// mode's order (area order under the interval rule, cut order under the cut), by binary search.
pub fn batch_range(
    set: &MeshPoints,
    mode: PointSelect,
    depth: [f32; 2],
    scale: [f32; 2],
    th: PointThresholds,
) -> [u32; 2] {
    match mode {
        PointSelect::Interval => interval_range(&set.areas(), depth, scale, th.k_min, th.k_max),
        PointSelect::Cut => cut_range(&set.cut_keys, depth, scale, th.k_max),
    }
}

/// The records (area order) of a range in the mode's order, ascending.
pub fn range_records(set: &MeshPoints, mode: PointSelect, range: [u32; 2]) -> Vec<u32> {
    let mut out: Vec<u32> = match mode {
        PointSelect::Interval => (range[0]..range[1]).collect(),
        PointSelect::Cut => set.cut_order[range[0] as usize..range[1] as usize].to_vec(),
    };
    out.sort_unstable();
    out
}

/// How many drawn records represent each placed point (the drawn records on its path to its
/// root), in the order of [`MeshPoints::placed`]: 0 is a hole, 2 or more a double.
pub fn representation_counts(set: &MeshPoints, drawn: &[u32]) -> Vec<u32> {
    let mut is_drawn = vec![false; set.records.len()];
    for &d in drawn {
        is_drawn[d as usize] = true;
    }
    set.placed()
        .map(|leaf| {
            let mut n = 0;
            let mut i = leaf;
            loop {
                n += is_drawn[i as usize] as u32;
                let p = set.records[i as usize].parent;
                if p == NO_PARENT {
                    break n;
                }
                i = p;
            }
        })
        .collect()
}

/// Holes and doubles of a drawn set: placed points represented 0 times, and 2 or more times.
pub fn holes_and_doubles(set: &MeshPoints, drawn: &[u32]) -> (usize, usize) {
    let counts = representation_counts(set, drawn);
    (
        counts.iter().filter(|&&c| c == 0).count(),
        counts.iter().filter(|&&c| c >= 2).count(),
    )
}

/// The mesh's safe change distance at unit scale (C§4.6.3), `None` without a whole-tree node.
pub fn mesh_change_distance(
    set: &MeshPoints,
    c: f64,
    min_tree_px: f32,
    max_tree_px: f32,
) -> Option<f64> {
    let whole = set.whole_tree.as_ref()?;
    let min_area = whole.records.first()?.area;
    Some(change_distance(
        c,
        min_area as f64,
        set.keep_triangle_area as f64,
        min_tree_px as f64,
        max_tree_px as f64,
    ))
}

/// What one tree draws at a view depth with the seed's change distance (C§4.6.3): the
/// cell-level records by `mode` at `[min_point, max_point]` up to `scale·D_c`, and beyond it the
/// whole-tree node's records at `[min_tree_point, max_tree_point]` (no whole-tree node: always
/// the cell level).
#[derive(Clone, Debug, PartialEq)]
pub struct TreePoints {
    /// Whether the records are the whole-tree node's.
    pub whole_tree: bool,
    /// Area-order indices into the drawn set's records.
    pub records: Vec<u32>,
}

/// [`TreePoints`] of one tree of scale `scale` at view depth `depth`, metric constant `c`.
pub fn select_tree_lod(
    set: &MeshPoints,
    mode: PointSelect,
    depth: f32,
    scale: f32,
    c: f64,
    sizes: &forestlod_shared::points::DetailSizes,
) -> TreePoints {
    let change = mesh_change_distance(set, c, sizes.min_tree_point, sizes.max_tree_point);
    match (&set.whole_tree, change) {
        (Some(whole), Some(dc)) if depth as f64 >= scale as f64 * dc => TreePoints {
            whole_tree: true,
            records: select_tree(
                whole,
                mode,
                depth,
                scale,
                PointThresholds::new(c, sizes.min_tree_point, sizes.max_tree_point),
            ),
        },
        _ => TreePoints {
            whole_tree: false,
            records: select_tree(
                set,
                mode,
                depth,
                scale,
                PointThresholds::new(c, sizes.min_point, sizes.max_point),
            ),
        },
    }
}

/// The point LOD a frame draws under `lod1 = points` (issue 33, `forestlod_shared::points`'s
/// module docs, "the point command path"): every mesh's [`MeshPoints`], built once in
/// `prepare` (they depend on `point_count` and `alpha_cutoff` only), with their areas (the
/// interval rule's binary search). The rule (`point_select`) and the thresholds
/// (`point_detail`) are per frame, read from `Params` by the draw. The draw keeps a record with [`forestlod_shared::points::point_keep`] at the
/// tree's own depth and scale; it visits the tree's own range ([`PointLod::tree_records`]), in
/// the mode's order, which holds every record the keep test can pass.
#[derive(Clone, Debug)]
pub struct PointLod {
    /// Per mesh, its point hierarchy (cell level; the whole-tree node is built but not drawn).
    pub sets: Vec<MeshPoints>,
    /// Per mesh, its records' areas in area order.
    pub areas: Vec<Vec<f32>>,
}

impl PointLod {
    /// The point LOD of `meshes` under `params`, `None` unless `params` draw points
    /// ([`forestlod_shared::points::draws_points`]). `params` must be valid.
    pub fn build(
        meshes: &[TreeMesh],
        params: &forestlod_shared::Params,
    ) -> Result<Option<Self>, ParamError> {
        if !forestlod_shared::points::draws_points(params) {
            return Ok(None);
        }
        let sets = build_points(meshes, &PointParams::from_params(params))?;
        let areas = sets.iter().map(MeshPoints::areas).collect();
        Ok(Some(PointLod { sets, areas }))
    }

    /// Records of every mesh (memory and counters).
    pub fn records(&self) -> usize {
        self.sets.iter().map(|s| s.records.len()).sum()
    }

    /// The records (area-order indices) one tree of `mesh` at view depth `depth` and scale
    /// `scale` may draw under `mode` ([`PointSelect`] as `u32`), in the mode's order: its own range ([`interval_range`] or
    /// [`cut_range`] with `[depth, depth]`, `[scale, scale]`), a superset of what the keep test
    /// passes (exactly it under the interval rule).
    pub fn tree_records(
        &self,
        mode: u32,
        mesh: u32,
        depth: f32,
        scale: f32,
        k: [f32; 2],
    ) -> impl Iterator<Item = u32> + '_ {
        let set = &self.sets[mesh as usize];
        let (area, cut): (std::ops::Range<u32>, &[u32]) = if mode == PointSelect::Interval as u32 {
            let [i0, i1] = interval_range(
                &self.areas[mesh as usize],
                [depth, depth],
                [scale, scale],
                k[0],
                k[1],
            );
            (i0..i1, &[])
        } else {
            let [i0, _] = cut_range(&set.cut_keys, [depth, depth], [scale, scale], k[1]);
            (0..0, &set.cut_order[i0 as usize..])
        };
        area.chain(cut.iter().copied())
    }
}
