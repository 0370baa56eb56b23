//! Occlusion culling against a depth pyramid (issue 31; beyond the seeds: E§7 lists finer culling
//! as future work, and G§3's octree is the seeds' only visibility structure). Every formula both
//! twins use: the pyramid's layout and reduction, a tree's conservative screen rectangle and
//! nearest depth, the pyramid level and texels that cover the rectangle, the cull decision, and
//! which trees are occluders. The reference twins are `reference/src/pyramid.rs` and
//! `reference/src/occlude.rs`; the WGSL twins `pyramid.wgsl` and `occlude.wgsl`.
//!
//! ## The frame with occlusion culling
//! 1. **Early pass**: the frame's commands restricted to the *occluders* ([`is_occluder`]) are drawn,
//!    ground first, into the colour, depth and id targets, exactly as the frame would draw them.
//!    `single` takes the trees of mesh commands whose footprint starts within `occluder_depth`
//!    behind the nearest such footprint in view ([`nearest_occluder_depth`]: a min-reduction
//!    over the frame's mesh trees before the split); `two-phase` takes the trees that passed the
//!    test in the previous frame of a camera path (niagara's `drawculllate` history), and on a
//!    path's first frame, with no history, `single`'s ([`effective_mode`]; niagara draws nothing
//!    early there). The depth is relative to the nearest tree, not to the eye, so that one
//!    `occluder_depth` serves a camera in the canopy and one 300 m above it: from `stress`'
//!    medium camera no tree starts within 100 m of the eye.
//! 2. **Pyramid** ([`pyramid_levels`], [`pyramid_reduce`]): level 0 is the depth buffer; texel
//!    `(i, j)` of level `L + 1` is the **largest** (farthest, depth test LESS) of texels
//!    `(2i..2i+1, 2j..2j+1)` of level `L` that exist. Level `L` is
//!    `ceil(W / 2^L) x ceil(H / 2^L)`, down to 1x1. So texel `(i, j)` of level `L` is the exact
//!    maximum over pixels `[i·2^L, (i+1)·2^L) x [j·2^L, (j+1)·2^L)` clipped to the frame: correct
//!    for every size, odd and non-power-of-two included, with no sampler involved.
//! 3. **Late test** ([`occlusion_bounds`], [`pyramid_level_for`], [`pyramid_texels_max`]): every
//!    tree of every command (in `single`, every tree not drawn early) is bounded by the eight
//!    corners of the axis-aligned cube around its footprint sphere (`reference::draw::
//!    tree_footprint_radius`: mesh and billboard quad, for any eye), widened by
//!    [`OCCLUSION_SLACK_REL`]. Their screen box widened by [`OCCLUSION_SLACK_PX`] gives the
//!    inclusive pixel rectangle, their least NDC depth less [`OCCLUSION_Z_SLACK`] the tree's
//!    nearest depth. The level is the **smallest** whose texels cover the rectangle with at most
//!    2x2 texels; all of them are read. The tree is culled when its nearest depth is **greater**
//!    than their maximum ([`occluded`]).
//! 4. **Final pass** ([`OcclusionOrder`]): under `exact` the targets are cleared again and the
//!    commands restricted to every tree not culled, the early ones included, are drawn in the
//!    commands' own order, ground first; under `reorder` (niagara's and Bevy's late pass) the
//!    commands restricted to the trees neither drawn early nor culled are drawn onto the early
//!    pass's targets.
//!
//! Commands are never removed or reordered (as in `refine`): the early and final selections are
//! the frame's commands with shorter instance lists over a `4m`-entry indirection
//! ([`occlusion_slot`]), so `base_vertex`, the command data and the draw stage are unchanged.
//!
//! Why two orders: `reorder` draws each tree once, but every early tree before every late one,
//! and a depth test LESS keeps the first of two equal depths: where an early and a late fragment
//! tie, the frame changes. Ties are not rare at distance: depth near 1 has a step of 6e-8, about
//! 0.1 m at 1 km with our 0.5 m near plane, and `stress` puts twenty trees in a 320x180 pixel;
//! the first sweep found such a pixel in 5 of 40 medium frames. `exact` makes the frame the
//! frame without culling, less trees that had no pixel, bit for bit, and pays for it by drawing
//! the early trees twice: at `stress`' close camera, where the nearest trees fill most of the
//! frame, that is more fragments than culling saves (`experiments/results/occlusion/`).

