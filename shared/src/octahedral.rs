//! Octahedral impostors per tree (issue 32 item 3): the far representation of the field's engines
//! today, as an alternative set of billboard views to the thesis's `K` elevations (E Alg. 3.1).
//!
//! The seeds have no octahedral impostor; the peers do (Unity's IMP: 12×12 frames; Godot's
//! addon and three.js' octahedral-impostor: 16×16). They bake a mesh from `N×N` directions laid
//! on an octahedral map of the sphere (or of the upper hemisphere) and draw a camera-facing quad
//! that blends the three frames around the eye's direction. This module is every formula the bake
//! and the draw share; `gpu/src/shaders/common.wgsl` has the twins.
//!
//! ## Contract
//! - **Views** ([`ViewSphere`], `Params::billboard_views`): `elevation` is the thesis (K
//!   elevations × J azimuths, `crate::azimuth`); `octahedral` and `hemi-octahedral` bake `N²`
//!   frames per mesh (`Params::octahedral_grid`). Frame `f = j·N + i` of mesh `m` is billboard
//!   array layer `m·N² + f` ([`octahedral_layer`]): the same array, mips (alpha-aware ones carry
//!   over) and layer limit as the thesis's billboards.
//! - **Map** ([`octahedral_encode`], [`octahedral_decode`]): a mesh-local direction `d` (Z up)
//!   goes to `p = (x, y)/(|x| + |y| + |z|)`. Full sphere: the lower half (`z < 0`) is folded onto
//!   the square's corners, `p ← ((1 − |p_y|)·sgn p_x, (1 − |p_x|)·sgn p_y)`. Hemisphere: `z` is
//!   clamped to `≥ 0` (a view from below the horizon shows the horizon frame) and the diamond
//!   `|p_x| + |p_y| ≤ 1` is turned 45° onto the square, `(p_x + p_y, p_x − p_y)`. Either way
//!   `uv = p·½ + ½ ∈ [0, 1]²`; `sgn 0 = +1` on both sides (WGSL's `sign(0)` is 0, so the twin
//!   spells it out).
//! - **Frames** ([`frame_direction`]): frame `(i, j)` looks along the decoded direction of the
//!   grid point `uv = (i, j)/(N − 1)`: frames sit on the grid's vertices, corners included, as
//!   the peers lay them out.
//! - **Frame basis** ([`frame_basis`]): right `R = normalize(Z × d)`, up `U = d × R`, so `(R, U,
//!   d)` is right-handed and the frame of `d = +X` is the thesis's level view from `+X`
//!   (`R = +Y`, `U = +Z`). Straight above or below (`|Z × d|² < 1e-12`) `R = +Y`.
//! - **Bake** (`reference/src/bake.rs`): orthographic along `−d`, the square
//!   `[−S, S]²` around the mesh's bounding-box centre `c` on `(R, U)`, `S` the bounding-sphere
//!   radius (`MeshMeta::sphere_radius`), so every frame holds the whole mesh and all frames share
//!   one scale. Texture `v` runs down: a mesh point `p` lands at
//!   `uv = (½ + (p − c)·R / 2S, ½ − (p − c)·U / 2S)` ([`frame_uv`]).
//! - **Selection** ([`octahedral_view`]): the eye's mesh-local direction from the tree's sphere
//!   centre is mapped, scaled to grid units `t = uv·(N − 1)` and split into a cell `(i₀, j₀)`,
//!   `i₀ = min(⌊t_x⌋, N − 2)`, and a position in it quantised to `1/`[`OCTAHEDRAL_STEPS`]
//!   (`q_x, q_y ∈ 0..=64`). Everything after is a function of `(i₀, j₀, q_x, q_y)`, so the vertex
//!   and the fragment, and the reference and the GPU, read the same three frames and weights
//!   from one 24-bit word ([`octahedral_pack`]: exact in an `f32` varying).
//! - **Three frames, barycentric weights** ([`octahedral_frames`]): the cell's lower triangle
//!   `(0,0), (1,0), (0,1)` when `q_x + q_y ≤ 64`, weights `(64 − q_x − q_y, q_x, q_y)/64`; else the
//!   upper `(1,1), (1,0), (0,1)` with `(q_x + q_y − 64, 64 − q_y, 64 − q_x)/64`. The weights are
//!   multiples of `1/64`, exact in `f32`, non-negative, and sum to 1 exactly. The *nearest* frame is
//!   the one of largest weight, the first on a tie.
//! - **Quad** (draw stage): a rectangle about the tree's sphere centre facing the eye (the
//!   [`frame_basis`] of the eye's mesh-local direction, turned by the tree's yaw), fitted to the
//!   mesh's bounding box projected on that basis ([`quad_fit`]: at most the sphere's square of
//!   half side `S·scale`). Its corners' `uv` are their re-projection onto the nearest frame
//!   ([`reproject_uv`] of [`fitted_corner`]: the peers' "virtual plane" projection,
//!   `uv_i = (½ + ½ p·R_i, ½ − ½ p·U_i)` for the quad point `p = (2u − 1)R + (1 − 2v)U`), linear in
//!   the corner, so it interpolates exactly. The fit halved the fragments rasterized against the
//!   sphere's square (`experiments/results/impostors/`).
//! - **Blend** (`Params::octahedral_blend`, `AzimuthMode`'s names): `nearest` samples that frame
//!   only; `blend` also samples the other two at the nearest frame's `uv` re-projected onto
//!   theirs (through the nearest frame's plane: the error against re-projecting the eye-facing
//!   quad directly is second order in the angle between the frames) and mixes the three
//!   premultiplied ([`octahedral_mix`]) before the alpha test, as the azimuth blend mixes two.
//! - **Considered: the quad on the nearest frame's plane** (the thesis's billboards snap their
//!   tilt to a baked elevation that way, E§3.3.1; the nearest frame is then exact for content on
//!   its plane). Measured against the mesh (`tests/tests/reference/octahedral.rs`, silhouette
//!   pixels covered by one and not the other over those either covers, 12 eyes between frames of
//!   an 8×8 hemi grid): a wash, worst 0.32 on the frame's plane against 0.34 facing the eye,
//!   means equal. On a coarse 3×3 grid each lost badly at one eye (0.83 on the frame's plane,
//!   which tilts edge-on as the eye leaves the frame; 0.59 facing the eye). Kept: facing the eye,
//!   the peers' choice, whose quad never turns edge-on and always holds the sphere's silhouette.
//! - **Depth channel** (`Params::octahedral_depth`, [`OctahedralDepth`]; the peers' option: Unity
//!   IMP bakes normal-depth, Godot's addon a depth map). `off` (default): the blend re-projects
//!   through the nearest frame's plane, i.e. it assumes every texel lies on the plane through `c`
//!   facing that frame. `on`: the bake also writes, per frame, a second array layer whose red
//!   channel is the depth of the visible surface, `z = (S − (p − c)·d) / 2S ∈ [0, 1]` (the
//!   orthographic bake's own depth: 0 at the sphere's point nearest the frame's eye), alpha the
//!   colour's alpha, mipmapped by the same alpha-aware rule so red stays an alpha-weighted depth.
//!   The blend then samples each of its three frames with one step of parallax along the *eye's*
//!   ray: the fragment's quad point `q` (recovered from the nearest frame's `uv` and the eye's
//!   direction `e`, [`quad_point`], [`view_direction`]), the frame's depth `t_k` read at `q`'s
//!   projection, and the frame sampled where the ray `q + s·e` reaches that depth
//!   ([`parallax_uv`]): each frame shows what lies on the eye's ray, not on the plane. A
//!   transparent texel keeps the plane (`t = 0`, [`depth_offset`]).
//! - **Rejected (measured): re-projecting the nearest frame's surface point** `P = a·R₀ + b·U₀ +
//!   t·d₀` onto the other two frames. It makes the two frames show what the *nearest* frame sees,
//!   so the blend collapses toward the nearest frame's view, which the blend exists to avoid: on
//!   a 4×4 hemi grid at 12 in-between eyes (`tests/tests/reference/octahedral.rs`) it raised the
//!   mean silhouette XOR against the mesh from 0.380 (plane) to 0.397, and the colour difference
//!   at every eye.
//! - One step, not a ray march (the peers' cheap form): exact where the surface is locally flat
//!   across the step. The field is read only under octahedral views with the blend
//!   ([`depth_channel`]); the nearest-frame rule stays without parallax. Cost: the depth array
//!   doubles the billboard array's bytes (stored as RGBA8 so the alpha-aware mips serve both; a
//!   packed R8 layer would add a quarter), and the blend takes three more samples.

