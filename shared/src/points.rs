//! Celba's point-based tree LOD (issue 33 item 1; C§4.4.3, Alg. 5, Alg. 6, C§4.6.3): the record
//! both backends read, the parameters, and the formulas the CPU preprocessing
//! (`reference/src/points.rs`), the reference draw and the draw's WGSL twin share.
//!
//! ## Contract
//! - **Placement** (C§4.4.4's proposed fix, slip (e) of the design study: our meshes are alpha
//!   cards of < 20 triangles, so the seed's one point per triangle means nothing). Per mesh,
//!   `n_pts` points are shared out over the triangles in proportion to `area × coverage`
//!   (coverage: the fraction of the triangle's level-0 texels whose alpha passes the draw's alpha
//!   test, [`texel_opaque`] at [`PointParams::alpha_cutoff`]) by largest remainder
//!   ([`largest_remainder`], ties to the lower triangle index). Each of a triangle's `n` points is
//!   a stratified hashed sample ([`point_hash`], [`triangle_sample`]) kept only on an opaque texel;
//!   after [`PointParams::retries`] rejected tries it takes one of the triangle's opaque texel
//!   centres by hash, so no point lies on a transparent texel and the work is bounded. A point
//!   carries the face normal, its texel's colour and the area `area·coverage/n` (× the seed's
//!   `PointScaleFactor²`, [`PointParams::scale_factor`]): the triangle's opaque area shared
//!   equally.
//! - **Hierarchy** (Alg. 5): the points of each cell of the seed's regular grid
//!   ([`PointParams::grid`], C§4.4.3 step 5) are split by the plane through the middle of the
//!   longest side of their AABB until a group holds at most [`PointParams::max_group`] points (a
//!   split that leaves one side empty falls back to halving the list ordered along that axis, so
//!   coincident points terminate). A group of `k > 1` points gets one merged point whose children
//!   are the `k` points; every binary split node gets one merged point whose children are its two
//!   sides' top points. A merged point's position is the mean of the placed points below it
//!   (C§4.4.3, "average of all point positions"), its normal and colour their area-weighted means
//!   (linear light; the seed weights by diameter, we by area so that colour follows the pixels a
//!   point covers), its area the **union of the squares** of the placed points below it
//!   projected on the **XZ plane** ([`union_area`], Alg. 6 and slip (b): the seed's "XY plane" is
//!   vertical in its Y-up world; ours is Z-up). By default the union is exact (Klee,
//!   [`UnionMode::Exact`]); [`UnionMode::SeedHull`] is Alg. 6 as printed, which sums
//!   `strip width × (max − min)` of the active squares and overestimates whenever they leave a
//!   gap (slip (a)). A merged area is then clamped into `[max child, Σ children]` (both bounds
//!   hold exactly for a union; the clamp only absorbs `f64 → f32` rounding), so areas never
//!   decrease towards the root.
//! - **Order**: the records of a mesh are sorted by area ascending, ties by creation order
//!   (stable; placed points first, in placement order), with parent links into that order
//!   ([`PointRecord::parent`], [`NO_PARENT`] for a cell's root). A second order, the **cut
//!   order**, sorts them by [`PointRecord::parent_area`] ascending (stable), for the cut's range.
//! - **Selection** at view depth `d` of a tree of scale `s`, with `k = pixels / C` per threshold
//!   ([`area_per_depth2`]; `C` of [`crate::metric::metric_constant`], C Eq. 4.2 corrected):
//!   - **interval** (C§4.6.3, the seed's): draw a record iff `d²·k_min ≤ A·s² ≤ d²·k_max`
//!     ([`interval_keep`]). Not a cut of the hierarchy (slip (c)): a parent and its child can
//!     both be drawn (a double) or a path can skip from above `max` to below `min` (a hole);
//!     the reference counts both per placed point.
//!   - **cut** (ours): draw a record iff `lower·s² ≤ d²·k_max < parent_area·s²`
//!     ([`cut_keep`]) with `lower` = its area, or 0 for a placed point (the finest level has
//!     nothing finer to fall back to). Areas never decrease towards a root and a root's
//!     `parent_area` is [`ROOT_PARENT_AREA`], so on every path from a placed point to its root
//!     exactly one record passes: each placed point is represented exactly once, at every depth.
//!     `min_point` does not apply in cut mode.
//!   - Both compare `f32` products of the same `f32` values on both sides (no division, no
//!     square root: WGSL's `*` is correctly rounded, its `/` is not).
//!   - **Batch range** (trees at depths `[lo, hi]`, scales `[s_min, s_max]`): interval mode
//!     `[first A·s_max² ≥ lo²·k_min, first A·s_min² > hi²·k_max)` in area order; cut mode
//!     `[first P·s_max² > lo²·k_max, len)` in cut order (`P` = `parent_area`), by binary search
//!     ([`interval_range`], [`cut_range`]). Rounding to nearest is monotone, so every tree's own
//!     drawn records lie in its batch's range (conservative); a cut range holds the drawn
//!     records and their ancestors only (about twice the drawn count in a binary hierarchy).
//! - **Safe change distance** (C§4.4.3, C§4.6.3): beyond
//!   `D_c = max(√(C·A_min_tree/MinTreeLevelPointSize), √(C·A_keep/MaxTreeLevelPointSize))`
//!   ([`change_distance`]) a tree is drawn from its whole-tree points alone: every cell-level
//!   point not copied into the whole-tree set covers at most `MinTreeLevelPointSize` pixels and
//!   every triangle but the tolerated biggest `TriangleCutOffToleration` fraction at most
//!   `MaxTreeLevelPointSize`. `A_keep` is the area of the **first non-discardable** triangle
//!   (slip (d): C§4.4.3's reading, the safe one), triangles ranked by opaque area.
//! - **Detail presets**: Table 5.2's five settings, [`DetailPreset`] and [`DetailSizes`], in
//!   the seed's pixels (its constant was 4x too large, `crate::metric`: pass `seed = true` to
//!   [`crate::metric::metric_constant`] to reproduce its behaviour).
//!
//! ## The point command path (issue 33 item 1: both backends draw it)
//! What the reference does (`reference/src/draw.rs`, `reference/src/points.rs` `PointLod`):
//! selection is unchanged (the LOD1 commands are the billboards' own, so coalescing, ordering,
//! `refine`, occlusion and subsets apply as they are); under `lod1 = points` the draw expands
//! each instance of a LOD1 command into the records of its tree's own range (in the mode's
//! order) that [`point_keep`] keeps at the tree's centre depth and drawn scale, each a square of
//! half side [`point_half_side`] about [`point_centre`] in the camera's `right`/`up` plane (so
//! it projects to an axis-aligned square of exactly `A·s²·C/d²` pixels at its own depth), flat
//! colour, depth-tested, fading like the billboard it replaces. The per-tree range visits
//! exactly the kept records under the interval rule and the kept ones and their ancestors under
//! the cut; the GPU design below replaces it with the batch's range and degenerate quads, which
//! draws the same records in the same order (the keep test decides, not the range).
//!
//! The GPU twin (`gpu/src/draw.rs`, `gpu/src/shaders/point_commands.wgsl`, `draw.wgsl`):
//! Points cannot go through the mesh path: [`crate::emit_command`] encodes the command slot in
//! `base_vertex = slot << COMMAND_SHIFT`, which leaves a draw `MAX_MESH_VERTICES` = 256 local
//! vertices, and a mesh holds up to about `2·n_pts` records of 6 vertices each. The far level's
//! trick (`crate::far`: an iota index range, the vertex stage pulls its primitive) extends to
//! points by moving the records into the **instances**:
//! - selection is untouched (every GPU selection path emits its LOD1 commands as today); under
//!   `lod1 = points` the draw copies the frame's commands into a buffer of its own and one
//!   compute invocation per slot (`point_commands.wgsl`, no loop) rewrites each LOD1 command of
//!   a mesh of `n` records into `index_count = 6` over the iota range (the packed geometry's
//!   far range), `instance_count = trees × n`, `first_instance = first_instance × n`, keeping
//!   `base_vertex` (the slot) so the draw still finds its `CommandData`;
//! - the vertex stage decodes instance `i` as indirection entry `i / n` and record rank
//!   `i % n` in the mode's order (area order, or the cut order read through its permutation):
//!   exact `u32` division, no per-frame array, no atomics, and the instances run tree by tree,
//!   record by record, the reference's draw order (blending and depth ties agree);
//! - it applies [`point_keep`] with the tree's own depth and drawn scale (a failed record is a
//!   degenerate quad, as the draw distance's discarded trees) and otherwise expands a
//!   camera-facing square of half side [`point_half_side`] about [`point_centre`], flat colour.
//!   A root's `parent_area · s²` overflows to +∞ for `s > 1`: the WGSL twin tests
//!   `parent == NO_PARENT` first rather than rely on overflow.
//!
//! Chosen over the proposal of a per-slot range (`[i0, i0 + n)` from the batch's depth and
//! scale bounds): that needs the batch's bounds, a loop over its trees (llvmpipe stops loops
//! at 65,535 iterations) or a change to every selection path; the whole mesh per tree costs
//! degenerate quads instead (every record is visited, the keep test decides), which is the
//! simplest path that draws the reference's records in its order. The ranges
//! ([`interval_range`], [`cut_range`]) remain the optimisation to take when the vertex work
//! shows in a measurement. Rejected: non-indexed `draw_indirect` with `first_vertex = 6·i0`
//! (frees the 256 limit but loses `base_vertex`, the slot's only channel); a compaction pass
//! writing kept `(tree, record)` pairs (the `refine` pattern) saves degenerate quads but makes
//! the order atomic (multiset parity instead of exact).
//!
//! In `Params` (issue 33 item 1, the draw): `lod1` ([`Lod1`]) selects points as the level past
//! the mesh, `point_select`, `point_detail` ([`DetailPreset`]) and `point_count` (`N_pts`)
//! configure it ([`PointParams::from_params`], [`draws_points`]). They are rows of the
//! parameter table (CLI flags, sweep keys), walked on both backends by the draw stage's row of
//! the stage table; `crate::Params::validate` checks them through the table like every field.