//! ## Why the test is conservative (no false cull), by construction
//! - Every fragment a tree can write lies in its footprint sphere, so in the cube; the cube's
//!   projection lies in the convex hull of its corners' projections when every corner is in front
//!   of the eye (clip `w` above half the near distance; otherwise the tree is never culled), so
//!   every pixel centre it covers lies in the rectangle (the slack covers rounding of the
//!   projection and the rasterizer's sub-pixel snapping, both far below a pixel).
//! - NDC depth is increasing in view depth, and view depth is linear, so the cube's least depth is
//!   at a corner and bounds every fragment's depth from below; [`OCCLUSION_Z_SLACK`] covers the
//!   interpolation's rounding.
//! - The chosen texels cover the whole rectangle and each holds the maximum of its block, so their
//!   maximum is at least the early pass's depth at every pixel of the rectangle.
//! - So a culled tree has, at every pixel it could cover, an early fragment strictly nearer. The
//!   early pass writes only fragments that are opaque where they are written in every dithered
//!   fade mode; under `alpha` ([`may_occlude`]) commands that blend (fading, or far-field subset
//!   weights) are never occluders. A culled tree therefore loses every depth test it would have
//!   taken part in: the frame is the same without it.
//!
//! ## Where the peers are not conservative (the test suite shows the first)
//! - niagara (`drawcull.comp`) picks the level `floor(log2(max(w, h)))` and reads a 2x2 footprint
//!   with a reduction sampler ([`pyramid_level_floor`]): a rectangle `w` pixels wide with
//!   `2^L <= w < 2^(L+1)` can span three texels of level `L`, and the third is never read. Its
//!   pyramid also starts at the previous power of two of the viewport, so the texels of odd and
//!   non-power-of-two sizes do not cover whole blocks (Bevy's docs call such viewports "a little
//!   bugged").
//! - niagara's meshlet test compares the far plane of a sphere that straddles it; ours never culls
//!   a tree any of whose corners is at or behind half the near distance.
//!
//! ## Images
//! Under `exact`, in every dithered fade mode (and `none`), the frame is bit-identical to the
//! frame without occlusion culling: the final pass is that frame's draw less culled trees, each of
//! which lost every depth test it took part in, strictly (no tie: it lies behind an early fragment
//! that the final pass draws too). Under `reorder` a pixel can differ only where two fragments tie
//! in depth. Under `alpha` a culled tree can still show through a blended fade-band fragment drawn
//! after it and before its occluder. The tests count and classify both.

use glam::{Mat4, Vec3, Vec4};

use crate::{CommandData, FadeMode, LOD_MESH, Params, SubsetMode};

crate::modes::modes! {
    /// Occlusion culling of the frame (module docs).
    pub enum Occlusion {
        /// No occlusion culling: one pass, today's frame.
        Off = 0 => "off",
        /// Occluders are the nearest mesh trees (within `occluder_depth`), drawn first.
        Single = 1 => "single",
        /// Occluders are the trees that passed the previous frame's test (niagara's two phases).
        TwoPhase = 2 => "two-phase",
    }
}

crate::modes::modes! {
    /// How the passes of a frame with occlusion culling are ordered (module docs, step 4).
    pub enum OcclusionOrder {
        /// The early pass is a depth pre-pass; the final pass clears and draws every tree not
        /// culled in the frame's own order: bit-identical frames, early trees drawn twice.
        Exact = 0 => "exact",
        /// niagara's and Bevy's: the late pass draws the trees not drawn early onto the early
        /// pass's targets: each tree drawn once, and a depth tie between an early and a late
        /// fragment can go the other way.
        Reorder = 1 => "reorder",
    }
}

/// Whether the final pass's lists hold the early trees too (`exact`: it clears and draws the
/// frame again) or only the trees not drawn early (`reorder`: it draws onto the early pass).
pub fn final_includes_early(order: u32) -> bool {
    order != OcclusionOrder::Reorder as u32
}

/// Pixels of slack around a tree's projected rectangle: pixel centres lie half a pixel inside a
/// pixel, and the projection's rounding and the rasterizer's sub-pixel snapping (1/256 px on
/// lavapipe) are far below a pixel; two pixels cover both with room (as the draw's mask test,
/// `reference::draw::tree_footprint_meets_mask`).
pub const OCCLUSION_SLACK_PX: f32 = 1.0;

/// Relative slack on the footprint radius, and on the centre's coordinates: the vertex stage's
/// world positions are rounded `f32` sums, a few ulps of the coordinates' size.
pub const OCCLUSION_SLACK_REL: f32 = 1.0e-5;