use crate::params::{ParamError, Params};

crate::modes::modes! {
    /// Which views the billboard array holds (module docs).
    pub enum ViewSphere {
        /// `K` elevations (× `J` azimuths) about the tree's base: the thesis's billboards.
        Elevation = 0 => "elevation" ("E Alg. 3.1"),
        /// `N×N` frames over the whole sphere on an octahedral map.
        Octahedral = 1 => "octahedral",
        /// `N×N` frames over the upper hemisphere on a hemi-octahedral map.
        HemiOctahedral = 2 => "hemi-octahedral",
    }
}

crate::modes::modes! {
    /// Whether octahedral impostors carry a depth channel for the blend (module docs).
    pub enum OctahedralDepth {
        /// The blend re-projects through the nearest frame's plane.
        Off = 0 => "off",
        /// The blend re-projects the nearest frame's surface point, from a baked depth layer.
        On = 1 => "on",
    }
}

impl ViewSphere {
    /// Whether the views are octahedral frames (either map).
    pub fn is_octahedral(self) -> bool {
        self != ViewSphere::Elevation
    }
}

/// Whether `billboard_views` (a [`ViewSphere`] id) names an octahedral map.
pub fn is_octahedral(billboard_views: u32) -> bool {
    billboard_views != ViewSphere::Elevation as u32
}

/// Whether `billboard_views` names the hemi-octahedral map.
pub fn is_hemi(billboard_views: u32) -> bool {
    billboard_views == ViewSphere::HemiOctahedral as u32
}

/// Least grid side `N`: one cell.
pub const MIN_OCTAHEDRAL_GRID: u32 = 2;
/// Greatest grid side `N`: 1024 frames a mesh, two meshes under the layer limit.
pub const MAX_OCTAHEDRAL_GRID: u32 = 32;
/// Steps of the in-cell position ([`octahedral_view`]): `1/64` of a cell, about 0.25° at the
/// hemi map's `N = 16`.
pub const OCTAHEDRAL_STEPS: u32 = 64;
/// Bits of the packed word ([`octahedral_pack`]) that hold the cell's first layer (the layer
/// limit, 2048, needs 11).
pub const OCTAHEDRAL_LAYER_BITS: u32 = 11;
/// `1 / OCTAHEDRAL_STEPS`, exact.
pub const OCTAHEDRAL_STEP: f32 = 1.0 / OCTAHEDRAL_STEPS as f32;