use bytemuck::{Pod, Zeroable};

use crate::ParamError;

crate::modes::modes! {
    /// What stands for a tree past the mesh level (`Params::lod1`, issue 33).
    pub enum Lod1 {
        /// The thesis's billboard (E§3.3).
        Billboard = 0 => "billboard" ("E§3.3"),
        /// Celba's point hierarchy, drawn as camera-facing squares (C§4.4, §4.6.3).
        Points = 1 => "points" ("C§4.4"),
    }
}

crate::modes::modes! {
    /// How a merged point's area is computed from the squares below it (module docs).
    pub enum UnionMode {
        /// The exact area of the union of the squares (Klee's measure, sweep + segment tree).
        Exact = 0 => "exact" ("Klee, ours"),
        /// Alg. 6 as printed: per sweep strip, width × the active squares' hull height.
        SeedHull = 1 => "seed-hull" ("C Alg. 6"),
    }
}

crate::modes::modes! {
    /// Which records of a point hierarchy a tree draws at a depth (module docs).
    pub enum PointSelect {
        /// The seed's rule: every record whose screen area lies in `[min, max]`.
        Interval = 0 => "interval" ("C§4.6.3"),
        /// Each placed point exactly once: `A_s(record) ≤ max < A_s(parent)`.
        Cut = 1 => "cut" ("ours, hole-free"),
    }
}