/// Slack taken off a tree's nearest NDC depth: 16 ulps at depth 1 (`2^-20`). The reference's
/// interpolated depth is at least its smallest vertex depth less one ulp
/// (`reference::raster::setup`'s `depth_lower_bound`); the GPU's interpolation and the vertex
/// stage's own rounding are within a few ulps of it.
pub const OCCLUSION_Z_SLACK: f32 = 1.0 / (1u32 << 20) as f32;

/// Most pyramid levels: a side of up to `2^15` pixels (more than the targets' limit).
pub const MAX_PYRAMID_LEVELS: u32 = 16;

/// One level of the depth pyramid: its size and where its texels start in the flat array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PyramidLevel {
    /// Texels per row: `ceil(W / 2^L)`.
    pub width: u32,
    /// Rows: `ceil(H / 2^L)`.
    pub height: u32,
    /// Index of texel `(0, 0)` in the flat array (levels follow each other, rows top-down).
    pub offset: u32,
}

/// The levels of the pyramid of a `width x height` depth buffer (module docs, step 2): level 0 is
/// the buffer, the last is 1x1. Sides must be at least 1.
pub fn pyramid_levels(width: u32, height: u32) -> Vec<PyramidLevel> {
    assert!(width >= 1 && height >= 1, "a pyramid of an empty buffer");
    let mut levels = Vec::new();
    let (mut w, mut h, mut offset) = (width, height, 0u32);
    loop {
        levels.push(PyramidLevel {
            width: w,
            height: h,
            offset,
        });
        if w == 1 && h == 1 {
            return levels;
        }
        offset += w * h;
        w = w.div_ceil(2);
        h = h.div_ceil(2);
    }
}

/// Texels of every level together (the flat array's length).
pub fn pyramid_len(width: u32, height: u32) -> usize {
    let last = *pyramid_levels(width, height).last().expect("a level");
    (last.offset + 1) as usize
}

/// Texel `(i, j)` of the level after `below` ([`pyramid_levels`]): the largest of the up to four
/// texels `(2i..2i+1, 2j..2j+1)` of `below` that exist, read by `texel(x, y)`.
pub fn pyramid_reduce(below: PyramidLevel, i: u32, j: u32, texel: impl Fn(u32, u32) -> f32) -> f32 {
    let (x0, y0) = (2 * i, 2 * j);
    let x1 = (x0 + 1).min(below.width - 1);
    let y1 = (y0 + 1).min(below.height - 1);
    texel(x0, y0)
        .max(texel(x1, y0))
        .max(texel(x0, y1))
        .max(texel(x1, y1))
}

/// A tree's rectangle in pixels (inclusive) and its nearest NDC depth (module docs, step 3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OcclusionRect {
    /// Leftmost pixel column.
    pub x0: u32,
    /// Top pixel row.
    pub y0: u32,
    /// Rightmost pixel column.
    pub x1: u32,
    /// Bottom pixel row.
    pub y1: u32,
    /// A lower bound of every fragment depth the tree can write.
    pub z_min: f32,
}

/// What bounds a tree on screen ([`occlusion_bounds`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OcclusionBound {
    /// A corner at or behind half the near distance (not all), or a non-finite value: never
    /// culled.
    Unbounded,
    /// The rectangle lies wholly outside the frame, or every corner is nearer than half the near
    /// distance (the near plane clips it all): the tree covers no pixel.
    Offscreen,
    /// The rectangle, clamped to the frame, and the nearest depth.
    Rect(OcclusionRect),
}

