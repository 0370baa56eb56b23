//! The far level (issue 32 items 1, 2 and 4): a third representation after the mesh (LOD0) and
//! the billboard (LOD1) that stands for **a whole hierarchy node** (many trees) with one cheap
//! primitive per cell. `--lod-levels 3` turns it on; `--far-lod` says which primitive.
//!
//! - **Octant impostors** (G§2): per node, the node's box is cut into `cs³` cells (G§2.4's
//!   clustering read in 3D, `cluster_size`); every cell holds **six colours**, the cell seen from
//!   each of its six sides (G§2.2), as RGBA8 (sRGB colour, linear alpha = the side's mean
//!   coverage). Drawn as a **sprite** (a quad facing the eye whose one colour mixes three sides,
//!   [`side_mix`]) or a **cube** (twelve triangles, one colour per face) (G§2.3). Cells whose
//!   every side has less than [`FAR_ALPHA_MIN`] coverage are dropped (G§2.4 "too little alpha").
//! - **Batch hulls** (E§7 future work): the node as one opaque convex mesh of at most
//!   [`MAX_HULL_TRIANGLES`] triangles that contains every tree's box, each triangle coloured by
//!   its normal from the node's six side colours ([`side_mix`] of the normal).
//!
//! ## Contract
//! - **Extent = content** (G§2.1 "tight" octants, the design study's recommended reading): a node's
//!   box is the box of its trees' spheres ([`crate::NodeMeta::box_center`], `extent`), not the
//!   octree cell, so a 250 m octant holding 30 m trees gives a 30 m tall box.
//! - **Sides**: side `2a` looks at the cell from `+axis a` (the eye on the `+a` side, the camera
//!   looking along `-a`), side `2a + 1` from `-axis a` ([`side_of`]).
//! - **Side weights** ([`side_weights`]): for a unit direction `v` from the cell towards the eye,
//!   `w_a = v_a²` on side `side_of(a, v_a ≥ 0)`: a partition of unity, exact on the axes
//!   (`v = ±e_a` gives that side alone). The seed leaves the weights open ("interpolated from
//!   three of the six side colours"); `|v_a| / Σ|v|` is the rejected alternative (not smooth on
//!   the diagonals' normals, and the same on the axes).
//! - **Selection** ([`far_eligible`]): a node that is drawn (in the frustum, within the draw
//!   distance) goes far when its whole view-depth interval lies at or beyond `far_start` (so every
//!   tree of it is beyond: the rule stays **conservative per tree** along the chain
//!   mesh → billboard → far) and its box covers fewer than `far_pixels` pixels by Celba's metric
//!   (C§4.6.3 Eq. 4.3, the corrected constant `C = f_px²`, [`crate::metric::metric_constant`]) with the
//!   box's area seen along the direction to the eye ([`box_area_along`]) at the interval's near
//!   end. An interior node that is not far but could have far descendants recurses.
//! - **Command encoding**: a far node emits one command with `lod = LOD_FAR`, one instance per
//!   cell (`first_instance` = the node's first cell, [`FarNode::cell_offset`]) and the index range
//!   of the primitive, an iota of local vertex ids `0..n` (`n` = [`CUBE_VERTICES`],
//!   [`SPRITE_VERTICES`], or 3 × the hull's triangles, at most `3 · MAX_HULL_TRIANGLES <
//!   MAX_MESH_VERTICES`, so `base_vertex`'s command encoding holds). The vertex stage pulls the
//!   corner from the cell ([`cube_corner`], [`sprite_corner`]) or the hull vertex
//!   ([`FarVertex`]) and passes the primitive's colour as a constant varying.
//! - **Alpha**: a far fragment is kept where its colour's alpha exceeds the frame pixel's dither
//!   threshold ([`crate::dither_threshold`]), the thesis's own screen-door, so a half-covered cell
//!   covers half its pixels with no sorting; kept fragments are opaque. Hulls are opaque.
//!
//! The bake (`reference/src/far_bake.rs`, twin `gpu/src/shaders/far_bake.wgsl`) fills the cells;
//! the cut (`hier_select`) selects; the draw (`draw`) draws.

use bytemuck::{Pod, Zeroable};

crate::modes::modes! {
    /// The far level's primitive (module docs).
    pub enum FarLod {
        /// A quad facing the eye per cell, one colour mixed from three sides.
        OctantSprite = 0 => "octant-sprite" ("G§2.3 sprite"),
        /// A colour cube per cell, one colour per face.
        OctantCube = 1 => "octant-cube" ("G§2.3 cube"),
        /// One opaque convex hull per node, coloured by face normal.
        Hull = 2 => "hull" ("E§7 batch hull"),
        /// A hierarchical impostor per planned node, rendered from the eye (`crate::impostor`).
        Impostor = 3 => "impostor" ("C§4.6.3 hierarchical impostor"),
    }
}