crate::modes::modes! {
    /// Table 5.2's five metric settings (C§5.2).
    pub enum DetailPreset {
        /// "Extra high".
        ExtraHigh = 0 => "extra-high" ("C Table 5.2"),
        /// "High".
        High = 1 => "high" ("C Table 5.2"),
        /// "Normal".
        Normal = 2 => "normal" ("C Table 5.2"),
        /// "Low".
        Low = 3 => "low" ("C Table 5.2"),
        /// "Extra low".
        ExtraLow = 4 => "extra-low" ("C Table 5.2"),
    }
}

/// The screen-area thresholds of one detail setting, in pixels (C Table 5.2's "size"s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DetailSizes {
    /// `MinPointSize`: a cell-level point smaller than this is not drawn (interval mode).
    pub min_point: f32,
    /// `MaxPointSize`: a cell-level point larger than this is not drawn.
    pub max_point: f32,
    /// `MinGeometrySize`: triangles at least this large are drawn.
    pub min_triangle: f32,
    /// `MinTreeLevelPointSize`: the whole-tree node's lower bound (and the change distance).
    pub min_tree_point: f32,
    /// `MaxTreeLevelPointSize`: the whole-tree node's upper bound (and the change distance).
    pub max_tree_point: f32,
}

/// Table 5.2, "Extra high".
pub const DETAIL_EXTRA_HIGH: DetailSizes = DetailSizes {
    min_point: 1.0,
    max_point: 5.0,
    min_triangle: 5.0,
    min_tree_point: 1.0,
    max_tree_point: 5.0,
};
/// Table 5.2, "High".
pub const DETAIL_HIGH: DetailSizes = DetailSizes {
    min_point: 1.0,
    max_point: 5.0,
    min_triangle: 5.0,
    min_tree_point: 4.0,
    max_tree_point: 10.0,
};
/// Table 5.2, "Normal".
pub const DETAIL_NORMAL: DetailSizes = DetailSizes {
    min_point: 5.0,
    max_point: 10.0,
    min_triangle: 10.0,
    min_tree_point: 7.0,
    max_tree_point: 15.0,
};
/// Table 5.2, "Low".
pub const DETAIL_LOW: DetailSizes = DetailSizes {
    min_point: 7.0,
    max_point: 15.0,
    min_triangle: 15.0,
    min_tree_point: 10.0,
    max_tree_point: 20.0,
};
/// Table 5.2, "Extra low".
pub const DETAIL_EXTRA_LOW: DetailSizes = DetailSizes {
    min_point: 10.0,
    max_point: 20.0,
    min_triangle: 20.0,
    min_tree_point: 15.0,
    max_tree_point: 30.0,
};

impl DetailPreset {
    /// The preset's thresholds.
    pub fn sizes(self) -> DetailSizes {
        match self {
            DetailPreset::ExtraHigh => DETAIL_EXTRA_HIGH,
            DetailPreset::High => DETAIL_HIGH,
            DetailPreset::Normal => DETAIL_NORMAL,
            DetailPreset::Low => DETAIL_LOW,
            DetailPreset::ExtraLow => DETAIL_EXTRA_LOW,
        }
    }
}

/// The point LOD's build and selection settings (not in [`crate::Params`]: CPU preprocessing;
/// module docs). The seed's names are given where it has one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointParams {
    /// `N_pts`: points placed per mesh (C§4.4.4's "equal number of points as there is number of
    /// triangles" does not fit < 20-triangle cards; ours is a count per mesh).
    pub n_pts: u32,
    /// `MaxPointGroupSize` (Alg. 5). The seed gives no default.
    pub max_group: u32,
    /// `GridSizeX/Y/Z` (C§4.4.3 step 5, each 1..=10). Default one cell (one root per mesh): our
    /// meshes are small; the seed's 4x4x4 is [`SEED_GRID`], C§5.4's best 2x2x2.
    pub grid: [u32; 3],
    /// How merged areas are computed.
    pub union: UnionMode,
    /// Tries per point before the opaque-texel fallback (`NumberOfColorApproxRetries`, 10).
    pub retries: u32,
    /// The alpha test placement obeys: the draw's `Params::alpha_cutoff` (the seed's
    /// `MinAlphaValue`).
    pub alpha_cutoff: f32,
    /// `PointScaleFactor`: scales every point's side (its area by the square).
    pub scale_factor: f32,
    /// `PercentageOfUpliftPoints` (fraction in `[0, 1]`): the biggest cell-level records copied
    /// into the whole-tree node. The seed gives no default.
    pub uplift: f32,
    /// `TriangleCutOffToleration` (fraction in `[0, 1]`): the biggest triangles that may vanish
    /// at the change distance. 0: none (safe).
    pub triangle_cutoff: f32,
}