/// The screen rectangle and nearest depth of the sphere `(center, radius)` (a tree's footprint)
/// under `view_proj` in a `width x height` frame (module docs, step 3).
pub fn occlusion_bounds(
    view_proj: &Mat4,
    near: f32,
    center: [f32; 3],
    radius: f32,
    width: u32,
    height: u32,
) -> OcclusionBound {
    let c = Vec3::from(center);
    let r = radius * (1.0 + OCCLUSION_SLACK_REL) + c.abs().max_element() * OCCLUSION_SLACK_REL;
    if !(r.is_finite() && c.is_finite()) {
        return OcclusionBound::Unbounded;
    }
    let (half_w, half_h) = (width as f32 * 0.5, height as f32 * 0.5);
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (f32::MAX, f32::MIN, f32::MAX, f32::MIN);
    let mut z_lo = f32::MAX;
    let corners: [Vec4; 8] = core::array::from_fn(|k| {
        let corner = k as u32;
        let sign = |bit: u32| if corner & bit != 0 { r } else { -r };
        let p = c + Vec3::new(sign(1), sign(2), sign(4));
        *view_proj * Vec4::new(p.x, p.y, p.z, 1.0)
    });
    // Wholly nearer than half the near distance (behind the eye included): clipped away.
    if corners.iter().all(|clip| clip.w < 0.5 * near) {
        return OcclusionBound::Offscreen;
    }
    for clip in corners {
        if !clip.is_finite() || clip.w <= 0.5 * near {
            return OcclusionBound::Unbounded;
        }
        let x = (clip.x / clip.w) * half_w + half_w;
        let y = half_h - (clip.y / clip.w) * half_h;
        (x_lo, x_hi) = (x_lo.min(x), x_hi.max(x));
        (y_lo, y_hi) = (y_lo.min(y), y_hi.max(y));
        z_lo = z_lo.min(clip.z / clip.w);
    }
    let (x_lo, x_hi) = (x_lo - OCCLUSION_SLACK_PX, x_hi + OCCLUSION_SLACK_PX);
    let (y_lo, y_hi) = (y_lo - OCCLUSION_SLACK_PX, y_hi + OCCLUSION_SLACK_PX);
    if x_hi < 0.0 || y_hi < 0.0 || x_lo >= width as f32 || y_lo >= height as f32 {
        return OcclusionBound::Offscreen;
    }
    let px = |v: f32, size: u32| v.clamp(0.0, (size - 1) as f32) as u32;
    OcclusionBound::Rect(OcclusionRect {
        x0: px(x_lo.floor(), width),
        y0: px(y_lo.floor(), height),
        x1: px(x_hi.floor(), width),
        y1: px(y_hi.floor(), height),
        z_min: z_lo - OCCLUSION_Z_SLACK,
    })
}

/// The smallest level at which `rect` spans at most 2x2 texels (module docs, step 3), among
/// `levels` levels (the last is 1x1, where every rectangle spans one texel).
pub fn pyramid_level_for(rect: &OcclusionRect, levels: u32) -> u32 {
    let mut level = 0;
    while level + 1 < levels
        && ((rect.x1 >> level) - (rect.x0 >> level) > 1
            || (rect.y1 >> level) - (rect.y0 >> level) > 1)
    {
        level += 1;
    }
    level
}

/// niagara's level rule (`drawcull.comp`: `floor(log2(max(width, height)))` of the rectangle's
/// size in pixels), kept to show that it is not conservative: read with a 2x2 footprint from the
/// rectangle's top-left texel, it misses the third texel a rectangle can span. Not used by the
/// frame.
pub fn pyramid_level_floor(rect: &OcclusionRect) -> u32 {
    let size = (rect.x1 - rect.x0 + 1).max(rect.y1 - rect.y0 + 1);
    31 - size.leading_zeros()
}

/// The largest texel of level `level` among texels `(x0>>L ..= x1>>L) x (y0>>L ..= y1>>L)` of
/// `rect`, read by `texel(level, i, j)`; at most 2x2 texels at [`pyramid_level_for`]'s level.
pub fn pyramid_texels_max(
    rect: &OcclusionRect,
    level: u32,
    texel: impl Fn(u32, u32, u32) -> f32,
) -> f32 {
    let (i0, i1) = (rect.x0 >> level, rect.x1 >> level);
    let (j0, j1) = (rect.y0 >> level, rect.y1 >> level);
    let mut m = f32::MIN;
    for j in j0..=j1 {
        for i in i0..=i1 {
            m = m.max(texel(level, i, j));
        }
    }
    m
}

/// The cull decision: the tree's nearest depth lies strictly behind the farthest early depth under
/// its rectangle.
pub fn occluded(rect: &OcclusionRect, pyramid_max: f32) -> bool {
    rect.z_min > pyramid_max
}

/// Whether the trees of a command may be occluders: always in a dithered fade mode (each fragment
/// written is opaque); under `alpha` only commands that never blend: not fading, and not
/// billboards under a far-field subset (whose weights blend).
pub fn may_occlude(data: &CommandData, fade_mode: u32, subset_mode: u32) -> bool {
    fade_mode != FadeMode::Alpha as u32
        || (data.fading == 0 && (data.billboard == 0 || subset_mode == SubsetMode::Off as u32))
}

/// The mode the early rule follows: `two-phase` without a history (a path's first frame) is
/// `single` (module docs, step 1).
pub fn effective_mode(mode: u32, has_history: bool) -> u32 {
    if mode == Occlusion::TwoPhase as u32 && !has_history {
        Occlusion::Single as u32
    } else {
        mode
    }
}