crate::modes::modes! {
    /// How an interior node's cells are made from its children's (G§2.2).
    pub enum ParentRule {
        /// The children's colours averaged, occlusion ignored (the seed).
        Average = 0 => "average" ("G§2.2"),
        /// Per side, the children composited front to back with "over" (occlusion-aware).
        Composite = 1 => "composite" ("beyond the seed"),
    }
}

/// `CommandData::lod` of a far command.
pub const LOD_FAR: u32 = 2;

/// The number of sides of a cell.
pub const SIDE_COUNT: usize = 6;

/// The largest `cluster_size` (G§6 used 12).
pub const MAX_CLUSTER_SIZE: u32 = 12;

/// Bake pixels per cell side: each side of a cell is the mean of `FAR_BAKE_PIXELS²` pixels.
pub const FAR_BAKE_PIXELS: u32 = 8;

/// A cell whose every side covers less than this is dropped (G§2.4): under one bake pixel of the
/// cell's `FAR_BAKE_PIXELS²`.
pub const FAR_ALPHA_MIN: f32 = 1.0 / (FAR_BAKE_PIXELS * FAR_BAKE_PIXELS) as f32;

/// The most triangles of a batch hull: `3 · 84 = 252` local vertices, under
/// [`crate::MAX_MESH_VERTICES`] (module docs).
pub const MAX_HULL_TRIANGLES: u32 = 84;

/// Local vertices of a cube: six faces of two triangles, not indexed (each vertex knows its face).
pub const CUBE_VERTICES: u32 = 36;

/// Local vertices of a sprite: two triangles.
pub const SPRITE_VERTICES: u32 = 6;

/// One cell of a node's far level (module docs): a box and its six side colours.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FarCell {
    /// Box centre.
    pub center: [f32; 3],
    /// Box half-size.
    pub extent: [f32; 3],
    /// Per side ([`side_of`]): RGBA8, sRGB colour and linear alpha, `r | g << 8 | b << 16 | a << 24`.
    pub colours: [u32; SIDE_COUNT],
}
const _: () = assert!(core::mem::size_of::<FarCell>() == 48);

/// Per hierarchy node: where its far level lies.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct FarNode {
    /// First cell in the cells array.
    pub cell_offset: u32,
    /// Number of kept cells (0: nothing to draw; such a node never goes far).
    pub cell_count: u32,
    /// First hull vertex in the hull vertex array.
    pub hull_offset: u32,
    /// Hull vertices, 3 per triangle (0 without a hull).
    pub hull_count: u32,
}
const _: () = assert!(core::mem::size_of::<FarNode>() == 16);

/// One vertex of a batch hull's triangle list, with its triangle's colour.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FarVertex {
    /// Position.
    pub position: [f32; 3],
    /// The triangle's RGBA8 colour (as [`FarCell::colours`]).
    pub colour: u32,
}
const _: () = assert!(core::mem::size_of::<FarVertex>() == 16);

/// A hierarchy's far level: per node its [`FarNode`], and the cells and hull vertices they
/// index. What `far_bake` writes and the cut and the draw read.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FarLevel {
    /// Per hierarchy node (same index as the hierarchy's nodes).
    pub nodes: Vec<FarNode>,
    /// Every node's kept cells, node by node.
    pub cells: Vec<FarCell>,
    /// Every node's hull triangles (3 vertices each), node by node; empty unless `far_lod = hull`.
    pub hull: Vec<FarVertex>,
    /// The impostor atlas under `far_lod = impostor` (`crate::impostor`): `impostor_pixels²`
    /// RGBA8 words per slot (as [`FarCell::colours`]), slot by slot, row by row; else empty.
    pub texels: Vec<u32>,
}

impl FarLevel {
    /// Bytes the far level keeps resident (nodes, cells and hull vertices): what the memory
    /// columns report beside G§6's 138 MB (`24 B × cells` of colours).
    pub fn bytes(&self) -> u64 {
        (self.nodes.len() * size_of::<FarNode>()
            + self.cells.len() * size_of::<FarCell>()
            + self.hull.len() * size_of::<FarVertex>()
            + self.texels.len() * 4) as u64
    }

    /// The colour bytes alone, G§2.4's `6 × 4 B` per cell.
    pub fn colour_bytes(&self) -> u64 {
        (self.cells.len() * SIDE_COUNT * 4) as u64
    }
}

/// The side seen from `+axis` (`positive`) or `-axis`.
pub const fn side_of(axis: usize, positive: bool) -> usize {
    axis * 2 + if positive { 0 } else { 1 }
}

/// The unit normal pointing out of side `side` (towards its eye).
pub fn side_normal(side: usize) -> [f32; 3] {
    let mut n = [0.0; 3];
    n[side / 2] = if side.is_multiple_of(2) { 1.0 } else { -1.0 };
    n
}