impl PointParams {
    /// The build settings of the point LOD drawn under `params` (issue 33): `point_count`
    /// points per mesh on a `point_grid³` grid, placed under the draw's `alpha_cutoff`; the rest
    /// the defaults.
    pub fn from_params(params: &crate::Params) -> Self {
        Self {
            n_pts: params.point_count,
            grid: [params.point_grid; 3],
            alpha_cutoff: params.alpha_cutoff.max(f32::MIN_POSITIVE),
            ..Self::default()
        }
    }
}

/// Whether `params` draw points as the second level (`lod1 = points` with `lod_levels >= 2`).
pub fn draws_points(params: &crate::Params) -> bool {
    params.lod1 == Lod1::Points as u32 && params.lod_levels >= 2
}

/// The seed's default grid (C§4.4.3, 4x4x4).
pub const SEED_GRID: [u32; 3] = [4, 4, 4];
/// Largest grid size per axis (the seed's "smaller than 11").
pub const MAX_POINT_GRID: u32 = 10;
/// Most points placed per mesh, 2^12 (a mesh then holds fewer than 2^13 records; the seed's
/// forests use a few hundred to a few thousand per tree). Lowered from 2^20 when the fields
/// became parameter-table rows (issue 33 item 1): the stage table's walk renders every row's
/// greatest value on both backends, and the GPU draw expands each LOD1 command into
/// `trees × records` quad instances (`gpu/src/shaders/point_commands.wgsl`), whose cost on
/// lavapipe grows with the count (measured at 2^14: 36-44 s per walk case, five cases, which
/// tripled `every_stage::walk_draw`; at 2^12 about a quarter) and whose `u32` instance index
/// `(indirection offset + trees) × records` would overflow past ~2000 trees at 2^20; at 2^12 it
/// holds up to ~524 000 trees (the GPU draw checks it and names `point_count` otherwise).
pub const MAX_POINTS_PER_MESH: u32 = 1 << 12;
/// Most placement tries per point.
pub const MAX_POINT_RETRIES: u32 = 64;

impl Default for PointParams {
    fn default() -> Self {
        Self {
            n_pts: 1024,
            max_group: 8,
            grid: [1, 1, 1],
            union: UnionMode::Exact,
            retries: 10,
            alpha_cutoff: 0.5,
            scale_factor: 1.0,
            uplift: 0.25,
            triangle_cutoff: 0.0,
        }
    }
}

impl PointParams {
    /// Checks every field's range ([`ParamError`] names the field and the value).
    pub fn validate(&self) -> Result<(), ParamError> {
        let err = |field: &'static str, value: String, reason: &'static str| {
            Err(ParamError {
                field,
                value,
                reason: reason.into(),
            })
        };
        if self.n_pts == 0 || self.n_pts > MAX_POINTS_PER_MESH {
            return err(
                "n_pts",
                self.n_pts.to_string(),
                "1 ..= 4096 points per mesh",
            );
        }
        if self.max_group == 0 {
            return err("max_group", self.max_group.to_string(), "at least 1");
        }
        if let Some(g) = self.grid.iter().find(|&&g| g == 0 || g > MAX_POINT_GRID) {
            return err("grid", g.to_string(), "each of x, y, z in 1 ..= 10");
        }
        if self.retries > MAX_POINT_RETRIES {
            return err("retries", self.retries.to_string(), "0 ..= 64");
        }
        if !(self.alpha_cutoff > 0.0 && self.alpha_cutoff <= 1.0) {
            return err(
                "alpha_cutoff",
                self.alpha_cutoff.to_string(),
                "in (0, 1] (0 would keep transparent texels)",
            );
        }
        if !(self.scale_factor > 0.0 && self.scale_factor <= 1e3) {
            return err(
                "scale_factor",
                self.scale_factor.to_string(),
                "in (0, 1000]",
            );
        }
        if !(0.0..=1.0).contains(&self.uplift) {
            return err("uplift", self.uplift.to_string(), "a fraction in [0, 1]");
        }
        if !(0.0..=1.0).contains(&self.triangle_cutoff) {
            return err(
                "triangle_cutoff",
                self.triangle_cutoff.to_string(),
                "a fraction in [0, 1]",
            );
        }
        Ok(())
    }
}

/// No parent: the record is a root of its cell.
pub const NO_PARENT: u32 = u32::MAX;
/// A root's `parent_area`: above every threshold (finite, so WGSL reads a plain number).
pub const ROOT_PARENT_AREA: f32 = f32::MAX;