const _: () = assert!(crate::azimuth::MAX_BILLBOARD_LAYERS <= 1 << OCTAHEDRAL_LAYER_BITS);
// The cell position `q_x·65 + q_y` above the layer fits the 24 bits an f32 holds exactly.
const _: () =
    assert!(((OCTAHEDRAL_STEPS + 1) * (OCTAHEDRAL_STEPS + 1)) << OCTAHEDRAL_LAYER_BITS <= 1 << 24);

fn sgn(x: f32) -> f32 {
    if x < 0.0 { -1.0 } else { 1.0 }
}

/// The octahedral map of a (not necessarily unit) direction, in `[0, 1]²` (module docs). A zero
/// or non-finite direction maps to the square's centre (straight up).
pub fn octahedral_encode(d: [f32; 3], hemi: bool) -> [f32; 2] {
    let z = if hemi { d[2].max(0.0) } else { d[2] };
    let l1 = d[0].abs() + d[1].abs() + z.abs();
    if !(l1 > 0.0 && l1 <= f32::MAX) {
        return [0.5, 0.5];
    }
    let (mut px, mut py) = (d[0] / l1, d[1] / l1);
    if hemi {
        let (a, b) = (px + py, px - py);
        px = a;
        py = b;
    } else if z < 0.0 {
        let (ax, ay) = (px.abs(), py.abs());
        px = (1.0 - ay) * sgn(px);
        py = (1.0 - ax) * sgn(py);
    }
    let c = |v: f32| (v * 0.5 + 0.5).max(0.0).min(1.0);
    [c(px), c(py)]
}

/// The unit direction of map point `uv` (module docs), the inverse of [`octahedral_encode`].
pub fn octahedral_decode(uv: [f32; 2], hemi: bool) -> [f32; 3] {
    let (ax, ay) = (uv[0] * 2.0 - 1.0, uv[1] * 2.0 - 1.0);
    let (mut x, mut y) = if hemi {
        ((ax + ay) * 0.5, (ax - ay) * 0.5)
    } else {
        (ax, ay)
    };
    let z = 1.0 - x.abs() - y.abs();
    if !hemi && z < 0.0 {
        let (bx, by) = (x.abs(), y.abs());
        x = (1.0 - by) * sgn(x);
        y = (1.0 - bx) * sgn(y);
    }
    let z = if hemi { z.max(0.0) } else { z };
    let len = (x * x + y * y + z * z).sqrt();
    [x / len, y / len, z / len]
}

/// The direction frame `f = j·N + i` of an `N×N` grid looks along (module docs).
pub fn frame_direction(f: u32, n: u32, hemi: bool) -> [f32; 3] {
    let n = n.max(MIN_OCTAHEDRAL_GRID);
    let last = (n - 1) as f32;
    let (i, j) = ((f % n) as f32, (f / n).min(n - 1) as f32);
    octahedral_decode([i / last, j / last], hemi)
}

/// A frame's right and up vectors (module docs).
pub fn frame_basis(d: [f32; 3]) -> ([f32; 3], [f32; 3]) {
    let len2 = d[0] * d[0] + d[1] * d[1];
    let r = if len2 < 1e-12 {
        [0.0, 1.0, 0.0]
    } else {
        let len = len2.sqrt();
        [-d[1] / len, d[0] / len, 0.0]
    };
    let u = [
        d[1] * r[2] - d[2] * r[1],
        d[2] * r[0] - d[0] * r[2],
        d[0] * r[1] - d[1] * r[0],
    ];
    (r, u)
}

/// Where the offset `p − c` of a mesh point from the bounding-box centre lands in a frame with
/// basis `(r, u)` and half side `s` (module docs): `uv` with `v` down.
pub fn frame_uv(offset: [f32; 3], r: [f32; 3], u: [f32; 3], s: f32) -> [f32; 2] {
    let dot = |a: [f32; 3]| offset[0] * a[0] + offset[1] * a[1] + offset[2] * a[2];
    let inv = 0.5 / s;
    [0.5 + dot(r) * inv, 0.5 - dot(u) * inv]
}

/// The layer of frame `f` of mesh `mesh` with `N×N` frames: `mesh·N² + f`.
pub fn octahedral_layer(mesh: u32, f: u32, n: u32) -> u32 {
    mesh * n * n + f
}

/// The eye's place among the frames (module docs): the cell's first frame `f₀ = j₀·N + i₀` and
/// the quantised position in the cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OctahedralView {
    /// The cell's first frame, `j₀·N + i₀`.
    pub cell: u32,
    /// Position along `i` in the cell, `0..=OCTAHEDRAL_STEPS`.
    pub qx: u32,
    /// Position along `j` in the cell, `0..=OCTAHEDRAL_STEPS`.
    pub qy: u32,
}

fn grid_axis(t: f32, n: u32) -> (u32, u32) {
    let last = (n - 1) as f32;
    let t = t.max(0.0).min(last);
    let i0 = (t.floor() as u32).min(n - 2);
    let f = t - i0 as f32;
    let q = ((f * OCTAHEDRAL_STEPS as f32 + 0.5).floor() as u32).min(OCTAHEDRAL_STEPS);
    (i0, q)
}