/// Side weights for the direction `v` towards the eye (module docs): `(weights, sides)`, with
/// `weights[a] = v_a² / |v|²` on `sides[a] = side_of(a, v_a ≥ 0)`. A zero `v` gives `+Z` alone.
pub fn side_weights(v: [f32; 3]) -> ([f32; 3], [u32; 3]) {
    let sq = [v[0] * v[0], v[1] * v[1], v[2] * v[2]];
    let sum = sq[0] + sq[1] + sq[2];
    let sides = [
        side_of(0, v[0] >= 0.0) as u32,
        side_of(1, v[1] >= 0.0) as u32,
        side_of(2, v[2] >= 0.0) as u32,
    ];
    if sum.is_nan() || sum <= 0.0 {
        return ([0.0, 0.0, 1.0], sides);
    }
    ([sq[0] / sum, sq[1] / sum, sq[2] / sum], sides)
}

/// Unpacks an RGBA8 word ([`FarCell::colours`]) to linear RGBA: sRGB-decoded colour
/// ([`crate::srgb_to_linear`]) and linear alpha.
pub fn unpack_far_colour(c: u32) -> [f32; 4] {
    [
        crate::srgb_to_linear(c as u8),
        crate::srgb_to_linear((c >> 8) as u8),
        crate::srgb_to_linear((c >> 16) as u8),
        ((c >> 24) & 255) as f32 / 255.0,
    ]
}

/// Packs linear RGBA to an RGBA8 word: sRGB-encoded colour ([`crate::linear_to_srgb`]) and
/// linear alpha ([`crate::unorm8`]).
pub fn pack_far_colour(c: [f32; 4]) -> u32 {
    crate::linear_to_srgb(c[0]) as u32
        | (crate::linear_to_srgb(c[1]) as u32) << 8
        | (crate::linear_to_srgb(c[2]) as u32) << 16
        | (crate::unorm8(c[3]) as u32) << 24
}

/// The colour of a cell seen along `v` (towards the eye): [`side_weights`] over the six sides'
/// linear colours, alpha included.
pub fn side_mix(colours: &[u32; SIDE_COUNT], v: [f32; 3]) -> [f32; 4] {
    let (w, sides) = side_weights(v);
    let mut out = [0.0f32; 4];
    for a in 0..3 {
        let c = unpack_far_colour(colours[sides[a] as usize]);
        for (o, x) in out.iter_mut().zip(c) {
            *o += w[a] * x;
        }
    }
    out
}

/// The area of the box of half-size `extent` projected along the unit direction `v`:
/// `4 (|v_x| e_y e_z + |v_y| e_x e_z + |v_z| e_x e_y)`.
pub fn box_area_along(extent: [f32; 3], v: [f32; 3]) -> f32 {
    4.0 * (v[0].abs() * extent[1] * extent[2]
        + v[1].abs() * extent[0] * extent[2]
        + v[2].abs() * extent[0] * extent[1])
}

/// The far level's per-frame constants of the cut (module docs).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FarUniform {
    /// 0: no far level (`lod_levels < 3`); else `1 + FarLod`.
    pub kind: u32,
    /// View depth from which a node may go far, `Params::far_start`.
    pub start: f32,
    /// `far_pixels / C`: a node goes far when `area / depth² <` this (C Eq. 4.3 rearranged).
    pub ratio: f32,
}
const _: () = assert!(core::mem::size_of::<FarUniform>() == 12);

impl FarUniform {
    /// The far constants of a validated camera and validated parameters.
    pub fn new(camera: &crate::Camera, params: &crate::Params) -> Self {
        if params.lod_levels < 3 {
            return Self::default();
        }
        let c = crate::metric::metric_constant(camera, false);
        Self {
            kind: 1 + params.far_lod,
            start: params.far_start,
            ratio: (params.far_pixels as f64 / c) as f32,
        }
    }

    /// The far primitive, or `None` when the frame has no far level.
    pub fn far_lod(&self) -> Option<FarLod> {
        self.kind.checked_sub(1).and_then(FarLod::from_id)
    }
}

/// Whether a drawn node whose view-depth interval starts at `lo` goes far (module docs). `eye` is
/// the eye, `box_center ± extent` the node's box, `cells` its kept cells.
pub fn far_eligible(
    far: &FarUniform,
    lo: f32,
    box_center: [f32; 3],
    extent: [f32; 3],
    eye: [f32; 3],
    cells: u32,
) -> bool {
    // NaN fails every comparison: a NaN depth never goes far.
    if far.kind == 0 || cells == 0 || lo.is_nan() || lo < far.start || lo <= 0.0 {
        return false;
    }
    let d = [
        eye[0] - box_center[0],
        eye[1] - box_center[1],
        eye[2] - box_center[2],
    ];
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if len.is_nan() || len <= 0.0 {
        return false;
    }
    let v = [d[0] / len, d[1] / len, d[2] / len];
    box_area_along(extent, v) / (lo * lo) < far.ratio
}