/// One point of a mesh's point hierarchy, at the mesh's unit scale, in mesh-local coordinates
/// (module docs). 48 bytes; what the draw reads per point.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PointRecord {
    /// Position, mesh-local, m.
    pub pos: [f32; 3],
    /// Area, m² (a placed point's share, or a merged point's union).
    pub area: f32,
    /// The cut's lower bound: `area`, or 0 for a placed point (module docs).
    pub lower: f32,
    /// The parent's area, [`ROOT_PARENT_AREA`] for a root.
    pub parent_area: f32,
    /// Unit normal, octahedral, two 16-bit unorms ([`pack_normal`]).
    pub normal: u32,
    /// sRGB RGBA8 colour, straight alpha, `r` in the low byte ([`pack_rgba8`]).
    pub rgba8: u32,
    /// Parent's index in the mesh's area order, [`NO_PARENT`] for a root.
    pub parent: u32,
    /// Placed points below it (1 for a placed point).
    pub leaves: u32,
    /// Padding.
    pub _pad: [u32; 2],
}
const _: () = assert!(core::mem::size_of::<PointRecord>() == 48);

/// Packs a colour, `r` in the low byte.
pub fn pack_rgba8(c: [u8; 4]) -> u32 {
    u32::from_le_bytes(c)
}

/// Unpacks [`pack_rgba8`].
pub fn unpack_rgba8(w: u32) -> [u8; 4] {
    w.to_le_bytes()
}

/// Packs a direction octahedrally ([`crate::octahedral::octahedral_encode`], full sphere) into
/// two 16-bit unorms, `u` in the low half.
pub fn pack_normal(n: [f32; 3]) -> u32 {
    let [u, v] = crate::octahedral::octahedral_encode(n, false);
    let q = |x: f32| (x * 65535.0).round() as u32;
    q(u) | (q(v) << 16)
}

/// Unpacks [`pack_normal`] (a unit vector).
pub fn unpack_normal(w: u32) -> [f32; 3] {
    let u = (w & 0xffff) as f32 / 65535.0;
    let v = (w >> 16) as f32 / 65535.0;
    crate::octahedral::octahedral_decode([u, v], false)
}

/// Whether a level-0 texel of stored alpha `alpha` passes the alpha test at `cutoff`: the
/// sampler decodes alpha as `a / 255` and the draw discards alpha below the cutoff.
pub fn texel_opaque(alpha: u8, cutoff: f32) -> bool {
    alpha as f32 / 255.0 >= cutoff
}

/// Largest-remainder shares of `n` among `weights` (non-negative; all-zero gives all zeros):
/// `floor(n·w/Σw)` each, then one more to the largest fractional parts, ties to the lower index.
pub fn largest_remainder(weights: &[f64], n: u32) -> Vec<u32> {
    let total: f64 = weights.iter().sum();
    if total.is_nan() || total <= 0.0 || total.is_infinite() {
        return vec![0; weights.len()];
    }
    let quotas: Vec<f64> = weights.iter().map(|w| n as f64 * w / total).collect();
    let mut shares: Vec<u32> = quotas.iter().map(|q| q.floor() as u32).collect();
    let given: u32 = shares.iter().sum();
    let mut order: Vec<usize> = (0..weights.len()).collect();
    // Largest fraction first; stable sort keeps ties in index order.
    order.sort_by(|&a, &b| {
        let fa = quotas[a] - quotas[a].floor();
        let fb = quotas[b] - quotas[b].floor();
        fb.total_cmp(&fa)
    });
    for &i in order.iter().take(n.saturating_sub(given) as usize) {
        shares[i] += 1;
    }
    shares
}

/// A 32-bit integer hash of four words (placement's stratified samples; fixed, so placement is
/// deterministic and independent of thread count).
pub fn point_hash(a: u32, b: u32, c: u32, d: u32) -> u32 {
    let mut h = 0x9e37_79b9u32;
    for w in [a, b, c, d] {
        h ^= w.wrapping_mul(0x85eb_ca6b);
        h = h.rotate_left(13).wrapping_mul(5).wrapping_add(0xe654_6b64);
        h ^= h >> 16;
        h = h.wrapping_mul(0x7feb_352d);
        h ^= h >> 15;
    }
    h
}