/// The view of an eye in mesh-local direction `d` (from the sphere centre) among `N×N` frames
/// (module docs). `N` below 2 is read as 2.
pub fn octahedral_view(d: [f32; 3], n: u32, hemi: bool) -> OctahedralView {
    let n = n.max(MIN_OCTAHEDRAL_GRID);
    let uv = octahedral_encode(d, hemi);
    let last = (n - 1) as f32;
    let (i0, qx) = grid_axis(uv[0] * last, n);
    let (j0, qy) = grid_axis(uv[1] * last, n);
    OctahedralView {
        cell: j0 * n + i0,
        qx,
        qy,
    }
}

/// The three frames of a view and their weights (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OctahedralFrames {
    /// Frame indices `j·N + i` within the mesh.
    pub frames: [u32; 3],
    /// Barycentric weights, multiples of `1/64` summing to 1.
    pub weights: [f32; 3],
    /// Which of the three is the nearest (largest weight, first on a tie).
    pub nearest: usize,
}

/// The three frames around `view` on an `N×N` grid (module docs).
pub fn octahedral_frames(view: OctahedralView, n: u32) -> OctahedralFrames {
    let n = n.max(MIN_OCTAHEDRAL_GRID);
    let s = OCTAHEDRAL_STEPS;
    let (qx, qy) = (view.qx.min(s), view.qy.min(s));
    let f0 = view.cell;
    let (frames, w) = if qx + qy <= s {
        ([f0, f0 + 1, f0 + n], [s - qx - qy, qx, qy])
    } else {
        ([f0 + n + 1, f0 + 1, f0 + n], [qx + qy - s, s - qy, s - qx])
    };
    let mut nearest = 0;
    for k in 1..3 {
        if w[k] > w[nearest] {
            nearest = k;
        }
    }
    OctahedralFrames {
        frames,
        weights: w.map(|w| w as f32 * OCTAHEDRAL_STEP),
        nearest,
    }
}

/// The packed varying: the cell's first layer, and `q_x·65 + q_y` above it (24 bits).
pub fn octahedral_pack(cell_layer: u32, view: OctahedralView) -> u32 {
    let q = view.qx.min(OCTAHEDRAL_STEPS) * (OCTAHEDRAL_STEPS + 1) + view.qy.min(OCTAHEDRAL_STEPS);
    (cell_layer & ((1 << OCTAHEDRAL_LAYER_BITS) - 1)) | (q << OCTAHEDRAL_LAYER_BITS)
}

/// The cell's first layer and the view within the mesh of an `N×N` grid from a packed word.
pub fn octahedral_unpack(word: u32, n: u32) -> (u32, OctahedralView) {
    let n = n.max(MIN_OCTAHEDRAL_GRID);
    let layer = word & ((1 << OCTAHEDRAL_LAYER_BITS) - 1);
    let q = word >> OCTAHEDRAL_LAYER_BITS;
    let view = OctahedralView {
        cell: layer % (n * n),
        qx: (q / (OCTAHEDRAL_STEPS + 1)).min(OCTAHEDRAL_STEPS),
        qy: q % (OCTAHEDRAL_STEPS + 1),
    };
    (layer, view)
}

/// The point at `uv` of the quad on frame basis `(r0, u0)` re-projected onto frame `(r, u)`
/// (module docs).
pub fn reproject_uv(
    uv: [f32; 2],
    r0: [f32; 3],
    u0: [f32; 3],
    r: [f32; 3],
    u: [f32; 3],
) -> [f32; 2] {
    let (a, b) = (uv[0] * 2.0 - 1.0, 1.0 - uv[1] * 2.0);
    let p = [
        r0[0] * a + u0[0] * b,
        r0[1] * a + u0[1] * b,
        r0[2] * a + u0[2] * b,
    ];
    let dot = |q: [f32; 3]| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
    [0.5 + dot(r) * 0.5, 0.5 - dot(u) * 0.5]
}

/// The offset `t` along the frame's direction, in sphere radii, of a depth texel whose red
/// channel is the bake's depth `z` and whose alpha is `alpha` (module docs): `1 − 2z`, or 0 (the
/// plane) where the texel is transparent.
pub fn depth_offset(z: f32, alpha: f32) -> f32 {
    if alpha > 0.0 { 1.0 - 2.0 * z } else { 0.0 }
}

/// The eye's mesh-local unit direction as the packed view holds it (module docs, depth channel):
/// the octahedral map decoded at the view's quantised place in its cell. The vertex stage built
/// the quad from the exact direction; this one is within `1/`[`OCTAHEDRAL_STEPS`] of a cell of it.
pub fn view_direction(view: OctahedralView, n: u32, hemi: bool) -> [f32; 3] {
    let n = n.max(MIN_OCTAHEDRAL_GRID);
    let last = (n - 1) as f32;
    let (i0, j0) = ((view.cell % n) as f32, (view.cell / n) as f32);
    let step = OCTAHEDRAL_STEP;
    octahedral_decode(
        [
            (i0 + view.qx as f32 * step) / last,
            (j0 + view.qy as f32 * step) / last,
        ],
        hemi,
    )
}