/// The two counter-clockwise triangles of a square, corners in `{-1, 1}²`: a cube face's (seen
/// from outside) and a sprite's (seen from the eye). Twinned by `far_quad_corner` in `common.wgsl`.
const QUAD_CORNERS: [[f32; 2]; 6] = [
    [-1.0, -1.0],
    [1.0, -1.0],
    [1.0, 1.0],
    [-1.0, -1.0],
    [1.0, 1.0],
    [-1.0, 1.0],
];

/// Corner `v` (`0..CUBE_VERTICES`) of a cube: `(face, signs)`, the face ([`side_of`]) and the
/// corner's sign per axis. Triangles wind counter-clockwise seen from outside.
pub fn cube_corner(v: u32) -> (u32, [f32; 3]) {
    let face = v / 6;
    let [s, t] = QUAD_CORNERS[(v % 6) as usize];
    let axis = (face / 2) as usize;
    let sign = if face.is_multiple_of(2) { 1.0 } else { -1.0 };
    // (axis, a1, a2) right-handed, so s along a1 and t along a2 wind counter-clockwise seen from
    // +axis; the -axis face swaps s for -s.
    let a1 = (axis + 1) % 3;
    let a2 = (axis + 2) % 3;
    let mut p = [0.0f32; 3];
    p[axis] = sign;
    p[a1] = s * sign;
    p[a2] = t;
    (face, p)
}

/// Corner `v` (`0..SPRITE_VERTICES`) of a sprite, in `{-1, 1}²` on the quad's (right, up).
pub fn sprite_corner(v: u32) -> [f32; 2] {
    QUAD_CORNERS[(v % 6) as usize]
}

/// The half-sizes of a sprite on the basis `(r, u)` that covers the box `extent`: the box's reach
/// along each axis of the quad (as [`crate::quad_fit`] before its normalisation).
pub fn sprite_half(extent: [f32; 3], r: [f32; 3], u: [f32; 3]) -> [f32; 2] {
    let reach =
        |a: [f32; 3]| a[0].abs() * extent[0] + a[1].abs() * extent[1] + a[2].abs() * extent[2];
    [reach(r), reach(u)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn side_weights_are_a_partition_of_unity_exact_on_the_axes() {
        for a in 0..3 {
            for positive in [true, false] {
                let mut v = [0.0; 3];
                v[a] = if positive { 2.5 } else { -0.5 };
                let (w, s) = side_weights(v);
                assert_eq!(w[a], 1.0);
                assert_eq!(s[a] as usize, side_of(a, positive));
                assert_eq!(w.iter().sum::<f32>(), 1.0);
            }
        }
        let (w, _) = side_weights([0.3, -0.4, 0.5]);
        assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn cube_faces_point_outwards_and_wind_counter_clockwise() {
        for f in 0..6 {
            let corner = |k: u32| cube_corner(f * 6 + k);
            for tri in 0..2 {
                let (face, a) = corner(tri * 3);
                let (_, b) = corner(tri * 3 + 1);
                let (_, c) = corner(tri * 3 + 2);
                assert_eq!(face, f);
                let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                let n = [
                    e1[1] * e2[2] - e1[2] * e2[1],
                    e1[2] * e2[0] - e1[0] * e2[2],
                    e1[0] * e2[1] - e1[1] * e2[0],
                ];
                let out = side_normal(f as usize);
                let dot: f32 = (0..3).map(|k| n[k] * out[k]).sum();
                assert!(dot > 0.0, "face {f} triangle {tri} winds inwards");
                for p in [a, b, c] {
                    assert_eq!(p[f as usize / 2], out[f as usize / 2]);
                }
            }
        }
    }

    #[test]
    fn colours_round_trip_and_mix_is_exact_on_an_axis() {
        let c = pack_far_colour([0.2, 0.5, 0.9, 0.4]);
        assert_eq!(pack_far_colour(unpack_far_colour(c)), c);
        let colours = [1, 2, 3, 4, 5, 6].map(|k| pack_far_colour([k as f32 / 7.0, 0.1, 0.2, 1.0]));
        for s in 0..6 {
            let m = side_mix(&colours, side_normal(s));
            assert_eq!(m, unpack_far_colour(colours[s]));
        }
    }

    #[test]
    fn box_area_is_the_face_area_on_an_axis() {
        assert_eq!(box_area_along([1.0, 2.0, 3.0], [1.0, 0.0, 0.0]), 24.0);
        assert_eq!(box_area_along([1.0, 2.0, 3.0], [0.0, 0.0, -1.0]), 8.0);
    }
}