/// A hash as a fraction in `[0, 1)` (its top 24 bits).
pub fn hash_unit(h: u32) -> f32 {
    (h >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Barycentric weights `(b1, b2)` of corners 1 and 2 for a uniform sample `(u, v) ∈ [0, 1)²` of
/// a triangle (the square-root warp): `b1 = √u·(1 − v)`, `b2 = √u·v`; corner 0 gets the rest.
pub fn triangle_sample(u: f32, v: f32) -> [f32; 2] {
    let r = u.sqrt();
    [r * (1.0 - v), r * v]
}

/// `pixels / C` (C Eq. 4.4 per unit depth²): the world area per `d²` that covers `pixels` at
/// view depth `d`, as the `f32` both sides multiply by `d²`.
pub fn area_per_depth2(c: f64, pixels: f32) -> f32 {
    (pixels as f64 / c) as f32
}

/// The interval rule (C§4.6.3): whether a record of area `area` of a tree of scale `scale` at
/// view depth `depth` is drawn, `d²·k_min ≤ A·s² ≤ d²·k_max` (`k` of [`area_per_depth2`]).
pub fn interval_keep(area: f32, scale: f32, depth: f32, k_min: f32, k_max: f32) -> bool {
    let a = area * (scale * scale);
    let d2 = depth * depth;
    d2 * k_min <= a && a <= d2 * k_max
}

/// The cut rule (module docs): `lower·s² ≤ d²·k_max < parent_area·s²`.
pub fn cut_keep(lower: f32, parent_area: f32, scale: f32, depth: f32, k_max: f32) -> bool {
    let s2 = scale * scale;
    let t = depth * depth * k_max;
    lower * s2 <= t && t < parent_area * s2
}

/// The per-depth² area factors `[k_min, k_max]` of a detail setting (`min_point`,
/// `max_point`, [`area_per_depth2`]) for the metric constant `c`: what the draw compares with.
pub fn point_thresholds(c: f64, sizes: &DetailSizes) -> [f32; 2] {
    [
        area_per_depth2(c, sizes.min_point),
        area_per_depth2(c, sizes.max_point),
    ]
}

/// Whether the draw keeps record `r` of a tree of scale `scale` whose centre lies at view depth
/// `depth` under `mode` ([`PointSelect`] as `u32`; module docs): [`interval_keep`] or
/// [`cut_keep`], a root's bound above every threshold tested by its [`NO_PARENT`] link (not by
/// the overflow of [`ROOT_PARENT_AREA`]` · s²`, which WGSL need not give). The draw's one keep
/// test, twinned by `point_keep` in `common.wgsl` (issue 33, C§4.6.3).
pub fn point_keep(r: &PointRecord, mode: u32, scale: f32, depth: f32, k: [f32; 2]) -> bool {
    if mode == PointSelect::Interval as u32 {
        return interval_keep(r.area, scale, depth, k[0], k[1]);
    }
    if r.parent == NO_PARENT {
        return r.lower * (scale * scale) <= depth * depth * k[1];
    }
    cut_keep(r.lower, r.parent_area, scale, depth, k[1])
}

/// The world-space centre of record position `pos` of a tree at `base` turned by the yaw of
/// sine `sin` and cosine `cos` and scaled by `scale`: `base + Rz(yaw)·(scale·pos)`, the mesh
/// vertex's transform (E§4.4).
pub fn point_centre(base: [f32; 3], sin: f32, cos: f32, scale: f32, pos: [f32; 3]) -> [f32; 3] {
    let p = [pos[0] * scale, pos[1] * scale, pos[2] * scale];
    [
        base[0] + (cos * p[0] - sin * p[1]),
        base[1] + (sin * p[0] + cos * p[1]),
        base[2] + p[2],
    ]
}

/// Half the side of a record's square at scale `scale`: `√(A·s²) / 2` (the square covers the
/// record's area, C§4.4.3's `D = √A`).
pub fn point_half_side(area: f32, scale: f32) -> f32 {
    (area * (scale * scale)).sqrt() * 0.5
}

/// The interval rule's range in area order for trees at depths `[lo, hi]` and scales
/// `[s_min, s_max]` (module docs): conservative, by binary search on `areas` (ascending).
pub fn interval_range(
    areas: &[f32],
    depth: [f32; 2],
    scale: [f32; 2],
    k_min: f32,
    k_max: f32,
) -> [u32; 2] {
    let (s_lo2, s_hi2) = (scale[0] * scale[0], scale[1] * scale[1]);
    let low = depth[0] * depth[0] * k_min;
    let high = depth[1] * depth[1] * k_max;
    let i0 = areas.partition_point(|&a| a * s_hi2 < low);
    let i1 = areas.partition_point(|&a| a * s_lo2 <= high);
    [i0 as u32, i1.max(i0) as u32]
}

/// The cut rule's range in cut order (`parent_areas` ascending) for trees at depths `[lo, hi]`
/// and scales `[s_min, s_max]` (module docs): `[first P·s_max² > lo²·k_max, len)`.
pub fn cut_range(parent_areas: &[f32], depth: [f32; 2], scale: [f32; 2], k_max: f32) -> [u32; 2] {
    let s_hi2 = scale[1] * scale[1];
    let t = depth[0] * depth[0] * k_max;
    let i0 = parent_areas.partition_point(|&p| p * s_hi2 <= t);
    [i0 as u32, parent_areas.len() as u32]
}

/// The safe change distance (module docs, C§4.6.3): `max(√(C·A_min_tree/min_tree_px),
/// √(C·A_keep/max_tree_px))`, at unit scale (a tree of scale `s` changes at `s·D_c`).
pub fn change_distance(
    c: f64,
    min_tree_area: f64,
    keep_triangle_area: f64,
    min_tree_px: f64,
    max_tree_px: f64,
) -> f64 {
    let points = crate::metric::depth_for_pixels(c, min_tree_area, min_tree_px);
    let triangles = crate::metric::depth_for_pixels(c, keep_triangle_area, max_tree_px);
    points.max(triangles)
}

/// The square of a point of area `area` at `pos` projected on the **XZ plane** (slip (b): the
/// seed's vertical XY plane in its Y-up world), as `[x0, z0, x1, z1]`.
pub fn square_xz(pos: [f32; 3], area: f32) -> [f64; 4] {
    let h = (area.max(0.0) as f64).sqrt() * 0.5;
    let (x, z) = (pos[0] as f64, pos[2] as f64);
    [x - h, z - h, x + h, z + h]
}

/// The area of the union of axis-aligned rectangles `[x0, y0, x1, y1]` by `mode` (module docs).
pub fn union_area(rects: &[[f64; 4]], mode: UnionMode) -> f64 {
    match mode {
        UnionMode::Exact => klee_area(rects),
        UnionMode::SeedHull => seed_hull_area(rects),
    }
}

fn rect_area(r: &[f64; 4]) -> f64 {
    (r[2] - r[0]).max(0.0) * (r[3] - r[1]).max(0.0)
}

/// Sweep events: `(x, +1 start / -1 end, rectangle)`, sorted by x, starts before ends at a tie
/// (order within a tie does not change any area: the strip between them is 0 wide).
fn events(rects: &[[f64; 4]]) -> Vec<(f64, i32, usize)> {
    let mut ev: Vec<(f64, i32, usize)> = rects
        .iter()
        .enumerate()
        .filter(|(_, r)| rect_area(r) > 0.0)
        .flat_map(|(i, r)| [(r[0], 1, i), (r[2], -1, i)])
        .collect();
    ev.sort_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cmp(&a.1)).then(a.2.cmp(&b.2)));
    ev
}