/// The quad point (sphere radii from `c`) whose projection on the nearest frame `(r0, u0, d0)` is
/// `uv`: the point of the plane through `c` facing the eye `e` (the quad's plane) over that uv
/// (module docs, depth channel). Where the frame is edge-on to the eye (`d0·e ≤ 1e-3`) the
/// frame's own plane point.
pub fn quad_point(
    uv: [f32; 2],
    e: [f32; 3],
    (r0, u0, d0): ([f32; 3], [f32; 3], [f32; 3]),
) -> [f32; 3] {
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (a, b) = (uv[0] * 2.0 - 1.0, 1.0 - uv[1] * 2.0);
    let de = dot(d0, e);
    let c = if de > 1e-3 {
        -(a * dot(r0, e) + b * dot(u0, e)) / de
    } else {
        0.0
    };
    [
        r0[0] * a + u0[0] * b + d0[0] * c,
        r0[1] * a + u0[1] * b + d0[1] * c,
        r0[2] * a + u0[2] * b + d0[2] * c,
    ]
}

/// One parallax step in frame `(r, u, d)` (module docs, depth channel): the point of the eye ray
/// `q + s·e` whose offset along `d` is the frame's depth `t` there, projected on the frame. At
/// `t = q·d` (the plane) it is the frame's projection of `q`; where the frame is edge-on to the
/// eye (`d·e ≤ 1e-3`) too.
pub fn parallax_uv(
    q: [f32; 3],
    e: [f32; 3],
    t: f32,
    (r, u, d): ([f32; 3], [f32; 3], [f32; 3]),
) -> [f32; 2] {
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let ed = dot(e, d);
    let s = if ed > 1e-3 { (t - dot(q, d)) / ed } else { 0.0 };
    let p = [q[0] + e[0] * s, q[1] + e[1] * s, q[2] + e[2] * s];
    [0.5 + dot(p, r) * 0.5, 0.5 - dot(p, u) * 0.5]
}

/// Whether `params` bake and read the depth channel (module docs): `octahedral_depth = on`
/// under octahedral views with the blend. Elsewhere the field is not read (like
/// `octahedral_grid` under elevation views): nothing is baked for it and nothing changes.
pub fn depth_channel(params: &Params) -> bool {
    params.octahedral_depth == OctahedralDepth::On as u32
        && is_octahedral(params.billboard_views)
        && params.octahedral_blend == crate::AzimuthMode::Blend as u32
}

/// How much of the sphere's square the quad on basis `(r, u)` needs (the quad fit): the mesh's
/// bounding box (half sizes `half`, centred on the sphere centre) projected on `r` and on `u`, as
/// fractions of the sphere radius `s`, at most 1. Every mesh point projects inside the fitted
/// rectangle, so a quad of half sides `f_r·s`, `f_u·s` holds the tree from this eye.
pub fn quad_fit(half: [f32; 3], r: [f32; 3], u: [f32; 3], s: f32) -> [f32; 2] {
    let reach = |a: [f32; 3]| a[0].abs() * half[0] + a[1].abs() * half[1] + a[2].abs() * half[2];
    let f = |x: f32| (x / s.max(f32::MIN_POSITIVE)).max(0.0).min(1.0);
    [f(reach(r)), f(reach(u))]
}

/// A corner `corner ∈ [0, 1]²` of the fitted quad ([`quad_fit`]) as a point of the sphere's
/// square, `½ + (corner − ½)·fit`: what [`reproject_uv`] takes.
pub fn fitted_corner(corner: [f32; 2], fit: [f32; 2]) -> [f32; 2] {
    [
        0.5 + (corner[0] - 0.5) * fit[0],
        0.5 + (corner[1] - 0.5) * fit[1],
    ]
}

/// A `uv` derivative of the quad re-projected onto frame `(r, u)` ([`reproject_uv`] is linear in
/// `uv`: this is its matrix applied to `duv`).
pub fn reproject_duv(
    duv: [f32; 2],
    r0: [f32; 3],
    u0: [f32; 3],
    r: [f32; 3],
    u: [f32; 3],
) -> [f32; 2] {
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    [
        dot(r0, r) * duv[0] - dot(u0, r) * duv[1],
        dot(u0, u) * duv[1] - dot(r0, u) * duv[0],
    ]
}

/// Mixes three texels by `weights` premultiplied (as [`crate::azimuth_mix`] mixes two), so a
/// texel transparent in one frame does not darken the others. A weight of 1 returns its texel
/// bit for bit.
pub fn octahedral_mix(texels: [[f32; 4]; 3], weights: [f32; 3]) -> [f32; 4] {
    for k in 0..3 {
        if weights[k] == 1.0 {
            return texels[k];
        }
    }
    let a = [
        texels[0][3] * weights[0],
        texels[1][3] * weights[1],
        texels[2][3] * weights[2],
    ];
    let alpha = a[0] + a[1] + a[2];
    let c = |i: usize| {
        if alpha > 0.0 {
            (texels[0][i] * a[0] + texels[1][i] * a[1] + texels[2][i] * a[2]) / alpha
        } else {
            texels[0][i] * weights[0] + texels[1][i] * weights[1] + texels[2][i] * weights[2]
        }
    };
    [c(0), c(1), c(2), alpha]
}