/// The view depth `single`'s occluder depth counts from: the least `depth_near` (the
/// footprint's nearest view depth, `view_interval(..).lo`) over the trees of mesh commands that
/// [`may_occlude`] and whose bound is not off screen, clamped to at least 0; 0 when there is none.
/// `depths` yields those trees' `depth_near`.
pub fn nearest_occluder_depth(depths: impl IntoIterator<Item = f32>) -> f32 {
    let m = depths.into_iter().fold(f32::INFINITY, f32::min);
    if m.is_finite() { m.max(0.0) } else { 0.0 }
}

/// Whether one tree of a command is drawn in the early pass (module docs, step 1), under the
/// [`effective_mode`] `mode`: under `single` a mesh command's tree whose footprint's nearest view
/// depth less [`nearest_occluder_depth`] (`depth_near`) is within `occluder_depth`; under `two-phase` a tree that passed the previous frame's test
/// (`visible_before`); never under `off`. Either way only trees of commands that
/// [`may_occlude`].
pub fn is_early(
    mode: u32,
    data: &CommandData,
    params: &Params,
    depth_near: f32,
    visible_before: bool,
) -> bool {
    if !may_occlude(data, params.fade_mode, params.subset_mode) {
        return false;
    }
    if mode == Occlusion::Single as u32 {
        data.lod == LOD_MESH && depth_near <= params.occluder_depth
    } else if mode == Occlusion::TwoPhase as u32 {
        visible_before
    } else {
        false
    }
}

/// The early pass's whole rule: [`is_early`], for a tree whose rectangle is not wholly off screen
/// (`bound`, [`occlusion_bounds`] of its footprint). Without the second test every tree behind
/// the eye or beside the view within `occluder_depth` was drawn early for no pixel: on `stress`'
/// close camera 271,739 early trees against 7,293 in view (grid batches straddle the frustum).
pub fn is_occluder(
    mode: u32,
    data: &CommandData,
    params: &Params,
    depth_near: f32,
    visible_before: bool,
    bound: &OcclusionBound,
) -> bool {
    is_early(mode, data, params, depth_near, visible_before)
        && !matches!(bound, OcclusionBound::Offscreen)
}

/// Where a command's kept trees go in the `4m`-entry indirection the occlusion stage writes over
/// an input indirection of `m` entries: `(2·phase + lod)·m + first_instance`, phase 0 early and
/// 1 final. A command's range is its own: the two LODs of one group share their input range, and
/// the commands of one LOD never overlap.
pub fn occlusion_slot(phase: u32, lod: u32, m: u32, first_instance: u32) -> u32 {
    (2 * phase + lod.min(1)) * m + first_instance
}

/// Work counters of the occlusion stages (module docs).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct OcclusionCounters {
    /// Trees drawn in the early pass.
    pub early: u32,
    /// Trees tested against the pyramid.
    pub tested: u32,
    /// Trees culled: behind the pyramid.
    pub occluded: u32,
    /// Trees culled: their rectangle lies outside the frame.
    pub offscreen: u32,
    /// Trees drawn in the final pass (every tree not culled, the early ones included).
    pub late: u32,
    /// Trees that were never bounded (a corner near or behind the eye).
    pub unbounded: u32,
    /// Explicit padding.
    pub _pad0: [u32; 2],
}
const _: () = assert!(core::mem::size_of::<OcclusionCounters>() == 32);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_halve_up_to_one_texel() {
        let l = pyramid_levels(5, 3);
        let sizes: Vec<_> = l.iter().map(|l| (l.width, l.height, l.offset)).collect();
        assert_eq!(sizes, [(5, 3, 0), (3, 2, 15), (2, 1, 21), (1, 1, 23)]);
        assert_eq!(pyramid_len(5, 3), 24);
        assert_eq!(pyramid_levels(1, 1).len(), 1);
        assert_eq!(pyramid_levels(1920, 1080).len(), 12);
    }

    #[test]
    fn the_level_spans_at_most_two_texels() {
        let r = OcclusionRect {
            x0: 3,
            y0: 0,
            x1: 10,
            y1: 1,
            z_min: 0.5,
        };
        let l = pyramid_level_for(&r, 12);
        assert!((r.x1 >> l) - (r.x0 >> l) <= 1);
        assert!(l == 0 || (r.x1 >> (l - 1)) - (r.x0 >> (l - 1)) > 1);
        // niagara's rule on a rectangle 15 pixels wide: level 3, where 7..=21 spans texels 0..=2.
        let wide = OcclusionRect { x0: 7, x1: 21, ..r };
        let f = pyramid_level_floor(&wide);
        assert_eq!(f, 3);
        assert_eq!(
            (wide.x1 >> f) - (wide.x0 >> f),
            2,
            "three texels, of which 2x2 reads two"
        );
    }
}