/// Cover counts over the elementary segments `[ys[i], ys[i + 1])` (Klee's sweep).
struct SegmentTree<'a> {
    ys: &'a [f64],
    count: Vec<i32>,
    covered: Vec<f64>,
}

impl SegmentTree<'_> {
    /// Adds `delta` to the cover count of segments `[ab[0], ab[1])` below `node` (segments
    /// `[l, r)`), and refreshes the covered length.
    fn update(&mut self, node: usize, l: usize, r: usize, ab: [usize; 2], delta: i32) {
        if ab[1] <= l || r <= ab[0] {
            return;
        }
        if ab[0] <= l && r <= ab[1] {
            self.count[node] += delta;
        } else {
            let mid = (l + r) / 2;
            self.update(2 * node, l, mid, ab, delta);
            self.update(2 * node + 1, mid, r, ab, delta);
        }
        self.covered[node] = if self.count[node] > 0 {
            self.ys[r] - self.ys[l]
        } else if r - l == 1 {
            0.0
        } else {
            self.covered[2 * node] + self.covered[2 * node + 1]
        };
    }
}

/// Klee's measure in 2D, exact: a sweep over x with a segment tree of cover counts over the
/// compressed y coordinates, `O(n log n)`.
pub fn klee_area(rects: &[[f64; 4]]) -> f64 {
    let ev = events(rects);
    if ev.is_empty() {
        return 0.0;
    }
    let mut ys: Vec<f64> = ev
        .iter()
        .flat_map(|&(_, _, i)| [rects[i][1], rects[i][3]])
        .collect();
    ys.sort_by(f64::total_cmp);
    ys.dedup();
    let m = ys.len() - 1; // elementary y segments (m ≥ 1: every live rectangle has y0 < y1)
    let mut tree = SegmentTree {
        ys: &ys,
        count: vec![0; 4 * m],
        covered: vec![0.0; 4 * m],
    };
    let index = |y: f64| ys.partition_point(|&v| v < y);
    let mut area = 0.0;
    let mut prev_x = ev[0].0;
    for &(x, delta, i) in &ev {
        area += (x - prev_x) * tree.covered[1];
        prev_x = x;
        let (a, b) = (index(rects[i][1]), index(rects[i][3]));
        tree.update(1, 0, m, [a, b], delta);
    }
    area
}