/// Refuses a grid whose layers, `meshes·N²`, pass the billboard array's layer limit, naming
/// `octahedral_grid`. Nothing to check under the thesis's elevation views.
pub fn check_octahedral_layers(meshes: usize, params: &Params) -> Result<(), ParamError> {
    if !is_octahedral(params.billboard_views) {
        return Ok(());
    }
    let n = u64::from(params.octahedral_grid);
    let layers = (meshes as u64).saturating_mul(n * n);
    if layers <= u64::from(crate::azimuth::MAX_BILLBOARD_LAYERS) {
        return Ok(());
    }
    Err(ParamError {
        field: "octahedral_grid",
        value: params.octahedral_grid.to_string(),
        reason: format!(
            "{meshes} meshes x {n}x{n} octahedral frames = {layers} billboard layers, over the \
             limit of {} array layers",
            crate::azimuth::MAX_BILLBOARD_LAYERS
        )
        .into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    use crate::test_support::proptest_config;

    fn unit(d: [f32; 3]) -> [f64; 3] {
        let l = d.iter().map(|v| f64::from(*v).powi(2)).sum::<f64>().sqrt();
        d.map(|v| f64::from(v) / l)
    }

    fn angle(a: [f32; 3], b: [f32; 3]) -> f64 {
        let (a, b) = (unit(a), unit(b));
        (a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
            .clamp(-1.0, 1.0)
            .acos()
    }

    proptest! {
        #![proptest_config(proptest_config())]
        /// The depth channel's parallax step (module docs) is exact: for a surface point `P`
        /// seen along the eye's direction `e`, the quad point `q` (P moved along `e` onto the
        /// quad's plane) is recovered from its nearest-frame `uv`, and one step in any frame
        /// whose depth there is `P·d` lands on `P`'s projection in that frame. Planted bugs:
        /// the step taken along the frame's direction instead of the eye's, and the quad point
        /// left on the frame's plane, each fail.
        #[test]
        fn the_parallax_step_lands_on_the_eye_rays_surface_point(
            p in prop::array::uniform3(-0.7f32..0.7),
            f0 in 0u32..64,
            f1 in 0u32..64,
            wobble in prop::array::uniform3(-0.15f32..0.15),
            hemi in any::<bool>(),
        ) {
            let n = 8;
            let basis = |f| {
                let d = frame_direction(f, n, hemi);
                let (r, u) = frame_basis(d);
                (r, u, d)
            };
            let (b0, b1) = (basis(f0), basis(f1));
            let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
            // An eye near the nearest frame (the blend's case), facing both frames.
            let e = {
                let v = [b0.2[0] + wobble[0], b0.2[1] + wobble[1], b0.2[2] + wobble[2]];
                let l = dot(v, v).sqrt();
                v.map(|x| x / l)
            };
            prop_assume!(dot(e, b1.2) > 0.2);
            let pe = dot(p, e);
            let q = [p[0] - e[0] * pe, p[1] - e[1] * pe, p[2] - e[2] * pe];
            let uv0 = frame_uv(q, b0.0, b0.1, 1.0);
            let q2 = quad_point(uv0, e, b0);
            for k in 0..3 {
                prop_assert!((q2[k] - q[k]).abs() < 1e-4, "{q2:?} vs {q:?}");
            }
            let got = parallax_uv(q2, e, dot(p, b1.2), b1);
            let want = frame_uv(p, b1.0, b1.1, 1.0);
            for k in 0..2 {
                prop_assert!((got[k] - want[k]).abs() < 1e-3, "{got:?} vs {want:?}");
            }
        }
    }

    #[test]
    fn the_view_direction_is_the_eyes_to_a_step() {
        for d in [[0.6f32, 0.3, 0.5], [-0.4, 0.7, 0.35], [0.2, -0.8, 0.6]] {
            for hemi in [true, false] {
                let v = view_direction(octahedral_view(d, 8, hemi), 8, hemi);
                assert!(angle(v, d) < 0.02, "{d:?} {hemi}: {v:?}");
            }
        }
    }

    #[test]
    fn depth_offset_reads_the_bakes_depth_and_keeps_the_plane_where_transparent() {
        // z = (S - o·d) / 2S: the sphere's near point (o·d = S) is z = 0, t = 1.
        assert_eq!(depth_offset(0.0, 1.0), 1.0);
        assert_eq!(depth_offset(1.0, 0.5), -1.0);
        assert_eq!(depth_offset(0.5, 1.0), 0.0);
        assert_eq!(depth_offset(0.0, 0.0), 0.0);
    }

    #[test]
    fn the_level_frame_from_x_is_the_thesis_view() {
        let (r, u) = frame_basis([1.0, 0.0, 0.0]);
        assert_eq!((r, u), ([0.0, 1.0, 0.0], [0.0, 0.0, 1.0]));
        // Straight up: R = +Y, U = d × R = -X (the thesis's 90° elevation from +X).
        let (r, u) = frame_basis([0.0, 0.0, 1.0]);
        assert_eq!((r, u), ([0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]));
    }

    #[test]
    fn the_maps_put_up_at_the_centre_and_the_horizon_on_the_rim() {
        for hemi in [false, true] {
            assert_eq!(octahedral_encode([0.0, 0.0, 1.0], hemi), [0.5, 0.5]);
            assert_eq!(octahedral_decode([0.5, 0.5], hemi), [0.0, 0.0, 1.0]);
            assert_eq!(octahedral_encode([0.0, 0.0, 0.0], hemi), [0.5, 0.5]);
            assert_eq!(octahedral_encode([f32::NAN, 0.0, 1.0], hemi), [0.5, 0.5]);
        }
        // The hemisphere's corners are the four horizon axes.
        let d = octahedral_decode([1.0, 0.5], true);
        assert!(angle(d, [0.5, 0.5, 0.0]) < 1e-6, "{d:?}");
        // Full sphere: down is every corner.
        for uv in [[0.0, 0.0], [1.0, 1.0], [0.0, 1.0], [1.0, 0.0]] {
            let d = octahedral_decode(uv, false);
            assert!(angle(d, [0.0, 0.0, -1.0]) < 1e-6, "{uv:?} {d:?}");
        }
        // Below the horizon, the hemi map shows the horizon.
        let e = octahedral_encode([1.0, 0.0, -0.5], true);
        assert_eq!(e, octahedral_encode([1.0, 0.0, 0.0], true));
    }

    #[test]
    fn a_frame_direction_selects_that_frame_alone() {
        for hemi in [false, true] {
            for n in [2, 3, 8, 12, 16, 32] {
                for f in 0..n * n {
                    let d = frame_direction(f, n, hemi);
                    let v = octahedral_view(d, n, hemi);
                    let fr = octahedral_frames(v, n);
                    let k = fr.nearest;
                    // On the full map the rim frames repeat (mirrored); the frame found must
                    // look along the same direction.
                    let chosen = frame_direction(fr.frames[k], n, hemi);
                    assert!(
                        angle(chosen, d) < 1e-5,
                        "N={n} hemi={hemi} f={f}: chose {} ({:?})",
                        fr.frames[k],
                        fr
                    );
                    assert_eq!(fr.weights[k], 1.0, "N={n} f={f}");
                }
            }
        }
    }

    #[test]
    fn pack_round_trips_and_fits_an_f32() {
        for n in [2u32, 12, 32] {
            for (layer, qx, qy) in [(0, 0, 0), (2047, 64, 64), (n * n + 5, 17, 63)] {
                let view = OctahedralView {
                    cell: layer % (n * n),
                    qx,
                    qy,
                };
                let w = octahedral_pack(layer, view);
                assert!(w < 1 << 24);
                assert_eq!(octahedral_unpack(w, n), (layer, view));
                assert_eq!(w as f32 as u32, w);
            }
        }
    }

    #[test]
    fn layer_limit_names_the_grid() {
        let p = Params {
            billboard_views: ViewSphere::HemiOctahedral as u32,
            octahedral_grid: 16,
            ..Params::default()
        };
        check_octahedral_layers(8, &p).unwrap();
        let e = check_octahedral_layers(9, &p).unwrap_err();
        assert_eq!((e.field, e.value.as_str()), ("octahedral_grid", "16"));
        assert!(e.to_string().contains("2304 billboard layers"), "{e}");
        let p = Params {
            octahedral_grid: 32,
            ..Params::default()
        };
        check_octahedral_layers(100, &p).unwrap();
    }

    #[test]
    fn a_weight_of_one_returns_its_texel_bit_for_bit() {
        let t = [
            [0.1, 0.2, 0.3, 0.3],
            [0.9, 0.8, 0.7, 0.6],
            [0.5, 0.5, 0.5, 0.0],
        ];
        for k in 0..3 {
            let mut w = [0.0; 3];
            w[k] = 1.0;
            assert_eq!(
                octahedral_mix(t, w).map(f32::to_bits),
                t[k].map(f32::to_bits)
            );
        }
    }

    proptest! {
        #![proptest_config(proptest_config())]

        /// The weights are a partition of unity over three distinct frames of the grid, the
        /// nearest has the largest weight, and the three frames' directions surround the eye:
        /// the eye is within one cell's diagonal of each frame with weight.
        #[test]
        fn three_frames_partition_unity_around_the_eye(
            x in -1.0f32..1.0, y in -1.0f32..1.0, z in -1.0f32..1.0, n in 2u32..=32, hemi: bool,
        ) {
            prop_assume!(x.abs() + y.abs() + z.abs() > 1e-3);
            let v = octahedral_view([x, y, z], n, hemi);
            let fr = octahedral_frames(v, n);
            let sum: f32 = fr.weights.iter().sum();
            prop_assert_eq!(sum, 1.0);
            prop_assert!(fr.weights.iter().all(|w| (0.0..=1.0).contains(w)));
            prop_assert!(fr.frames.iter().all(|f| *f < n * n), "{:?}", fr);
            prop_assert!(fr.frames[0] != fr.frames[1] && fr.frames[1] != fr.frames[2] && fr.frames[0] != fr.frames[2]);
            prop_assert!(fr.weights.iter().all(|w| *w <= fr.weights[fr.nearest]));
            // The map point lies in the triangle of the three frames' grid points with these
            // barycentric weights, to the quantisation.
            let uv = octahedral_encode([x, y, z], hemi);
            let last = (n - 1) as f32;
            let mut p = [0.0f32; 2];
            for k in 0..3 {
                let f = fr.frames[k];
                p[0] += fr.weights[k] * (f % n) as f32 / last;
                p[1] += fr.weights[k] * (f / n) as f32 / last;
            }
            let tol = 0.5 / OCTAHEDRAL_STEPS as f32 / last + 1e-5;
            prop_assert!((p[0] - uv[0]).abs() <= tol && (p[1] - uv[1]).abs() <= tol, "{:?} vs {:?}", p, uv);
        }

        /// Encode and decode are inverses: on the map (hemi: the upper half) a direction comes
        /// back to within f32 rounding.
        #[test]
        fn the_map_round_trips(x in -1.0f32..1.0, y in -1.0f32..1.0, z in -1.0f32..1.0, hemi: bool) {
            prop_assume!(x.abs() + y.abs() + z.abs() > 1e-3);
            let d = [x, y, if hemi { z.abs() } else { z }];
            let back = octahedral_decode(octahedral_encode(d, hemi), hemi);
            prop_assert!(angle(back, d) < 1e-5, "{:?} -> {:?}", d, back);
        }

        /// A frame's basis is orthonormal and right-handed about its direction.
        #[test]
        fn frame_bases_are_orthonormal(f in 0u32..1024, n in 2u32..=32, hemi: bool) {
            let d = frame_direction(f % (n * n), n, hemi);
            let (r, u) = frame_basis(d);
            let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
            for (a, b, want) in [(r, r, 1.0), (u, u, 1.0), (d, d, 1.0), (r, u, 0.0), (r, d, 0.0), (u, d, 0.0)] {
                prop_assert!((dot(a, b) - want).abs() < 1e-5, "{:?} {:?}", a, b);
            }
            // R × U = d.
            let c = [r[1] * u[2] - r[2] * u[1], r[2] * u[0] - r[0] * u[2], r[0] * u[1] - r[1] * u[0]];
            prop_assert!(angle(c, d) < 1e-4);
        }

        /// Re-projecting onto the same frame is the identity, and a point's uv in one frame
        /// re-projected onto another is that point's uv there when it lies on the first plane.
        #[test]
        fn reprojection_moves_points_on_the_plane(
            u in 0.0f32..1.0, v in 0.0f32..1.0, f in 0u32..144, g in 0u32..144, hemi: bool,
        ) {
            let (r0, u0) = frame_basis(frame_direction(f, 12, hemi));
            let same = reproject_uv([u, v], r0, u0, r0, u0);
            prop_assert!((same[0] - u).abs() < 1e-5 && (same[1] - v).abs() < 1e-5);
            let (r1, u1) = frame_basis(frame_direction(g, 12, hemi));
            let p = [
                r0[0] * (2.0 * u - 1.0) + u0[0] * (1.0 - 2.0 * v),
                r0[1] * (2.0 * u - 1.0) + u0[1] * (1.0 - 2.0 * v),
                r0[2] * (2.0 * u - 1.0) + u0[2] * (1.0 - 2.0 * v),
            ];
            let want = frame_uv(p, r1, u1, 1.0);
            let got = reproject_uv([u, v], r0, u0, r1, u1);
            prop_assert!((want[0] - got[0]).abs() < 1e-5 && (want[1] - got[1]).abs() < 1e-5);
        }

        /// The fitted quad holds every point of the bounding box from every eye: a point's
        /// offset on the quad's basis is within the fit (to f32 rounding), and the fit is at most
        /// the sphere's square.
        #[test]
        fn the_fitted_quad_holds_the_box(
            hx in 0.1f32..5.0, hy in 0.1f32..5.0, hz in 0.5f32..20.0,
            px in -1.0f32..=1.0, py in -1.0f32..=1.0, pz in -1.0f32..=1.0,
            x in -1.0f32..1.0, y in -1.0f32..1.0, z in -1.0f32..1.0,
        ) {
            prop_assume!(x.abs() + y.abs() + z.abs() > 1e-3);
            let l = (x * x + y * y + z * z).sqrt();
            let (r, u) = frame_basis([x / l, y / l, z / l]);
            let s = (hx * hx + hy * hy + hz * hz).sqrt();
            let fit = quad_fit([hx, hy, hz], r, u, s);
            prop_assert!(fit[0] <= 1.0 && fit[1] <= 1.0 && fit[0] >= 0.0 && fit[1] >= 0.0);
            let p = [px * hx, py * hy, pz * hz];
            let dot = |a: [f32; 3]| p[0] * a[0] + p[1] * a[1] + p[2] * a[2];
            prop_assert!(dot(r).abs() <= fit[0] * s * (1.0 + 1e-5) + 1e-5, "{} > {}", dot(r), fit[0] * s);
            prop_assert!(dot(u).abs() <= fit[1] * s * (1.0 + 1e-5) + 1e-5, "{} > {}", dot(u), fit[1] * s);
        }

        /// The mix is a weighted mean: alpha is the weighted alpha, colours stay within the
        /// texels' range.
        #[test]
        fn the_mix_stays_in_range(
            t in prop::array::uniform3(prop::array::uniform4(0.0f32..=1.0)),
            qx in 0u32..=64, qy in 0u32..=64,
        ) {
            let fr = octahedral_frames(OctahedralView { cell: 0, qx, qy }, 4);
            let m = octahedral_mix(t, fr.weights);
            let want_a: f32 = (0..3).map(|k| t[k][3] * fr.weights[k]).sum();
            prop_assert!((m[3] - want_a).abs() < 1e-6);
            for i in 0..3 {
                let lo = t.iter().map(|x| x[i]).fold(f32::MAX, f32::min);
                let hi = t.iter().map(|x| x[i]).fold(f32::MIN, f32::max);
                prop_assert!(m[i] >= lo - 1e-6 && m[i] <= hi + 1e-6);
            }
        }
    }
}