/// Alg. 6 as the seed describes it (C§4.4.3): one rectangle's area; for two, the sum less the
/// intersection (exact); for more, a sweep over x that adds `(X − X_prev)·(MaxY − MinY)` of the
/// squares active over the strip (the hull of their y extents, not their union: slip (a)). The
/// printed pseudo-code updates the height list *before* adding the strip, which would weight
/// each strip by the next event's set (a disjoint pair of squares would lose one and gain the
/// gap); we read it as the set over the strip.
pub fn seed_hull_area(rects: &[[f64; 4]]) -> f64 {
    let live: Vec<[f64; 4]> = rects
        .iter()
        .copied()
        .filter(|r| rect_area(r) > 0.0)
        .collect();
    match live.len() {
        0 => return 0.0,
        1 => return rect_area(&live[0]),
        2 => {
            let (a, b) = (live[0], live[1]);
            let inter = [
                a[0].max(b[0]),
                a[1].max(b[1]),
                a[2].min(b[2]),
                a[3].min(b[3]),
            ];
            return rect_area(&a) + rect_area(&b) - rect_area(&inter);
        }
        _ => {}
    }
    let ev = events(&live);
    let mut active: Vec<usize> = Vec::new();
    let mut area = 0.0;
    let mut prev_x = ev[0].0;
    for &(x, delta, i) in &ev {
        if !active.is_empty() {
            let lo = active
                .iter()
                .map(|&k| live[k][1])
                .fold(f64::INFINITY, f64::min);
            let hi = active
                .iter()
                .map(|&k| live[k][3])
                .fold(f64::NEG_INFINITY, f64::max);
            area += (x - prev_x) * (hi - lo);
        }
        prev_x = x;
        if delta > 0 {
            active.push(i);
        } else if let Some(p) = active.iter().position(|&k| k == i) {
            active.swap_remove(p);
        }
    }
    area
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_5_2_is_the_seeds() {
        let rows: Vec<[f32; 5]> = DetailPreset::ALL
            .iter()
            .map(|p| {
                let s = p.sizes();
                [
                    s.min_point,
                    s.max_point,
                    s.min_triangle,
                    s.min_tree_point,
                    s.max_tree_point,
                ]
            })
            .collect();
        assert_eq!(
            rows,
            vec![
                [1.0, 5.0, 5.0, 1.0, 5.0],
                [1.0, 5.0, 5.0, 4.0, 10.0],
                [5.0, 10.0, 10.0, 7.0, 15.0],
                [7.0, 15.0, 15.0, 10.0, 20.0],
                [10.0, 20.0, 20.0, 15.0, 30.0],
            ]
        );
    }

    #[test]
    fn klee_and_hull_on_known_shapes() {
        // Two disjoint unit squares: 2 (the literal pseudo-code would give 1).
        let two = [[0.0, 0.0, 1.0, 1.0], [2.0, 0.0, 3.0, 1.0]];
        assert_eq!(klee_area(&two), 2.0);
        assert_eq!(seed_hull_area(&two), 2.0);
        // Three squares stacked with a gap in y: the hull fills the gap.
        let three = [
            [0.0, 0.0, 1.0, 1.0],
            [0.0, 2.0, 1.0, 3.0],
            [0.5, 0.0, 1.5, 1.0],
        ];
        assert_eq!(klee_area(&three), 2.5);
        assert_eq!(seed_hull_area(&three), 3.5);
        // A cross of two rectangles: 2·3 − 1.
        let cross = [[0.0, 1.0, 3.0, 2.0], [1.0, 0.0, 2.0, 3.0]];
        assert_eq!(klee_area(&cross), 5.0);
    }

    #[test]
    fn largest_remainder_gives_exactly_n() {
        let s = largest_remainder(&[1.0, 1.0, 1.0], 10);
        assert_eq!(s, vec![4, 3, 3]);
        assert_eq!(largest_remainder(&[0.0, 0.0], 5), vec![0, 0]);
        assert_eq!(largest_remainder(&[3.0, 0.0, 1.0], 8), vec![6, 0, 2]);
    }

    #[test]
    fn bad_point_params_name_the_field() {
        let bad = [
            (
                PointParams {
                    n_pts: 0,
                    ..Default::default()
                },
                "n_pts",
            ),
            (
                PointParams {
                    max_group: 0,
                    ..Default::default()
                },
                "max_group",
            ),
            (
                PointParams {
                    grid: [1, 11, 1],
                    ..Default::default()
                },
                "grid",
            ),
            (
                PointParams {
                    retries: 65,
                    ..Default::default()
                },
                "retries",
            ),
            (
                PointParams {
                    alpha_cutoff: 0.0,
                    ..Default::default()
                },
                "alpha_cutoff",
            ),
            (
                PointParams {
                    scale_factor: f32::NAN,
                    ..Default::default()
                },
                "scale_factor",
            ),
            (
                PointParams {
                    uplift: 1.5,
                    ..Default::default()
                },
                "uplift",
            ),
            (
                PointParams {
                    triangle_cutoff: -0.1,
                    ..Default::default()
                },
                "triangle_cutoff",
            ),
        ];
        for (p, field) in bad {
            assert_eq!(p.validate().unwrap_err().field, field);
        }
        PointParams::default().validate().unwrap();
    }

    #[test]
    fn bad_point_fields_of_params_name_the_field() {
        let base = crate::Params::default();
        let bad = [
            (crate::Params { lod1: 2, ..base }, "lod1"),
            (
                crate::Params {
                    point_select: 2,
                    ..base
                },
                "point_select",
            ),
            (
                crate::Params {
                    point_detail: 5,
                    ..base
                },
                "point_detail",
            ),
            (
                crate::Params {
                    point_count: 0,
                    ..base
                },
                "point_count",
            ),
            (
                crate::Params {
                    lod1: Lod1::Points as u32,
                    lod_levels: 3,
                    far_start: 4000.0,
                    ..base
                },
                "lod1",
            ),
        ];
        for (p, field) in bad {
            let e = p.validate().unwrap_err();
            assert_eq!(e.field, field, "{e}");
        }
        crate::Params {
            lod1: Lod1::Points as u32,
            ..base
        }
        .validate()
        .unwrap();
    }

    #[test]
    fn normals_and_colours_round_trip() {
        for n in [
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.6, 0.0, -0.8],
        ] {
            let m = unpack_normal(pack_normal(n));
            assert!((0..3).all(|k| (m[k] - n[k]).abs() < 1e-3), "{n:?} -> {m:?}");
        }
        assert_eq!(unpack_rgba8(pack_rgba8([1, 2, 3, 4])), [1, 2, 3, 4]);
    }
}
