//! The reference software rasterizer: triangles in wgpu clip space to an sRGB RGBA8 colour target,
//! an `f32` depth target and a `u32` auxiliary target, following the Vulkan rules that the GPU (and
//! Mesa's lavapipe in CI) follows, so that the wgpu twin can be compared pixel by pixel (SPEC §3, §8).
//!
//! ## Contract
//!
//! [`RenderTarget::draw`] takes a triangle list ([`Triangle`]: three [`Vertex`]es, each a clip-space
//! position plus `N` `f32` varyings), a [`FragmentShader`] and a [`DrawState`], and runs, for every
//! triangle in submission order:
//!
//! 1. **Clipping** (Vulkan §"Primitive Clipping"). The clip volume is `0 <= z <= w` (wgpu's depth
//!    range) and `-w <= x, y <= w`. Against the near (`z >= 0`) and far (`z <= w`) planes we clip
//!    exactly, in homogeneous space. Against x and y we clip only at a **guard band**
//!    [`GUARD_BAND_PX`] pixels outside the viewport: coverage never depends on x/y clipping (the
//!    spec lets implementations rasterize outside the viewport and discard), and the guard band is
//!    what keeps snapped coordinates small enough for exact `i64` edge functions (see below).
//!    The Sutherland–Hodgman clipper always interpolates from the vertex inside a plane towards the
//!    one outside, so an edge shared by two triangles is cut at bit-identical points in both and the
//!    mesh stays watertight. The clipped convex polygon is split into a fan `(v0, vi, vi+1)`; each
//!    piece keeps the primitive id of its triangle.
//! 2. **Viewport transform** (Vulkan §"Controlling the Viewport"), in `f32` as the GPU does, with
//!    wgpu's flipped viewport (negative height), so framebuffer y points down:
//!    `x_f = (x_ndc + 1)/2 · width`, `y_f = (1 - y_ndc)/2 · height`, `z_f = z_ndc`.
//! 3. **Snapping** to [`SUBPIXEL_BITS`] = 8 fractional bits (Vulkan `subPixelPrecisionBits`; lavapipe
//!    reports 8): `X = round_half_even(x_f · 256)` as `i64`, the IEEE default rounding that
//!    lavapipe's `lrintf` uses.
//! 4. **Setup** (Vulkan §"Basic Polygon Rasterization"): the signed area in framebuffer coordinates
//!    decides facing: with [`FrontFace::Ccw`] a triangle is front-facing when it is counter-clockwise
//!    in NDC with y up, which is Vulkan's `a > 0` after wgpu's viewport flip. Zero-area triangles
//!    (after snapping) cover nothing. Both windings are rasterized unless [`CullMode`] says otherwise.
//! 5. **Coverage**: one sample per pixel at its centre `(x + 0.5, y + 0.5)`, tested against three
//!    exact `i64` edge functions. Vulkan requires that a sample on an edge shared by two triangles is
//!    covered by exactly one of them and leaves the choice to the implementation; like lavapipe (and
//!    Direct3D) we use the **top-left rule** in framebuffer coordinates (y down): a sample exactly on
//!    an edge is covered only if that edge is a *top* edge (horizontal, interior below it) or a *left*
//!    edge (interior to its right).
//! 6. **Interpolation**: depth `z_f` is interpolated linearly in screen space (Vulkan §"Basic Polygon
//!    Rasterization", `z = a·z_a + b·z_b + c·z_c`, used by §"Depth Test") and clamped to `[0, 1]`;
//!    varyings are **perspective-correct** (the same section's `f = (a·f_a/w_a + b·f_b/w_b +
//!    c·f_c/w_c) / (a/w_a + b/w_b + c/w_c)`), with barycentrics `a, b, c` computed in `f64` from the
//!    exact edge functions and results rounded once to `f32`.
//! 7. **Quads and derivatives** (Vulkan §"Derivative Operations", §"Helper Invocations"): pixels are
//!    processed in 2x2 quads aligned to even coordinates. Varyings are evaluated at all four pixel
//!    centres, covered or not (the uncovered ones stand for helper invocations), and every fragment
//!    of the quad receives the **coarse** derivatives anchored at the quad's top-left pixel:
//!    `ddx = f(x0 + 1, y0) - f(x0, y0)`, `ddy = f(x0, y0 + 1) - f(x0, y0)` (`ddy` points down, towards
//!    the next framebuffer row). This is what `dFdxCoarse`/`dFdyCoarse` may return and what lavapipe
//!    uses for implicit texture LOD (one LOD per quad). Helper invocations are not shaded: the only
//!    derivatives on offer are those of the varyings, which is what texture sampling needs.
//! 8. **Fragment stage and output merge** (Vulkan §"Depth Test", §"Blending", §"Primitive Order"):
//!    for each covered sample in submission order: the depth test **LESS** (`z < stored`; skipped,
//!    i.e. wgpu's `CompareFunction::Always`, when [`DrawState::depth_test`] is false); then the
//!    [`FragmentShader`], which may discard (alpha test); then, for a kept fragment, the depth write
//!    (if [`DrawState::depth_write`]), the colour write through [`Blend`] and the `u32` id write.
//!    The depth test runs *before* the shader: the shader cannot lower depth, so a fragment that
//!    fails the test can have no effect whatever the shader does, and testing first gives the same
//!    buffers as testing after (Vulkan's early fragment tests). Depth is written only after the
//!    shader keeps the fragment. A shader may **replace** the depth ([`FragmentOutput::depth`],
//!    SPIR-V `FragDepth`) under the conservative-depth contract `DepthGreater`: its depth is never
//!    below the interpolated one, so the early test rejects only fragments that the late test
//!    would reject too. The returned depth is clamped to `[0, 1]` (Vulkan clamps `FragDepth` to the
//!    viewport's depth range), tested again with LESS when the depth test is on, and written.
//! 9. **Colour target** is RGBA8 sRGB, like wgpu's `Rgba8UnormSrgb`: the shader's linear,
//!    straight-alpha colour is clamped to `[0, 1]` (NaN to 0, as conversion to UNORM does), blended in
//!    `f32` with the destination decoded to linear, and re-encoded to sRGB8 with round-to-nearest
//!    after **every** fragment. This per-fragment quantization is what the GPU does, and what makes
//!    the two agree within ±1 per channel (SPEC §8).
//!
//! ## Invariants
//!
//! - **Watertight, no double hits**: triangles sharing an edge (same snapped endpoints) cover every
//!   sample on it exactly once; a fan tiling a convex region covers each sample in it exactly once.
//! - **Primitive order** (Vulkan §"Primitive Order"): per pixel, fragments are merged in submission
//!   order. Parallelism is over screen tiles of [`TILE_SIZE`]² pixels ([`MASKED_TILE_SIZE`]² when
//!   every target of a draw is masked) (rayon): every tile processes
//!   every triangle overlapping it, in submission order, into its own pixels only. Setup is parallel
//!   over triangles but collected in order. Hence the buffers are **bit-identical for any thread
//!   count**, and so are the [`DrawStats`].
//! - **Exact coverage**: all coverage arithmetic is integer. Snapped coordinates are bounded by the
//!   guard band: `|X|, |Y| <= M = 2 · (GUARD_BAND_PX + MAX_TARGET_SIZE) · 256 < 2^30` (the factor 2
//!   absorbs `f32` rounding at the guard band), so an edge function, a difference of two products
//!   of coordinate differences, is at most `8 M² < 2^62` and cannot overflow `i64`. A polygon whose
//!   snapped coordinates exceed `M` anyway (only possible when a vertex has `w` so close to zero that
//!   the division overflows) is dropped. So is any triangle with a non-finite clip coordinate
//!   (Vulkan leaves those undefined).
//!
//! ## Speed-ups (issue 14), and what each relies on
//!
//! None changes a bit of any buffer or counter; each is an equality, not an approximation.
//!
//! - **Binning by tile**: a triangle is listed only in the bins of the tiles its pixel box
//!   touches, in submission order; a tile renders only its bin. Relies on coverage being confined
//!   to the box (pixel centres outside it fail an edge test).
//! - **No per-triangle allocation in setup**: setup runs over runs of [`SETUP_RUN`] triangles,
//!   one output vector each, concatenated in order; a triangle that crosses no clip plane skips the
//!   clipper (its polygon would be itself). A set-up piece whose box holds no pixel centre is
//!   counted but not kept (it can cover nothing).
//! - **Tile buffers loaded once per draw**: a tile's private copy of its pixels lives from the
//!   first chunk that reaches it to the end of the draw (tiles own disjoint pixels, so nothing
//!   else reads them meanwhile); a masked target's tiles with no pixel in the mask are never
//!   loaded.
//! - **Masked bins**: for a masked target, a tile renders only the triangles whose box meets a
//!   pixel of the mask inside the tile (a summed-area table of the mask answers that in four
//!   lookups), and targets with equal masks share those lists. Relies on a masked draw's quad loop
//!   writing and counting nothing outside the mask.
//! - **Passes share the walk** (session 9, issue 14): [`draw_passes`] draws one triangle list
//!   into several targets, one [`PassShader`] pass each; the targets with equal masks walk the
//!   quads once, and coverage, barycentrics, depth, varyings and derivatives are computed once
//!   for all of them; the early depth test, the late one and the merge are per target, and the
//!   shader is called once per pixel with the set of passes whose test it passed. Relies on
//!   those values depending only on the triangle and the pixel (never on a target's contents),
//!   and on each target's fragments still merging in submission order (each pixel's passes
//!   are handled in full before the next fragment). The parity's six alternative frames:
//!   0.67 → 0.55 s in the main job (with the ground drawn once and copied).
//! - **Masked bins from the tile's masked pixels**: the per-tile filter tests a triangle's
//!   coverage at the tile's list of masked pixels when that list is shorter than the triangle's
//!   box (the same pixels, so the same answer).
//! - **Masked quads** (session 8, issue 14): in a masked tile, a triangle whose box holds more
//!   quads than the tile has quads with a masked pixel visits only those (row-major, the full
//!   walk's order), its edge functions evaluated at each (exact integers, equal to the stepped
//!   ones). Relies on the same: a quad with no masked pixel covers, counts and writes nothing.
//! - **Shared barycentrics; helpers only where read**: a pixel's barycentrics are computed once
//!   (same expression) for depth and varyings; the bottom-right pixel of a quad is interpolated
//!   only when it is shaded, since the coarse derivatives read the other three only.
//! - **Table sRGB encoder** (`srgb8`): relies on `linear_to_srgb` being non-decreasing in its
//!   `f32` input (module `srgb8` docs; checked exhaustively by an ignored test).
//! - **Edge functions walked by integer steps** (second round, issue 14): per triangle and tile the
//!   edge functions are evaluated once, at the first quad, and then stepped two pixels at a time
//!   by the exact integer increments of `SetupTriangle::edge_steps` (an edge function is linear
//!   in the sample position; every value is a real pixel's, bounded as in "Exact coverage"); the
//!   coverage test is one sign test of the OR of `E_i + bias_i`. Relies on integer arithmetic
//!   being exact (checked pixel by pixel by `quad_edges_equal_the_edge_functions_at_each_pixel`).
//! - **Hot arrays written out**: `std::array::from_fn` over `[i64; 3]` and `[f32; N]` compiled to
//!   stack copies that were 18 % of a 1280x720 frame; the same expressions are written element by
//!   element. The `f64` sums of depth and varyings were `Iterator::sum`, whose fold starts at
//!   `-0.0`: `-0.0 + x = x`, so `x0 + x1 + x2` left to right is the same value bit for bit.
//! - **Opaque source-over is a replace** (`merge`): with `a = 1` the destination is not
//!   decoded; `s·1 + d·0 = s` for a decoded `d` in `[0, 1]` (checked by
//!   `opaque_source_over_equals_replace`).
//! - Texture texels are decoded to linear light once per texture, not per fetch
//!   (`crate::sampler::Texture`).
//! - **Covered spans** (session 10, issue 14): per row of quads, the walk visits only the quads
//!   whose largest edge function values (at the quad's best corner, an exact integer) pass all
//!   three edges' tests, an interval found by exact integer division (`covered_quad_span`).
//!   Relies on a quad with no covered pixel counting and writing nothing. Before it, the
//!   mispredicted early exit of empty quads alone was 11 % of the `close` frame's samples.
//! - **Depth bound** (session 10, issue 14): each set-up triangle carries a lower bound of its
//!   depth at every covered sample (`depth_lower_bound`: the smallest vertex depth, less a
//!   relative `2^-50`, with the proof there); a covered sample whose stored depth is at most the
//!   bound fails LESS whatever its interpolated depth, so its barycentrics and depth are not
//!   computed. It is still counted as covered (the counters are unchanged), and computed when a
//!   neighbour needs it as a helper. The `close` frame covers 26.9 M samples, of which 6.4 M
//!   pass the depth test: the other 20.5 M are mostly trees behind trees, which the bound
//!   rejects for the price of one comparison. (Hierarchical rejection per tile would save
//!   little more: every covered sample must still be counted.)
//! - **sRGB encoder starts from a per-bucket lower bound** (round 3, merged in session 10):
//!   `srgb8` looks up the code of the first `f32` of `l`'s bucket of `2^15` bit patterns and
//!   steps up through the thresholds; relies on the same monotonicity as the table (checked at
//!   both ends of every bucket and every threshold by `srgb8_equals_linear_to_srgb`).
//! - **Streamed triangle lists** (session 11, issue 14): [`draw_passes_streamed`] takes the list
//!   a piece at a time from a [`TriangleSource`], so a caller can produce the next piece after
//!   the previous one is drawn (the tree draw's vertex stage does: `crate::draw`), instead of
//!   the whole list existing at once. Relies on what chunking already relies on: pieces are
//!   drawn in order, each tile renders a piece's triangles in order before the next piece's,
//!   and a primitive id is the triangle's index in the concatenation
//!   (`a_streamed_draw_in_uneven_pieces_equals_one_draw`). `stress` close at 320x180 holds 10.7 M
//!   triangles (1.15 GB as one list); its frame went from 3.5 s to 2.6 s on one thread, with its
//!   peak memory from 1.3 GB to under 0.2 GB.
//! - **A dropped target's buffers reused** (session 11, issue 14): [`RenderTarget::new`] takes
//!   the buffers of the last dropped target (at most 1920x1080) instead of fresh pages, and
//!   clears them as it clears new ones (`a_new_target_is_cleared_whatever_buffers_it_reuses`).
//!   A new 1280x720 target is 11 MB of pages to fault in; in a frame without trees that was a
//!   fifth to a third of the frame.
//! - **One tile per parallel job** (session 12, issue 14): the tiles of a chunk (and a masked
//!   group's per-tile triangle lists) are handed to rayon one per job (`with_max_len(1)`).
//!   Rayon's default splitting cut a chunk's 240 tiles into a few runs, each processed
//!   sequentially and unstealable, and a frame's heavy tiles cluster (the trees near the
//!   camera): on two threads synthetic 1280x720 `close` rendered its tiles at 1.44x one thread's
//!   speed; one per job, 1.99x (frame 0.585 → 0.435 s with `frame_bench --threads 2`). Which
//!   thread renders a tile changes nothing: tiles are disjoint and keep their own order.
//! - **Set-up triangles referenced, not concatenated** (session 12, issue 14): a chunk's set-up
//!   triangles stay in the vectors of the runs that set them up, and the bins index a table of
//!   references to them in submission order; the concatenation copied 16 MB per chunk on one
//!   thread (synthetic 1280x720 `close`: 0.431 → 0.415 s on two threads). The same triangles in
//!   the same order.
//! - **Clear in parallel** (session 12, issue 14): [`RenderTarget::new`] fills reused buffers
//!   in parallel pieces (a 1280x720 frame without trees: 1.23 → 1.12 ms). Every value is still
//!   the clear value.
//! - **No libm rounding calls** (round 3, merged in session 10): `round_ties_even_exact` (the
//!   snap) and `round_exact` (the tree shader's layer and command) equal the standard library's
//!   bit for bit (proofs at each; `rounding_helpers_equal_the_standard_library`).

use std::ops::{Add, AddAssign};

use rayon::prelude::*;

use crate::texture::{Rgba8Image, linear_to_srgb, srgb_to_linear, unorm8};

/// Fractional bits of snapped framebuffer coordinates (Vulkan `subPixelPrecisionBits`; lavapipe
/// reports 8).
pub const SUBPIXEL_BITS: u32 = 8;
/// One pixel in snapped (fixed-point) units.
const SUBPIXEL_ONE: i64 = 1 << SUBPIXEL_BITS;
/// Half a pixel in snapped units: the offset of a pixel centre.
const SUBPIXEL_HALF: i64 = SUBPIXEL_ONE / 2;

/// Largest width or height of a [`RenderTarget`] (the limit `Camera::validate` enforces too).
pub const MAX_TARGET_SIZE: u32 = 16384;

/// How far, in pixels, the x/y clip planes lie outside the viewport on every side (module docs).
pub const GUARD_BAND_PX: u32 = 1 << 20;

/// Side of the square screen tiles that are rendered in parallel. Even, so that 2x2 quads never
/// straddle two tiles.
pub const TILE_SIZE: u32 = 64;

/// Bound on the magnitude of snapped coordinates (module docs, "Exact coverage").
const MAX_ABS_FIXED: i64 = 2 * (GUARD_BAND_PX as i64 + MAX_TARGET_SIZE as i64) * SUBPIXEL_ONE;
const _: () = assert!(
    8 * (MAX_ABS_FIXED as i128) * (MAX_ABS_FIXED as i128) < i64::MAX as i128,
    "edge functions of guard-band coordinates must fit in i64"
);
const _: () = assert!(TILE_SIZE.is_multiple_of(2));

/// Tile side of a draw whose every target is masked ([`RenderTarget::with_pixel_mask`]): the
/// parity's alternatives, masked to ~1 % of the pixels in small clusters (issue 14).
pub const MASKED_TILE_SIZE: u32 = 16;
const _: () = assert!(MASKED_TILE_SIZE.is_multiple_of(2));

/// A vertex as the vertex stage outputs it: a clip-space position (wgpu conventions: after the
/// divide by `w`, x and y in `-1..1` with y up, depth in `0..1`) and `N` varyings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vertex<const N: usize> {
    /// Clip-space position `[x, y, z, w]`.
    pub clip: [f32; 4],
    /// Values interpolated (perspective-correct) across the triangle.
    pub varyings: [f32; N],
}

impl<const N: usize> Vertex<N> {
    /// A vertex from its clip-space position and varyings.
    pub fn new(clip: [f32; 4], varyings: [f32; N]) -> Self {
        Self { clip, varyings }
    }
}

/// Three vertices; a draw is a list of them (a "triangle list" topology).
pub type Triangle<const N: usize> = [Vertex<N>; 3];

/// Output-merge colour blending (per draw).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Blend {
    /// Overwrite the destination (`BlendState::REPLACE`).
    #[default]
    Replace,
    /// Straight-alpha "source over": `rgb = src.rgb·src.a + dst.rgb·(1 - src.a)`,
    /// `a = src.a + dst.a·(1 - src.a)`, in linear light (wgpu `SrcAlpha, OneMinusSrcAlpha` for
    /// colour and `One, OneMinusSrcAlpha` for alpha).
    AlphaBlend,
}

/// Which faces are dropped before rasterization.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CullMode {
    /// Rasterize both windings.
    #[default]
    None,
    /// Drop front-facing triangles.
    Front,
    /// Drop back-facing triangles.
    Back,
}

/// Which winding is front-facing, judged in NDC with y up (wgpu's `FrontFace`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FrontFace {
    /// Counter-clockwise triangles face the viewer (wgpu's default).
    #[default]
    Ccw,
    /// Clockwise triangles face the viewer.
    Cw,
}

/// Fixed-function state of one draw.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DrawState {
    /// Depth test LESS when true; when false every fragment passes (wgpu `CompareFunction::Always`).
    pub depth_test: bool,
    /// Write the depth of kept fragments (even when `depth_test` is false, as wgpu does).
    pub depth_write: bool,
    /// How colour is merged.
    pub blend: Blend,
    /// Face culling.
    pub cull: CullMode,
    /// Which winding is front-facing.
    pub front_face: FrontFace,
}

impl DrawState {
    /// Opaque geometry: depth test and write, no blending, no culling.
    pub const OPAQUE: Self = Self {
        depth_test: true,
        depth_write: true,
        blend: Blend::Replace,
        cull: CullMode::None,
        front_face: FrontFace::Ccw,
    };
    /// Transparent geometry: depth test without write, alpha blending, no culling.
    pub const TRANSPARENT: Self = Self {
        depth_test: true,
        depth_write: false,
        blend: Blend::AlphaBlend,
        cull: CullMode::None,
        front_face: FrontFace::Ccw,
    };
}

impl Default for DrawState {
    /// [`DrawState::OPAQUE`].
    fn default() -> Self {
        Self::OPAQUE
    }
}

/// What the fragment stage sees for one covered pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fragment<const N: usize> {
    /// Pixel column (framebuffer, from the left).
    pub x: u32,
    /// Pixel row (framebuffer, from the top).
    pub y: u32,
    /// Interpolated depth `z_f` in `[0, 1]`: the value that is tested and written.
    pub depth: f32,
    /// Perspective-correct varyings at the pixel centre.
    pub varyings: [f32; N],
    /// Coarse derivative of each varying along +x (module docs, step 7).
    pub ddx: [f32; N],
    /// Coarse derivative of each varying along +y, i.e. down one framebuffer row.
    pub ddy: [f32; N],
    /// Whether the triangle faces the viewer ([`FrontFace`]).
    pub front_facing: bool,
    /// Index of the triangle in the draw's slice (Vulkan `PrimitiveId`; clipped pieces keep it).
    pub primitive_id: u32,
}

/// What the fragment stage returns for a kept fragment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FragmentOutput {
    /// Linear-light RGBA, straight alpha; clamped to `[0, 1]` at the output merge.
    pub color: [f32; 4],
    /// Value written to the auxiliary `u32` target (e.g. the LOD id of the debug view).
    pub id: u32,
    /// A depth the shader writes instead of the interpolated one (SPIR-V `FragDepth`), or `None`
    /// for the interpolated depth. Module docs, step 8: the shader must not return less than
    /// [`Fragment::depth`] (SPIR-V `DepthGreater`, GLSL `layout(depth_greater)`), so the early
    /// test stays valid; the returned depth is clamped to `[0, 1]`, tested again (LESS) and
    /// written. NaN discards the fragment. Used by the *Primitive* baseline (E§5).
    pub depth: Option<f32>,
}

/// The fragment stage: `None` discards the fragment (alpha test), leaving every target untouched.
///
/// Implemented for every `Fn(&Fragment<N>) -> Option<FragmentOutput> + Sync` closure. Tiles run in
/// parallel, hence `Sync`; a shader is called in submission order per pixel but in no particular
/// order across pixels, so it must not depend on call order.
pub trait FragmentShader<const N: usize>: Sync {
    /// Shades one covered fragment.
    fn shade(&self, fragment: &Fragment<N>) -> Option<FragmentOutput>;
}

impl<const N: usize, F> FragmentShader<N> for F
where
    F: Fn(&Fragment<N>) -> Option<FragmentOutput> + Sync,
{
    fn shade(&self, fragment: &Fragment<N>) -> Option<FragmentOutput> {
        self(fragment)
    }
}

/// Work counters of one or more draws (add them up with `+=`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DrawStats {
    /// Triangles submitted.
    pub triangles_in: u64,
    /// Triangles leaving the clipper: 1 for a triangle wholly inside, 0 for one wholly outside, the
    /// fan size of a clipped polygon otherwise.
    pub triangles_clipped: u64,
    /// Triangles set up for rasterization: those of `triangles_clipped` with non-zero snapped area
    /// that are not culled.
    pub triangles_rasterized: u64,
    /// Covered samples (before the depth test): the rasterizer's output.
    pub fragments_covered: u64,
    /// Fragment shader invocations: covered samples that passed the depth test, which runs first
    /// (module docs, step 8). Helper pixels are not counted (they are never shaded).
    pub fragments_shaded: u64,
    /// Fragments kept by the shader and merged into the targets. `fragments_written / pixels` is
    /// the overdraw.
    pub fragments_written: u64,
}

impl AddAssign for DrawStats {
    fn add_assign(&mut self, o: Self) {
        self.triangles_in += o.triangles_in;
        self.triangles_clipped += o.triangles_clipped;
        self.triangles_rasterized += o.triangles_rasterized;
        self.fragments_covered += o.fragments_covered;
        self.fragments_shaded += o.fragments_shaded;
        self.fragments_written += o.fragments_written;
    }
}

impl Add for DrawStats {
    type Output = Self;
    fn add(mut self, o: Self) -> Self {
        self += o;
        self
    }
}

/// Values a [`RenderTarget`] is cleared to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClearValues {
    /// Linear-light RGBA, straight alpha (encoded to sRGB8 like a clear of an `Rgba8UnormSrgb`
    /// attachment).
    pub color: [f32; 4],
    /// Depth (1.0: the far plane, so LESS accepts anything drawn).
    pub depth: f32,
    /// Auxiliary id.
    pub aux: u32,
}

impl ClearValues {
    /// The colour as the target stores it (sRGB8, clamped).
    fn color_code(&self) -> [u8; 4] {
        encode(clamp_color(self.color))
    }
}

impl Default for ClearValues {
    /// Transparent black, depth 1.0, id 0.
    fn default() -> Self {
        Self {
            color: [0.0; 4],
            depth: 1.0,
            aux: 0,
        }
    }
}

/// The buffers of the last dropped [`RenderTarget`] of at most [`Spare::MAX_BYTES`], which the
/// next [`RenderTarget::new`] takes and clears (issue 14, session 11). What it saves: a new
/// 1280x720 target is 11 MB of fresh pages, and faulting them in was about a third of a frame
/// with no trees (the `far` camera: sky and ground, 5-6 ms); a frame loop (a sweep, a benchmark)
/// drops one target before it makes the next. What it costs: at most one target's buffers stay
/// allocated after it is dropped ([`release_spare_buffers`] frees them). It cannot change a
/// pixel: `new` sets every value through `clear`.
struct Spare;

/// A target's colour, depth and auxiliary buffers.
type Buffers = (Vec<[u8; 4]>, Vec<f32>, Vec<u32>);

static SPARE: std::sync::Mutex<Option<Buffers>> = std::sync::Mutex::new(None);

impl Spare {
    /// Largest target kept: 1920x1080 and smaller (a supersampled truth frame is not kept).
    const MAX_BYTES: usize = 32 << 20;

    fn take() -> Option<Buffers> {
        SPARE.lock().unwrap_or_else(|e| e.into_inner()).take()
    }

    fn keep(buffers: Buffers) {
        let bytes = buffers.0.capacity() * 4 + buffers.1.capacity() * 4 + buffers.2.capacity() * 4;
        if bytes > 0 && bytes <= Self::MAX_BYTES {
            *SPARE.lock().unwrap_or_else(|e| e.into_inner()) = Some(buffers);
        }
    }
}

/// Frees the buffers a dropped [`RenderTarget`] left for the next one (see [`RenderTarget::new`]):
/// for a caller about to measure or hand back its resident memory.
pub fn release_spare_buffers() {
    drop(Spare::take());
}

impl Drop for RenderTarget {
    fn drop(&mut self) {
        Spare::keep((
            std::mem::take(&mut self.color),
            std::mem::take(&mut self.depth),
            std::mem::take(&mut self.aux),
        ));
    }
}

/// A colour (RGBA8 sRGB), depth (`f32`) and auxiliary (`u32`) target of one size, drawn into by any
/// number of [`RenderTarget::draw`] calls. All buffers are row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderTarget {
    width: u32,
    height: u32,
    color: Vec<[u8; 4]>,
    depth: Vec<f32>,
    aux: Vec<u32>,
    /// [`RenderTarget::with_pixel_mask`]: the only pixels draws may touch (row-major); `None`,
    /// every pixel.
    mask: Option<Vec<bool>>,
}

impl RenderTarget {
    /// A `width` x `height` target cleared to `clear`.
    ///
    /// # Panics
    /// If a side is 0 or larger than [`MAX_TARGET_SIZE`] (the guard band bound depends on it).
    pub fn new(width: u32, height: u32, clear: ClearValues) -> Self {
        assert!(
            (1..=MAX_TARGET_SIZE).contains(&width) && (1..=MAX_TARGET_SIZE).contains(&height),
            "render target {width}x{height}: expected 1..={MAX_TARGET_SIZE} pixels per side"
        );
        let n = width as usize * height as usize;
        // A dropped target's buffers when there are some (`Spare`), else new ones; every value
        // is written once, the clear value, so which memory it is changes nothing.
        let (color, depth, aux) = Spare::take().unwrap_or_default();
        // The reused part is filled in parallel, in pieces of `FILL_CHUNK` values (a 1280x720
        // target's three buffers are 11 MB; issue 14, session 12), the rest as it is allocated.
        fn filled<T: Copy + Send + Sync>(mut v: Vec<T>, n: usize, value: T) -> Vec<T> {
            const FILL_CHUNK: usize = 1 << 16;
            v.truncate(n);
            v.par_chunks_mut(FILL_CHUNK).for_each(|c| c.fill(value));
            v.resize(n, value);
            v
        }
        Self {
            width,
            height,
            color: filled(color, n, clear.color_code()),
            depth: filled(depth, n, clear.depth),
            aux: filled(aux, n, clear.aux),
            mask: None,
        }
    }

    /// Restricts every later draw to the pixels where `mask` (row-major, one entry per pixel) is
    /// true: a sample outside it counts as uncovered, so it is never tested, shaded or written,
    /// and a quad or tile with no pixel inside is skipped. A pixel inside receives exactly the
    /// fragments, in the same order, with the same quad derivatives (helpers are still
    /// interpolated) as without a mask, so its colour, depth and id are **bit-identical** to an
    /// unmasked draw's; pixels outside keep their clear values. What this is for: the parity
    /// comparison reads its alternative frames (cutoff moved) only at the few pixels where the GPU
    /// and the reference disagree, so those frames need only those pixels (issue 14: 6 of the main
    /// job's 7 reference frames). The work counters ([`DrawStats`]) count only the masked pixels.
    ///
    /// # Panics
    /// If `mask` does not have one entry per pixel.
    pub fn with_pixel_mask(mut self, mask: Vec<bool>) -> Self {
        assert_eq!(
            mask.len(),
            self.width as usize * self.height as usize,
            "pixel mask length"
        );
        self.mask = Some(mask);
        self
    }

    /// Resets every pixel of every buffer.
    pub fn clear(&mut self, clear: ClearValues) {
        self.color.fill(clear.color_code());
        self.depth.fill(clear.depth);
        self.aux.fill(clear.aux);
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The colour, depth and auxiliary buffers, moved out (no copy).
    pub fn into_buffers(mut self) -> (Vec<[u8; 4]>, Vec<f32>, Vec<u32>) {
        (
            std::mem::take(&mut self.color),
            std::mem::take(&mut self.depth),
            std::mem::take(&mut self.aux),
        )
    }

    /// The colour buffer: sRGB-encoded RGB, linear alpha.
    pub fn color(&self) -> &[[u8; 4]] {
        &self.color
    }

    /// The depth buffer.
    pub fn depth(&self) -> &[f32] {
        &self.depth
    }

    /// The auxiliary id buffer.
    pub fn aux(&self) -> &[u32] {
        &self.aux
    }

    /// The colour buffer as an image (ready for PNG encoding).
    pub fn color_image(&self) -> Rgba8Image {
        Rgba8Image {
            width: self.width,
            height: self.height,
            texels: self.color.clone(),
        }
    }

    /// Draws a triangle list (module docs for every step) and returns its work counters.
    ///
    /// # Panics
    /// If there are more than `u32::MAX` triangles (primitive ids are `u32`, as in Vulkan).
    pub fn draw<const N: usize, S>(
        &mut self,
        triangles: &[Triangle<N>],
        shader: &S,
        state: &DrawState,
    ) -> DrawStats
    where
        S: FragmentShader<N> + ?Sized,
    {
        draw_passes(&mut [self], &One(shader), triangles, state)[0]
    }

    /// Screen tiles, row by row.
    fn tiles(&self, size: u32) -> Vec<PixelRect> {
        let mut tiles = Vec::new();
        for y0 in (0..self.height).step_by(size as usize) {
            for x0 in (0..self.width).step_by(size as usize) {
                tiles.push(PixelRect {
                    x0,
                    y0,
                    x1: (x0 + size).min(self.width),
                    y1: (y0 + size).min(self.height),
                });
            }
        }
        tiles
    }

    fn load_tile(&self, rect: PixelRect) -> TileBuffers {
        let n = rect.width() as usize * rect.height() as usize;
        let mut b = TileBuffers {
            rect,
            color: Vec::with_capacity(n),
            depth: Vec::with_capacity(n),
            aux: Vec::with_capacity(n),
            mask: self.mask.as_ref().map(|_| Vec::with_capacity(n)),
        };
        for y in rect.y0..rect.y1 {
            let row = self.index(rect.x0, y)..self.index(rect.x1, y);
            b.color.extend_from_slice(&self.color[row.clone()]);
            b.depth.extend_from_slice(&self.depth[row.clone()]);
            if let (Some(local), Some(mask)) = (&mut b.mask, &self.mask) {
                local.extend_from_slice(&mask[row.clone()]);
            }
            b.aux.extend_from_slice(&self.aux[row]);
        }
        b
    }

    /// Whether a draw may touch any pixel of `rect` (always, without a pixel mask).
    fn tile_has_pixels(&self, rect: PixelRect) -> bool {
        self.mask.as_ref().is_none_or(|mask| {
            (rect.y0..rect.y1)
                .any(|y| mask[self.index(rect.x0, y)..self.index(rect.x1, y)].contains(&true))
        })
    }

    fn store_tile(&mut self, b: &TileBuffers) {
        let w = b.rect.width() as usize;
        for (j, y) in (b.rect.y0..b.rect.y1).enumerate() {
            let row = self.index(b.rect.x0, y)..self.index(b.rect.x1, y);
            let local = j * w..(j + 1) * w;
            self.color[row.clone()].copy_from_slice(&b.color[local.clone()]);
            self.depth[row.clone()].copy_from_slice(&b.depth[local.clone()]);
            self.aux[row].copy_from_slice(&b.aux[local]);
        }
    }

    fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }
}

/// How many pixels of a pixel mask lie in any rectangle, in four lookups: the mask's summed-area
/// table, `(width + 1) x (height + 1)` counts, `sums[y][x]` the mask pixels above and left of
/// `(x, y)`. [`draw_passes`] uses it to leave out, per tile, the triangles whose box meets no
/// pixel of a masked target (issue 14), and [`crate::draw`] to leave out whole trees.
pub(crate) struct MaskCounts {
    stride: usize,
    sums: Vec<u32>,
}

impl MaskCounts {
    pub(crate) fn new(mask: &[bool], width: u32, height: u32) -> Self {
        let (w, h) = (width as usize, height as usize);
        let stride = w + 1;
        let mut sums = vec![0u32; stride * (h + 1)];
        for y in 0..h {
            let mut row = 0u32;
            for x in 0..w {
                row += u32::from(mask[y * w + x]);
                sums[(y + 1) * stride + x + 1] = sums[y * stride + x + 1] + row;
            }
        }
        Self { stride, sums }
    }

    /// Whether `r` holds a pixel of the mask.
    fn any(&self, r: &PixelRect) -> bool {
        let at = |x: u32, y: u32| self.sums[y as usize * self.stride + x as usize];
        at(r.x1, r.y1) + at(r.x0, r.y0) > at(r.x0, r.y1) + at(r.x1, r.y0)
    }

    /// Whether the half-open rectangle `[x0, x1) x [y0, y1)` (within the mask) holds a pixel of
    /// the mask; an empty rectangle holds none.
    pub(crate) fn any_in(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> bool {
        x0 < x1 && y0 < y1 && self.any(&PixelRect { x0, y0, x1, y1 })
    }
}

/// A half-open pixel rectangle `[x0, x1) x [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PixelRect {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

impl PixelRect {
    fn width(&self) -> u32 {
        self.x1 - self.x0
    }
    fn height(&self) -> u32 {
        self.y1 - self.y0
    }
    fn contains(&self, x: u32, y: u32) -> bool {
        (self.x0..self.x1).contains(&x) && (self.y0..self.y1).contains(&y)
    }
    fn intersect(&self, o: &PixelRect) -> Option<PixelRect> {
        let r = PixelRect {
            x0: self.x0.max(o.x0),
            y0: self.y0.max(o.y0),
            x1: self.x1.min(o.x1),
            y1: self.y1.min(o.y1),
        };
        (r.x0 < r.x1 && r.y0 < r.y1).then_some(r)
    }
}

/// Viewport constants: the transform (module docs, step 2) and the guard-band clip planes.
struct Viewport {
    width: u32,
    height: u32,
    half_w: f32,
    half_h: f32,
    /// The x clip planes are `-guard_x·w <= x <= guard_x·w`: `GUARD_BAND_PX` outside the viewport.
    guard_x: f32,
    /// Likewise for y.
    guard_y: f32,
}

impl Viewport {
    fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            half_w: width as f32 * 0.5,
            half_h: height as f32 * 0.5,
            guard_x: 1.0 + 2.0 * GUARD_BAND_PX as f32 / width as f32,
            guard_y: 1.0 + 2.0 * GUARD_BAND_PX as f32 / height as f32,
        }
    }

    /// Signed distance-like value of `p` to clip plane `plane`: inside when `>= 0`.
    /// Planes: near `z >= 0`, far `z <= w`, then the guard band's left, right, bottom, top.
    fn plane_distance(&self, plane: usize, p: &[f32; 4]) -> f32 {
        let [x, y, z, w] = *p;
        match plane {
            0 => z,
            1 => w - z,
            2 => self.guard_x * w + x,
            3 => self.guard_x * w - x,
            4 => self.guard_y * w + y,
            5 => self.guard_y * w - y,
            _ => unreachable!("six clip planes"),
        }
    }

    /// Bit mask of the planes `p` is outside of (NaN counts as outside).
    fn outcode(&self, p: &[f32; 4]) -> u32 {
        (0..CLIP_PLANES)
            .filter(|&i| {
                let d = self.plane_distance(i, p);
                d < 0.0 || d.is_nan()
            })
            .fold(0, |m, i| m | 1 << i)
    }
}

const CLIP_PLANES: usize = 6;

/// Clips one triangle to the near, far and guard-band planes (module docs, step 1). Returns the
/// clipped convex polygon, empty when nothing is left.
fn clip_triangle<const N: usize>(tri: &Triangle<N>, viewport: &Viewport) -> Vec<Vertex<N>> {
    let codes = tri.map(|v| viewport.outcode(&v.clip));
    if codes[0] & codes[1] & codes[2] != 0 {
        return Vec::new(); // wholly outside one plane
    }
    let mut poly = tri.to_vec();
    let crossed = codes[0] | codes[1] | codes[2];
    for plane in (0..CLIP_PLANES).filter(|&p| crossed & (1 << p) != 0) {
        let mut out = Vec::with_capacity(poly.len() + 1);
        for (i, cur) in poly.iter().enumerate() {
            let next = &poly[(i + 1) % poly.len()];
            let dc = viewport.plane_distance(plane, &cur.clip);
            let dn = viewport.plane_distance(plane, &next.clip);
            let (cur_in, next_in) = (dc >= 0.0, dn >= 0.0);
            if cur_in {
                out.push(*cur);
            }
            if cur_in != next_in {
                // Always from the inside vertex towards the outside one, so both triangles sharing
                // this edge compute the same point. An inside vertex on the plane is itself the
                // intersection and is emitted on its own.
                let (inside, outside, di, d_out) = if cur_in {
                    (cur, next, dc, dn)
                } else {
                    (next, cur, dn, dc)
                };
                if di > 0.0 {
                    out.push(lerp_vertex(inside, outside, di / (di - d_out)));
                }
            }
        }
        poly = out;
        if poly.len() < 3 {
            return Vec::new();
        }
    }
    poly
}

fn lerp_vertex<const N: usize>(a: &Vertex<N>, b: &Vertex<N>, t: f32) -> Vertex<N> {
    let lerp = |x: f32, y: f32| x + t * (y - x);
    Vertex {
        clip: std::array::from_fn(|i| lerp(a.clip[i], b.clip[i])),
        varyings: std::array::from_fn(|i| lerp(a.varyings[i], b.varyings[i])),
    }
}

/// A vertex after the viewport transform and snapping.
#[derive(Clone, Copy)]
struct ScreenVertex<const N: usize> {
    /// Snapped framebuffer position, in 1/256 pixel.
    pos: [i64; 2],
    /// `z_f = z / w`.
    z: f32,
    /// `1 / w`.
    inv_w: f64,
    varyings: [f32; N],
}

/// `c.round_ties_even()` bit for bit (signed zeros, NaN, infinities) without libm's `rintf`,
/// which is what it compiles to on x86-64's baseline (0.8 % of a `stress` frame, issue 14 round
/// 3). A value of magnitude at least `2^23`, a NaN or an infinity is already integral and returned
/// as it is. Otherwise `|c| + 2^23` lies in `[2^23, 2^24)`, where the `f32` spacing is 1, so the
/// addition rounds `|c|` to an integer with the IEEE default (ties to even; `2^23` is even, so
/// the sum's parity is the result's) and subtracting `2^23` again is exact; the sign is `c`'s,
/// as `round_ties_even` keeps it (`-0.3` gives `-0.0`). Checked against the standard library by
/// `rounding_helpers_equal_the_standard_library`.
#[inline]
pub(crate) fn round_ties_even_exact(c: f32) -> f32 {
    const TWO_23: f32 = 8_388_608.0;
    let a = c.abs();
    if a.is_nan() || a >= TWO_23 {
        return c;
    }
    ((a + TWO_23) - TWO_23).copysign(c)
}

/// `c.round()` (halves away from zero) bit for bit without libm's `roundf` (1.3 % of a
/// 1280x720 frame, called twice per tree fragment by `draw::TreeShader`). A value of magnitude
/// at least `2^23`, a NaN or an infinity is integral; otherwise truncation through `i32` is exact,
/// so is the fraction `|c| - trunc(|c|)` (in `[0, 1)`, with `c`'s exponent or less), and the
/// result moves up by one exactly when that fraction is at least a half; the sign is `c`'s.
/// Checked by `rounding_helpers_equal_the_standard_library`.
#[inline]
pub(crate) fn round_exact(c: f32) -> f32 {
    let a = c.abs();
    if a.is_nan() || a >= 8_388_608.0 {
        return c;
    }
    let t = a as i32 as f32;
    let r = if a - t >= 0.5 { t + 1.0 } else { t };
    r.copysign(c)
}

fn project<const N: usize>(v: &Vertex<N>, viewport: &Viewport) -> Option<ScreenVertex<N>> {
    let [x, y, z, w] = v.clip;
    // Viewport transform in f32 (module docs, step 2), then snapping (step 3).
    let xf = (x / w) * viewport.half_w + viewport.half_w;
    let yf = viewport.half_h - (y / w) * viewport.half_h;
    let snap = |c: f32| {
        let s = round_ties_even_exact(c * SUBPIXEL_ONE as f32);
        (s.is_finite() && s.abs() <= MAX_ABS_FIXED as f32).then_some(s as i64)
    };
    Some(ScreenVertex {
        pos: [snap(xf)?, snap(yf)?],
        z: z / w,
        inv_w: 1.0 / w as f64,
        varyings: v.varyings,
    })
}

/// A triangle ready for coverage: snapped, oriented with positive area, with its edge rules.
#[derive(Clone, Copy)]
struct SetupTriangle<const N: usize> {
    primitive_id: u32,
    front_facing: bool,
    /// Vertices, ordered so that `area > 0` (clockwise on screen, where y points down).
    v: [ScreenVertex<N>; 3],
    /// Twice the signed area in snapped units², `> 0`.
    area: i64,
    /// Per edge (edge `i` is opposite vertex `i`): 0 for a top or left edge, -1 otherwise; a sample
    /// is covered when `E_i + bias_i >= 0` for all `i`.
    bias: [i64; 3],
    /// Pixels whose centres lie in the vertices' bounding box, within the target; `None` if none.
    bbox: Option<PixelRect>,
    /// A lower bound of [`SetupTriangle::depth`] at every sample the triangle covers
    /// ([`depth_lower_bound`]).
    min_depth: f32,
}

/// Twice the signed area of `(a, b, p)`: the edge function of edge `a -> b` at `p`.
fn edge_function(a: [i64; 2], b: [i64; 2], p: [i64; 2]) -> i64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// Whether the edge `a -> b` of a triangle with positive area (y down) is a top or left edge.
///
/// With positive area the interior lies where the edge function is positive. A horizontal edge
/// (`dy == 0`) has the interior below it exactly when `dx > 0`: a top edge. A non-horizontal edge
/// has the interior to its right exactly when `dy < 0`: a left edge.
fn is_top_left(a: [i64; 2], b: [i64; 2]) -> bool {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    dy < 0 || (dy == 0 && dx > 0)
}

/// What [`setup_primitive`] did with one submitted triangle (its [`DrawStats`] shares).
#[derive(Clone, Copy, Default)]
struct SetupCounts {
    /// Triangles that left the clipper.
    clipped: u64,
    /// Of those, triangles with non-zero snapped area that were not culled.
    rasterized: u64,
}

/// Clips, projects and sets up one submitted triangle, appending to `out` the pieces that survive
/// setup **and cover at least one pixel centre of the target** (a piece with no pixel in its box
/// can produce no fragment, so it is counted in [`SetupCounts::rasterized`] but not kept: that is
/// most of a far forest's triangles).
///
/// Speed-up (issue 14): a triangle inside every clip plane (the common case) skips the clipper's
/// polygon and is projected and set up directly, with no allocation; it is exactly what the clipper
/// would return (the polygon of a triangle that crosses no plane is the triangle itself).
fn setup_primitive<const N: usize>(
    id: u32,
    tri: &Triangle<N>,
    viewport: &Viewport,
    state: &DrawState,
    out: &mut Vec<SetupTriangle<N>>,
) -> SetupCounts {
    let mut counts = SetupCounts::default();
    if tri.iter().any(|v| v.clip.iter().any(|c| !c.is_finite())) {
        return counts;
    }
    let mut keep = |t: Option<SetupTriangle<N>>| {
        if let Some(t) = t {
            counts.rasterized += 1;
            if t.bbox.is_some() {
                out.push(t);
            }
        }
    };
    if tri.iter().all(|v| viewport.outcode(&v.clip) == 0) {
        counts.clipped = 1;
        let [a, b, c] = tri;
        if let (Some(a), Some(b), Some(c)) = (
            project(a, viewport),
            project(b, viewport),
            project(c, viewport),
        ) {
            keep(setup_triangle(id, [a, b, c], viewport, state));
        }
        return counts;
    }
    let poly = clip_triangle(tri, viewport);
    if poly.is_empty() {
        return counts;
    }
    counts.clipped = poly.len() as u64 - 2;
    let Some(screen) = poly
        .iter()
        .map(|v| project(v, viewport))
        .collect::<Option<Vec<_>>>()
    else {
        return counts;
    };
    for i in 1..screen.len() - 1 {
        keep(setup_triangle(
            id,
            [screen[0], screen[i], screen[i + 1]],
            viewport,
            state,
        ));
    }
    counts
}

fn setup_triangle<const N: usize>(
    primitive_id: u32,
    mut v: [ScreenVertex<N>; 3],
    viewport: &Viewport,
    state: &DrawState,
) -> Option<SetupTriangle<N>> {
    let mut area = edge_function(v[0].pos, v[1].pos, v[2].pos);
    if area == 0 {
        return None; // degenerate: covers nothing
    }
    // Vulkan's `a = -area / 2` (its formula's minus sign turns y-down into y-up): `a > 0` is
    // counter-clockwise as seen in NDC with y up.
    let ccw = area < 0;
    let front_facing = match state.front_face {
        FrontFace::Ccw => ccw,
        FrontFace::Cw => !ccw,
    };
    let culled = match state.cull {
        CullMode::None => false,
        CullMode::Front => front_facing,
        CullMode::Back => !front_facing,
    };
    if culled {
        return None;
    }
    if area < 0 {
        v.swap(1, 2);
        area = -area;
    }
    let p = v.map(|s| s.pos);
    // Edge i runs between the two vertices other than i, in winding order.
    let bias = std::array::from_fn(|i| {
        let (a, b) = (p[(i + 1) % 3], p[(i + 2) % 3]);
        if is_top_left(a, b) { 0 } else { -1 }
    });

    // Pixels whose centre X = 256·x + 128 lies within [min, max] of the vertices.
    let min = |k: usize| p.iter().map(|q| q[k]).min().unwrap_or(0);
    let max = |k: usize| p.iter().map(|q| q[k]).max().unwrap_or(0);
    let first = |lo: i64| -((SUBPIXEL_HALF - lo).div_euclid(SUBPIXEL_ONE)); // ceil((lo - 128) / 256)
    let last = |hi: i64| (hi - SUBPIXEL_HALF).div_euclid(SUBPIXEL_ONE); // floor((hi - 128) / 256)
    let x0 = first(min(0)).max(0);
    let y0 = first(min(1)).max(0);
    let x1 = (last(max(0)) + 1).min(viewport.width as i64);
    let y1 = (last(max(1)) + 1).min(viewport.height as i64);
    let bbox = (x0 < x1 && y0 < y1).then_some(PixelRect {
        x0: x0 as u32,
        y0: y0 as u32,
        x1: x1 as u32,
        y1: y1 as u32,
    });

    let min_depth = depth_lower_bound([v[0].z, v[1].z, v[2].z]);
    Some(SetupTriangle {
        primitive_id,
        front_facing,
        v,
        area,
        bias,
        bbox,
        min_depth,
    })
}

/// A lower bound of the depth ([`SetupTriangle::depth`]) at every sample a triangle with vertex
/// depths `z` covers, for the early depth test's shortcut (module docs, "Depth bound"): `0` when
/// a vertex depth is at most 0 (the depth is clamped to `[0, 1]`), `-∞` (no bound) when one is
/// NaN, otherwise `zmin · (1 - 2^-50)` rounded to `f32` and clamped.
///
/// Why it is a bound: at a covered sample every edge function is `>= 0` (the coverage test is
/// `E_i + bias_i >= 0` with `bias_i <= 0`), so the barycentrics `b_i = E_i / area` are `>= 0` and
/// sum to 1 in exact arithmetic (`E_0 + E_1 + E_2 = area`). Each computed `b_i` is within a factor
/// `(1 ± u)` of the exact one (`u = 2^-53`), and the depth's two products and two sums add three
/// more such factors, all of non-negative terms: the `f64` depth is at least
/// `zmin · (1 - u)^4 >= zmin · (1 - 4u)`, which `zmin · (1 - 2^-50)` (at most `zmin · (1 - 7u)`
/// after its own rounding) does not exceed. Rounding to `f32` and clamping are non-decreasing, so
/// the bound survives them.
fn depth_lower_bound(z: [f32; 3]) -> f32 {
    if z.iter().any(|z| z.is_nan()) {
        return f32::NEG_INFINITY;
    }
    let zmin = z[0].min(z[1]).min(z[2]);
    if zmin <= 0.0 {
        return 0.0;
    }
    ((zmin as f64 * (1.0 - DEPTH_BOUND_MARGIN)) as f32).clamp(0.0, 1.0)
}

/// The relative margin of [`depth_lower_bound`]: `2^-50`, above the `4 · 2^-53` that the `f64`
/// depth's five roundings can take off the smallest vertex depth.
const DEPTH_BOUND_MARGIN: f64 = 1.0 / (1u64 << 50) as f64;

impl<const N: usize> SetupTriangle<N> {
    /// Edge functions at the centre of pixel `(x, y)`; `E_i` belongs to the edge opposite vertex
    /// `i`, so `E_i / area` is vertex `i`'s screen-space barycentric weight.
    fn edges(&self, x: u32, y: u32) -> [i64; 3] {
        let s = [
            x as i64 * SUBPIXEL_ONE + SUBPIXEL_HALF,
            y as i64 * SUBPIXEL_ONE + SUBPIXEL_HALF,
        ];
        let p = [self.v[0].pos, self.v[1].pos, self.v[2].pos];
        [
            edge_function(p[1], p[2], s),
            edge_function(p[2], p[0], s),
            edge_function(p[0], p[1], s),
        ]
    }

    /// The edge functions at the four pixel centres of the 2x2 quad at `(qx, qy)`, in [`QUAD`]
    /// order: those of the top-left pixel plus the exact integer steps of one pixel right and one
    /// down (an edge function is linear in the sample position), so each value equals
    /// [`SetupTriangle::edges`] at that pixel bit for bit, for a quarter of the multiplications.
    #[cfg(test)]
    fn quad_edges(&self, qx: u32, qy: u32) -> [[i64; 3]; 4] {
        quad_edges(self.edges(qx, qy), &self.edge_steps())
    }

    /// How the edge functions change one pixel right (`[0]`) and one pixel down (`[1]`): exact
    /// integers, since an edge function is linear in the sample position.
    fn edge_steps(&self) -> [[i64; 3]; 2] {
        let p = self.v.map(|v| v.pos);
        // Edge i runs from a = p[i+1] to b = p[i+2]: E = (b.x - a.x)(s.y - a.y) - (b.y - a.y)(s.x - a.x).
        [
            std::array::from_fn(|i| -(p[(i + 2) % 3][1] - p[(i + 1) % 3][1]) * SUBPIXEL_ONE),
            std::array::from_fn(|i| (p[(i + 2) % 3][0] - p[(i + 1) % 3][0]) * SUBPIXEL_ONE),
        ]
    }

    /// The top-left coverage test (module docs, step 5): `E_i + bias_i >= 0` for all three
    /// edges, written as one sign test of their bitwise OR (negative exactly when one of them
    /// is), which compiles without branches.
    #[inline]
    fn covers(&self, e: &[i64; 3]) -> bool {
        ((e[0] + self.bias[0]) | (e[1] + self.bias[1]) | (e[2] + self.bias[2])) >= 0
    }

    /// Screen-space barycentric weights of a sample with edge functions `e`.
    #[inline]
    fn barycentrics(&self, e: &[i64; 3]) -> [f64; 3] {
        let area = self.area as f64;
        [e[0] as f64 / area, e[1] as f64 / area, e[2] as f64 / area]
    }

    /// Depth at a sample with barycentrics `b` ([`SetupTriangle::barycentrics`]): linear in
    /// screen space, clamped to `[0, 1]`.
    ///
    /// The sums here and in [`SetupTriangle::varyings`] are written out left to right (they were
    /// `Iterator::sum`, whose fold starts at `-0.0`, and `-0.0 + x = x`: the same value bit for
    /// bit, without the iterator and `array::from_fn` overhead, issue 14).
    #[inline]
    fn depth(&self, b: &[f64; 3]) -> f32 {
        let v = &self.v;
        let z = b[0] * v[0].z as f64 + b[1] * v[1].z as f64 + b[2] * v[2].z as f64;
        (z as f32).clamp(0.0, 1.0)
    }

    /// Perspective-correct varyings at a sample with barycentrics `b` (inside the triangle or,
    /// for helper pixels, outside it).
    #[inline]
    fn varyings(&self, b: &[f64; 3]) -> [f32; N] {
        let v = &self.v;
        let q = [b[0] * v[0].inv_w, b[1] * v[1].inv_w, b[2] * v[2].inv_w];
        let denom = q[0] + q[1] + q[2];
        let mut out = [0.0f32; N];
        for (j, o) in out.iter_mut().enumerate() {
            let num = q[0] * v[0].varyings[j] as f64
                + q[1] * v[1].varyings[j] as f64
                + q[2] * v[2].varyings[j] as f64;
            *o = (num / denom) as f32;
        }
        out
    }
}

/// Triangles set up per chunk of [`draw_passes`]: bounds the setup's memory (a setup triangle is
/// about 250 bytes; a million-triangle frame set up at once held over 500 MB, issue 14) without
/// changing any pixel: chunks go in submission order and each tile renders a chunk's triangles in
/// order before the next chunk's, so every pixel still merges its fragments in submission order.
pub const SETUP_CHUNK: usize = 1 << 16;

/// Triangles per parallel work item of the setup (one output vector each).
const SETUP_RUN: usize = 256;

/// Several passes of one draw as a bit set of their indices (pass `p` is bit `1 << p`): see
/// [`PassShader`].
pub type PassSet = u64;

/// Most passes of one [`draw_passes`] (the bits of a [`PassSet`]).
pub const MAX_PASSES: usize = PassSet::BITS as usize;

/// The fragment stage of a draw into several targets at once ([`draw_passes`]; a target with
/// its share of the shading is a **pass**) whose passes differ only in which fragments they keep:
/// each pass is shaded as its own draw would shade it, and a fragment a pass keeps has the same
/// output in every pass that keeps it. What the passes share is everything before the shader
/// (coverage, the barycentrics, depth, varyings and derivatives) and the shader's own work (the
/// tree shader samples its texture once for the six alpha-test cutoffs of the parity's
/// alternative frames, issue 14).
pub trait PassShader<const N: usize>: Sync {
    /// Shades `fragment` for the passes of `passes` (never empty: those whose early depth test
    /// it passed): its output and the passes of `passes` that keep it (not empty), or `None`
    /// when every one of them discards it.
    fn shade_passes(
        &self,
        fragment: &Fragment<N>,
        passes: PassSet,
    ) -> Option<(FragmentOutput, PassSet)>;
}

/// One [`FragmentShader`] as the only pass of a draw ([`RenderTarget::draw`]).
struct One<'a, S: ?Sized>(&'a S);

impl<const N: usize, S> PassShader<N> for One<'_, S>
where
    S: FragmentShader<N> + ?Sized,
{
    #[inline(always)]
    fn shade_passes(
        &self,
        fragment: &Fragment<N>,
        passes: PassSet,
    ) -> Option<(FragmentOutput, PassSet)> {
        self.0.shade(fragment).map(|out| (out, passes))
    }
}

/// Draws one triangle list into several targets of one size (the passes of `shader`, pass `p`
/// into `targets[p]`), sharing the clipping, setup and binning (they depend only on the
/// triangles, the size and `state`) and, for the targets with equal pixel masks, the walk over
/// the quads and everything before the shader (coverage, early depth test, barycentrics,
/// varyings): each target's buffers and counters are exactly those of its own
/// [`RenderTarget::draw`] with its pass's shader. What it is for: the reference frames that
/// differ only in a shader constant (the parity's alternative frames, cutoff moved) cost one
/// setup and one walk, not one each (issue 14).
///
/// Order of work: per chunk of [`SETUP_CHUNK`] triangles, setup in parallel (collected in order),
/// bin by bounding box, then per group of targets with equal masks render every tile (tiles in
/// parallel, each into a private copy of its pixels per target, written back in tile order). A
/// masked group's tiles list only the triangles that cover a pixel of its mask there (the quad
/// loop's own coverage test), and a draw whose every target is masked uses tiles of
/// [`MASKED_TILE_SIZE`]: neither changes a pixel or a counter.
///
/// # Panics
/// If there are more than `u32::MAX` triangles (primitive ids are `u32`, as in Vulkan), more
/// than [`MAX_PASSES`] targets, or the targets differ in size.
pub fn draw_passes<const N: usize, S>(
    targets: &mut [&mut RenderTarget],
    shader: &S,
    triangles: &[Triangle<N>],
    state: &DrawState,
) -> Vec<DrawStats>
where
    S: PassShader<N> + ?Sized,
{
    assert!(
        u32::try_from(triangles.len()).is_ok(),
        "a draw holds at most u32::MAX triangles"
    );
    draw_passes_streamed(targets, shader, &mut SliceSource(triangles), state)
}

/// A triangle list handed to a draw a piece at a time ([`draw_passes_streamed`]), so that the
/// whole list never has to exist at once: the tree draw's vertex stage fills one piece while the
/// previous one is already drawn (issue 14, session 11: a `stress` frame's 10.7 M triangles
/// were 1.15 GB, and allocating, faulting in and copying them was a third of the frame).
pub trait TriangleSource<const N: usize> {
    /// The next triangles in submission order (any number, possibly none), or `None` when the
    /// list has ended. The slice lives until the next call.
    fn next_triangles(&mut self) -> Option<&[Triangle<N>]>;
}

/// A slice as a [`TriangleSource`], in pieces of [`SETUP_CHUNK`].
struct SliceSource<'a, const N: usize>(&'a [Triangle<N>]);

impl<const N: usize> TriangleSource<N> for SliceSource<'_, N> {
    fn next_triangles(&mut self) -> Option<&[Triangle<N>]> {
        if self.0.is_empty() {
            return None;
        }
        let (piece, rest) = self.0.split_at(self.0.len().min(SETUP_CHUNK));
        self.0 = rest;
        Some(piece)
    }
}

/// [`draw_passes`] of the triangles `source` hands out, in its order: the same buffers and
/// counters as [`draw_passes`] of their concatenation, whatever the pieces' sizes. Why: the
/// pieces are set up, binned and rendered one after the other, each tile rendering a piece's
/// triangles in order before the next piece's, so every pixel still merges its fragments in
/// submission order, and a triangle's primitive id is its index in the concatenation. Pieces
/// longer than [`SETUP_CHUNK`] are drawn in chunks of that size.
///
/// # Panics
/// As [`draw_passes`]; the `u32::MAX` limit is checked as the pieces arrive.
pub fn draw_passes_streamed<const N: usize, S>(
    targets: &mut [&mut RenderTarget],
    shader: &S,
    source: &mut dyn TriangleSource<N>,
    state: &DrawState,
) -> Vec<DrawStats>
where
    S: PassShader<N> + ?Sized,
{
    assert!(
        targets.len() <= MAX_PASSES,
        "a draw has at most {MAX_PASSES} passes"
    );
    let mut stats = vec![DrawStats::default(); targets.len()];
    let Some(first) = targets.first() else {
        return stats;
    };
    let (width, height) = (first.width, first.height);
    assert!(
        targets
            .iter()
            .all(|t| (t.width, t.height) == (width, height)),
        "draw_passes: targets differ in size"
    );
    let viewport = Viewport::new(width, height);
    // Draws whose every pass is masked use smaller tiles (issue 14): a masked tile's quad loop
    // still walks each listed triangle's whole box within the tile, so the tile bounds that walk
    // around the few masked pixels. Tiles are disjoint and keep submission order, so the tile
    // size changes no pixel and no counter.
    let tile_size = if targets.iter().all(|t| t.mask.is_some()) {
        MASKED_TILE_SIZE
    } else {
        TILE_SIZE
    };
    let tiles = first.tiles(tile_size);
    let tiles_x = width.div_ceil(tile_size) as usize;
    // The targets grouped by equal pixel masks, in pass order: a group walks its triangles'
    // quads once for all its targets (the coverage test, the only place a mask enters, is the
    // same for all of them). A masked group's triangles per tile are also filtered by its mask:
    // a triangle whose box meets no pixel of the mask inside a tile writes nothing and counts
    // nothing there (every pixel of the quad loop fails the mask), so it is left out of that
    // tile's list. The parity's six alternative frames, masked to ~1 % of the pixels, so skip
    // ~99 % of the tile work.
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for p in 0..targets.len() {
        match groups
            .iter_mut()
            .find(|g| targets[g[0]].mask == targets[p].mask)
        {
            Some(g) => g.push(p),
            None => groups.push(vec![p]),
        }
    }
    let mask_counts: Vec<Option<MaskCounts>> = groups
        .iter()
        .map(|g| {
            let mask = targets[g[0]].mask.as_ref()?;
            Some(MaskCounts::new(mask, width, height))
        })
        .collect();
    // Per group, per tile: whether the mask leaves it any pixel, and its targets' private copies
    // of its pixels, loaded when a triangle first reaches it and written back after the last
    // chunk (one copy each way per draw, not per chunk).
    let live: Vec<Vec<bool>> = groups
        .iter()
        .map(|g| {
            let target = &targets[g[0]];
            tiles.iter().map(|r| target.tile_has_pixels(*r)).collect()
        })
        .collect();
    let mut tile_buffers: Vec<Vec<Option<Vec<TileBuffers>>>> = groups
        .iter()
        .map(|_| tiles.iter().map(|_| None).collect())
        .collect();
    let reads: Vec<&RenderTarget> = targets.iter().map(|t| &**t).collect();
    // Triangles submitted before the current chunk (the first one's primitive id).
    let mut submitted = 0usize;
    while let Some(piece) = source.next_triangles() {
        for chunk in piece.chunks(SETUP_CHUNK) {
            let base = submitted;
            submitted += chunk.len();
            assert!(
                u32::try_from(submitted).is_ok(),
                "a draw holds at most u32::MAX triangles"
            );
            for s in &mut stats {
                s.triangles_in += chunk.len() as u64;
            }
            // Clip, project, snap and set up, in parallel over runs of triangles (one output vector
            // per run, not per triangle), concatenated in submission order.
            let runs: Vec<(SetupCounts, Vec<SetupTriangle<N>>)> = chunk
                .par_chunks(SETUP_RUN)
                .enumerate()
                .map(|(r, run)| {
                    let mut out = Vec::with_capacity(run.len());
                    let mut counts = SetupCounts::default();
                    for (i, tri) in run.iter().enumerate() {
                        let id = (base + r * SETUP_RUN + i) as u32;
                        let c = setup_primitive(id, tri, &viewport, state, &mut out);
                        counts.clipped += c.clipped;
                        counts.rasterized += c.rasterized;
                    }
                    (counts, out)
                })
                .collect();
            // The set-up triangles in submission order, as references into the runs' vectors
            // (session 12, issue 14: concatenating the runs copied 16 MB per chunk on one thread).
            let mut setup: Vec<&SetupTriangle<N>> =
                Vec::with_capacity(runs.iter().map(|(_, t)| t.len()).sum());
            let (mut clipped, mut rasterized) = (0, 0);
            for (counts, tris) in &runs {
                clipped += counts.clipped;
                rasterized += counts.rasterized;
                setup.extend(tris);
            }
            for s in &mut stats {
                s.triangles_clipped += clipped;
                s.triangles_rasterized += rasterized;
            }
            // Bin by bounding box; each bin lists setup indices in increasing, i.e. submission, order.
            let mut bins: Vec<Vec<u32>> = vec![Vec::new(); tiles.len()];
            for (i, tri) in setup.iter().enumerate() {
                let Some(b) = tri.bbox else { continue };
                for ty in (b.y0 / tile_size)..=((b.y1 - 1) / tile_size) {
                    for tx in (b.x0 / tile_size)..=((b.x1 - 1) / tile_size) {
                        bins[ty as usize * tiles_x + tx as usize].push(i as u32);
                    }
                }
            }
            for (((group, counts), live), buffers) in groups
                .iter()
                .zip(&mask_counts)
                .zip(&live)
                .zip(&mut tile_buffers)
            {
                // A masked group's triangles per tile that cover a pixel of the mask there: a box
                // meeting the mask (four lookups), then the same coverage test as the quad loop's at
                // each masked pixel of the box (`edges` equals the quad loop's stepped edge
                // functions bit for bit).
                // The masked pixels are visited from the tile's list of them where that is shorter
                // than the box (the same pixels; `any` does not depend on the order).
                let masked_bins: Option<Vec<Vec<u32>>> = counts.as_ref().map(|counts| {
                    let mask = reads[group[0]].mask.as_deref().expect("a masked group");
                    let covers_mask =
                        |tri: &SetupTriangle<N>, r: &PixelRect, list: &[(u32, u32)]| {
                            if list.len() < r.width() as usize * r.height() as usize {
                                return list.iter().any(|&(x, y)| {
                                    r.contains(x, y) && tri.covers(&tri.edges(x, y))
                                });
                            }
                            (r.y0..r.y1).any(|y| {
                                (r.x0..r.x1).any(|x| {
                                    mask[y as usize * width as usize + x as usize]
                                        && tri.covers(&tri.edges(x, y))
                                })
                            })
                        };
                    tiles
                        .par_iter()
                        .zip(bins.par_iter())
                        .with_max_len(1)
                        .map(|(rect, bin)| {
                            if bin.is_empty() || !counts.any(rect) {
                                return Vec::new();
                            }
                            let list = masked_pixels(*rect, mask, width);
                            bin.iter()
                                .copied()
                                .filter(|&i| {
                                    let tri = setup[i as usize];
                                    tri.bbox.and_then(|b| b.intersect(rect)).is_some_and(|r| {
                                        counts.any(&r) && covers_mask(tri, &r, &list)
                                    })
                                })
                                .collect()
                        })
                        .collect()
                });
                let bins = masked_bins.as_ref().unwrap_or(&bins);
                // Render tiles in parallel, each into its targets' private copies of its pixels.
                let counts: Vec<Vec<FragmentCounts>> = tiles
                    .par_iter()
                    .zip(bins.par_iter())
                    .zip(buffers.par_iter_mut())
                    .zip(live.par_iter())
                    .with_max_len(1)
                    .map(|(((rect, bin), buffers), &live)| {
                        if bin.is_empty() || !live {
                            return Vec::new();
                        }
                        let buffers = buffers.get_or_insert_with(|| {
                            group.iter().map(|&p| reads[p].load_tile(*rect)).collect()
                        });
                        // A group of one target takes a copy of the walk compiled for one (no
                        // loop over targets per pixel; part of undoing a 9-13 % regression of a
                        // plain frame in this function's first form, profile README session 9).
                        if group.len() == 1 {
                            render_tile::<N, S, true>(buffers, group, bin, &setup, shader, state)
                        } else {
                            render_tile::<N, S, false>(buffers, group, bin, &setup, shader, state)
                        }
                    })
                    .collect();
                for tile in counts {
                    for (c, &p) in tile.iter().zip(group) {
                        stats[p].fragments_covered += c.covered;
                        stats[p].fragments_shaded += c.shaded;
                        stats[p].fragments_written += c.written;
                    }
                }
            }
        }
    }
    drop(reads);
    // Write back (tiles are disjoint).
    for (group, buffers) in groups.iter().zip(tile_buffers) {
        for tile in buffers.into_iter().flatten() {
            for (&p, b) in group.iter().zip(&tile) {
                targets[p].store_tile(b);
            }
        }
    }
    stats
}

/// A tile's private copy of its pixels.
struct TileBuffers {
    rect: PixelRect,
    color: Vec<[u8; 4]>,
    depth: Vec<f32>,
    aux: Vec<u32>,
    /// The target's pixel mask over this tile, if it has one.
    mask: Option<Vec<bool>>,
}

#[derive(Clone, Copy, Default)]
struct FragmentCounts {
    covered: u64,
    shaded: u64,
    written: u64,
}

/// Pixel offsets within a quad: top-left, top-right, bottom-left, bottom-right.
const QUAD: [(u32, u32); 4] = [(0, 0), (1, 0), (0, 1), (1, 1)];

/// The edge functions at the four pixel centres of a quad, in [`QUAD`] order, from those `e` of
/// its top-left pixel and the steps of [`SetupTriangle::edge_steps`]: each equals
/// [`SetupTriangle::edges`] at that pixel bit for bit (integer arithmetic), for no
/// multiplication. (Written out element by element: `std::array::from_fn` over `[i64; 3]`
/// compiled to stack copies that were 18 % of a 1280x720 frame, issue 14.)
#[inline]
fn quad_edges(e: [i64; 3], steps: &[[i64; 3]; 2]) -> [[i64; 3]; 4] {
    let [sx, sy] = steps;
    let right = add3(e, *sx);
    [e, right, add3(e, *sy), add3(right, *sy)]
}

/// `a + b` element by element.
#[inline(always)]
fn add3(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a · k` element by element.
#[inline(always)]
fn mul3(a: [i64; 3], k: i64) -> [i64; 3] {
    [a[0] * k, a[1] * k, a[2] * k]
}

/// The quads `m0..m1` (counted from the row's first, `0..row_quads`) of one row of quads that
/// may hold a pixel `tri` covers, from the edge functions `row` at the row's first quad's
/// top-left pixel and the per-pixel `steps`; `None` when none may. Exact (issue 14, session
/// 10): an edge function is linear, so its largest value over a quad's four pixel centres is
/// `E + max(sx, 0) + max(sy, 0)` at the quad's top-left pixel, an exact integer, and a quad
/// where that value plus the edge's bias is negative for some edge covers none of its pixels;
/// along the row that bound is `A + m·2sx`, so the quads it allows form one interval per edge,
/// found by exact integer division. Every skipped quad is one the walk would have left at its
/// coverage test with nothing counted or written. (Every value is an edge function at a real
/// pixel centre or a quad index times a step of at most a tile's width, so within the bounds of
/// "Exact coverage".)
#[inline]
fn covered_quad_span<const N: usize>(
    tri: &SetupTriangle<N>,
    row: [i64; 3],
    steps: &[[i64; 3]; 2],
    row_quads: u32,
) -> Option<(u32, u32)> {
    let (mut lo, mut hi) = (0i64, row_quads as i64);
    for i in 0..3 {
        let (sx, sy) = (steps[0][i], steps[1][i]);
        let a = row[i] + sx.max(0) + sy.max(0) + tri.bias[i];
        let s = 2 * sx;
        if s > 0 {
            if a < 0 {
                // The first m with a + m·s >= 0: ceil(-a / s).
                lo = lo.max((-a + s - 1) / s);
            }
        } else if a < 0 {
            return None; // the bound only falls (or stays) along the row
        } else if s < 0 {
            // The last m with a + m·s >= 0 is floor(a / -s); the range ends after it.
            hi = hi.min(a / -s + 1);
        }
    }
    (lo < hi).then_some((lo as u32, hi as u32))
}

/// Rasterizes the triangles of `bin` (indices into `setup`, in submission order) into one tile
/// of the targets of `group` (pass indices; `buffers[i]` is pass `group[i]`'s copy of the tile,
/// all with the same mask). Returns each pass's counts, in `group` order.
fn render_tile<const N: usize, S, const ONE: bool>(
    buffers: &mut [TileBuffers],
    group: &[usize],
    bin: &[u32],
    setup: &[&SetupTriangle<N>],
    shader: &S,
    state: &DrawState,
) -> Vec<FragmentCounts>
where
    S: PassShader<N> + ?Sized,
{
    let tile = buffers[0].rect;
    // One target's counts live on the stack, where the compiler keeps them in registers.
    let (mut one, mut many) = ([FragmentCounts::default()], Vec::new());
    let counts: &mut [FragmentCounts] = if ONE {
        &mut one
    } else {
        many.resize(group.len(), FragmentCounts::default());
        &mut many
    };
    // Speed-up (issue 14, masked draws): the quads of a masked tile with at least one masked
    // pixel, in row-major order. A quad with none covers nothing (the coverage test below
    // requires the mask), so a triangle may visit only these quads of its box, in the same
    // order, with the edge functions evaluated at each (exact integers, equal to the stepped
    // ones): every value and counter is the full walk's. Used where it is the shorter walk.
    let masked_quads = buffers[0]
        .mask
        .as_ref()
        .map(|mask| masked_quads(tile, mask));
    for tri in bin.iter().map(|&i| setup[i as usize]) {
        let Some(r) = tri.bbox.and_then(|b| b.intersect(&tile)) else {
            continue;
        };
        // Quads are aligned to even coordinates; tiles start at even coordinates too. The edge
        // functions walk the quads by exact integer steps (two pixels per quad) from those of
        // the first quad's top-left pixel.
        let (qx0, qy0) = (r.x0 & !1, r.y0 & !1);
        let steps = tri.edge_steps();
        let box_quads = (r.x1 - qx0).div_ceil(2) as usize * (r.y1 - qy0).div_ceil(2) as usize;
        if let Some(list) = masked_quads.as_ref().filter(|l| l.len() < box_quads) {
            for &(qx, qy) in list {
                if qx < qx0 || qx >= r.x1 || qy < qy0 || qy >= r.y1 {
                    continue;
                }
                let edges = quad_edges(tri.edges(qx, qy), &steps);
                shade_quad::<N, S, ONE>(
                    buffers,
                    group,
                    tri,
                    &r,
                    (qx, qy),
                    &edges,
                    shader,
                    state,
                    counts,
                );
            }
            continue;
        }
        let [two_sx, two_sy] = steps.map(|s| add3(s, s));
        let row_quads = (r.x1 - qx0).div_ceil(2);
        let mut row_edges = tri.edges(qx0, qy0);
        for qy in (qy0..r.y1).step_by(2) {
            let row_start = row_edges;
            row_edges = add3(row_edges, two_sy);
            // Only the quads of this row that can hold a covered pixel (exact, see
            // `covered_quad_span`): the others would cover, count and write nothing.
            let Some((m0, m1)) = covered_quad_span(tri, row_start, &steps, row_quads) else {
                continue;
            };
            let mut quad_e = add3(row_start, mul3(two_sx, m0 as i64));
            for qx in (qx0 + 2 * m0..qx0 + 2 * m1).step_by(2) {
                let edges = quad_edges(quad_e, &steps);
                quad_e = add3(quad_e, two_sx);
                shade_quad::<N, S, ONE>(
                    buffers,
                    group,
                    tri,
                    &r,
                    (qx, qy),
                    &edges,
                    shader,
                    state,
                    counts,
                );
            }
        }
    }
    counts.to_vec()
}

/// The pixels of `tile` set in `mask` (the whole target's row-major pixel mask, `width` wide),
/// in row-major order.
fn masked_pixels(tile: PixelRect, mask: &[bool], width: u32) -> Vec<(u32, u32)> {
    let mut pixels = Vec::new();
    for y in tile.y0..tile.y1 {
        for x in tile.x0..tile.x1 {
            if mask[y as usize * width as usize + x as usize] {
                pixels.push((x, y));
            }
        }
    }
    pixels
}

/// The quads (top-left pixel, even coordinates) of `tile` with at least one pixel set in
/// `mask` (the tile's row-major pixel mask), in row-major order.
fn masked_quads(tile: PixelRect, mask: &[bool]) -> Vec<(u32, u32)> {
    let tile_w = tile.width();
    let mut quads = Vec::new();
    for qy in (tile.y0..tile.y1).step_by(2) {
        for qx in (tile.x0..tile.x1).step_by(2) {
            let any = QUAD.iter().any(|&(dx, dy)| {
                let (x, y) = (qx + dx, qy + dy);
                x < tile.x1
                    && y < tile.y1
                    && mask[((y - tile.y0) * tile_w + (x - tile.x0)) as usize]
            });
            if any {
                quads.push((qx, qy));
            }
        }
    }
    quads
}

/// One 2x2 quad of one triangle in a tile of the targets of `group` (module docs, steps 7-9):
/// coverage (once for all), the early depth test (per target), interpolation with the quad's
/// derivatives (once, for the pixels some target shades), shading (once per pixel, for the
/// passes whose test it passed: [`PassShader`]), the late depth test and the merge (per target).
/// `r`: the triangle's box within the tile; `edges`: the edge functions at the quad's four
/// pixels; `buffers`, `counts`: per target, in `group` order.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn shade_quad<const N: usize, S, const ONE: bool>(
    buffers: &mut [TileBuffers],
    group: &[usize],
    tri: &SetupTriangle<N>,
    r: &PixelRect,
    (qx, qy): (u32, u32),
    edges: &[[i64; 3]; 4],
    shader: &S,
    state: &DrawState,
    counts: &mut [FragmentCounts],
) where
    S: PassShader<N> + ?Sized,
{
    // With `ONE` (a group of one target) the loops over targets below run once, and the
    // compiler knows it.
    let n = if ONE { 1 } else { buffers.len() };
    let (buffers, counts, group) = (&mut buffers[..n], &mut counts[..n], &group[..n]);
    let tile = buffers[0].rect;
    let tile_w = tile.width();
    // Covered pixels: inside the triangle, and pixels this tile may write (inside the
    // triangle's box and the tile, and inside the targets' pixel mask if they have one). `at`:
    // each pixel's index in the tile buffers.
    let first = ((qy - tile.y0) * tile_w + (qx - tile.x0)) as usize;
    let at = [
        first,
        first + 1,
        first + tile_w as usize,
        first + tile_w as usize + 1,
    ];
    let mut covered = [false; 4];
    {
        let mask = buffers[0].mask.as_ref();
        for k in 0..4 {
            covered[k] = tri.covers(&edges[k])
                && r.contains(qx + QUAD[k].0, qy + QUAD[k].1)
                && mask.is_none_or(|m| m[at[k]]);
        }
    }
    if covered == [false; 4] {
        return;
    }
    // The early depth test of the covered pixels (module docs, step 8), per target: `passed[k]`
    // holds the passes whose test pixel `k` passed.
    // Barycentrics are computed once per pixel and shared by depth and varyings.
    let mut bary = [[0.0f64; 3]; 4];
    let mut have_bary = [false; 4];
    let mut depth = [0.0f32; 4];
    let mut passed: [PassSet; 4] = [0; 4];
    for k in (0..4).filter(|&k| covered[k]) {
        // Depth bound (module docs): the passes whose stored depth is at most the triangle's
        // lower bound fail the test whatever the interpolated depth; the others may pass.
        // `at[k]` may lie outside the tile only for uncovered pixels.
        let mut may_pass: PassSet = 0;
        for ((b, c), &p) in buffers.iter().zip(counts.iter_mut()).zip(group) {
            c.covered += 1;
            if !state.depth_test || tri.min_depth < b.depth[at[k]] {
                may_pass |= 1 << p;
            }
        }
        if may_pass == 0 {
            continue;
        }
        bary[k] = tri.barycentrics(&edges[k]);
        have_bary[k] = true;
        depth[k] = tri.depth(&bary[k]);
        for (b, &p) in buffers.iter().zip(group) {
            if may_pass & (1 << p) != 0 && (!state.depth_test || depth[k] < b.depth[at[k]]) {
                passed[k] |= 1 << p;
            }
        }
    }
    if passed == [0; 4] {
        return;
    }
    // The derivatives need the top three pixels, covered or not (helpers); the bottom-right
    // one is interpolated only if it is shaded.
    for k in (0..3).filter(|&k| !have_bary[k]) {
        bary[k] = tri.barycentrics(&edges[k]);
    }
    let mut values = [[0.0f32; N]; 4];
    for k in (0..4).filter(|&k| k < 3 || passed[k] != 0) {
        values[k] = tri.varyings(&bary[k]);
    }
    let ddx = std::array::from_fn(|j| values[1][j] - values[0][j]);
    let ddy = std::array::from_fn(|j| values[2][j] - values[0][j]);
    for k in (0..4).filter(|&k| passed[k] != 0) {
        for (c, &p) in counts.iter_mut().zip(group) {
            c.shaded += u64::from(passed[k] & (1 << p) != 0);
        }
        let fragment = Fragment {
            x: qx + QUAD[k].0,
            y: qy + QUAD[k].1,
            depth: depth[k],
            varyings: values[k],
            ddx,
            ddy,
            front_facing: tri.front_facing,
            primitive_id: tri.primitive_id,
        };
        let Some((out, kept)) = shader.shade_passes(&fragment, passed[k]) else {
            continue; // discarded by every pass
        };
        let at = at[k];
        for ((b, c), &p) in buffers.iter_mut().zip(counts.iter_mut()).zip(group) {
            if kept & (1 << p) == 0 {
                continue;
            }
            // Shader-written depth (module docs, step 8): clamped, then the late test.
            let z = match out.depth {
                None => depth[k],
                Some(d) if d.is_nan() => continue,
                Some(d) => {
                    let d = d.clamp(0.0, 1.0);
                    if state.depth_test && d >= b.depth[at] {
                        continue;
                    }
                    d
                }
            };
            c.written += 1;
            if state.depth_write {
                b.depth[at] = z;
            }
            b.color[at] = merge(b.color[at], out.color, state.blend);
            b.aux[at] = out.id;
        }
    }
}

/// Clamps to `[0, 1]`, NaN to 0 (Vulkan: fixed-point attachments clamp source values before
/// blending).
#[inline]
fn clamp_color(c: [f32; 4]) -> [f32; 4] {
    c.map(|v| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) })
}

/// sRGB8 colour, UNORM8 alpha, rounded to nearest.
#[inline]
fn encode(c: [f32; 4]) -> [u8; 4] {
    [srgb8(c[0]), srgb8(c[1]), srgb8(c[2]), unorm8(c[3])]
}

/// [`linear_to_srgb`] bit for bit, by table (speed-up, issue 14: the exact function takes an
/// `f64` `powf` per channel of every written fragment). `linear_to_srgb` is a non-decreasing step
/// function of its `f32` argument (`powf` is accurate to far less than the relative gap between
/// two neighbouring `f32`s, and every later step is monotone), so it equals "the largest byte
/// whose first input is at most `l`", found by binary search in [`srgb_thresholds`]. Checked at
/// every step's edge and on a dense sample by `srgb8_equals_linear_to_srgb`; the exhaustive check
/// over every `f32` in `[0, 1]` is the ignored `srgb8_equals_linear_to_srgb_everywhere`.
#[inline]
fn srgb8(l: f32) -> u8 {
    // NaN, negative values and zero encode to 0, as in `linear_to_srgb`.
    if l.is_nan() || l <= 0.0 {
        return 0;
    }
    if l >= 1.0 {
        return 255;
    }
    // The largest `c` with `t[c] <= l` (`t[0] = 0 < l`): start from the code of the first `f32`
    // of `l`'s bucket, which is at most `l`'s (non-decreasing), and step up while the next
    // threshold is still at most `l` (round 3, issue 14: was a binary search over all 256).
    let t = srgb_thresholds();
    let mut c = srgb_bucket_starts()[(l.to_bits() >> SRGB_BUCKET_SHIFT) as usize];
    while c < 255 && t[c as usize + 1] <= l {
        c += 1;
    }
    c
}

/// `f32`s of `[0, 1)` fall into buckets of `2^SRGB_BUCKET_SHIFT` consecutive bit patterns (a
/// relative width of `2^-8` of the value): few enough that [`srgb8`] steps past at most one or
/// two thresholds in any bucket, and 32,512 bytes of [`srgb_bucket_starts`].
const SRGB_BUCKET_SHIFT: u32 = 15;

/// Per bucket (module-level [`SRGB_BUCKET_SHIFT`]): the code of its first `f32`, by binary
/// search in [`srgb_thresholds`]. Any lower bound of the answer would keep [`srgb8`] exact;
/// this one is the tightest.
fn srgb_bucket_starts() -> &'static [u8] {
    static STARTS: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    STARTS.get_or_init(|| {
        let t = srgb_thresholds();
        (0..=(1.0f32.to_bits() >> SRGB_BUCKET_SHIFT))
            .map(|i| {
                let first = f32::from_bits(i << SRGB_BUCKET_SHIFT);
                (t.partition_point(|&x| x <= first).max(1) - 1) as u8
            })
            .collect()
    })
}

/// `t[c]`: the smallest `f32` in `[0, 1]` that [`linear_to_srgb`] encodes to `c` or more (found by
/// bisection on the bit patterns, which order non-negative `f32`s); `t[0] = 0`.
fn srgb_thresholds() -> &'static [f32; 256] {
    static THRESHOLDS: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    THRESHOLDS.get_or_init(|| {
        let mut t = [0.0f32; 256];
        for (c, slot) in t.iter_mut().enumerate().skip(1) {
            // Invariant: encode(lo) < c <= encode(hi).
            let (mut lo, mut hi) = (0.0f32.to_bits(), 1.0f32.to_bits());
            while hi - lo > 1 {
                let mid = lo + (hi - lo) / 2;
                if linear_to_srgb(f32::from_bits(mid)) as usize >= c {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            *slot = f32::from_bits(hi);
        }
        t
    })
}

fn decode(c: [u8; 4]) -> [f32; 4] {
    [
        srgb_to_linear(c[0]),
        srgb_to_linear(c[1]),
        srgb_to_linear(c[2]),
        c[3] as f32 / 255.0,
    ]
}

/// The output merge of one fragment into an sRGB8 pixel (module docs, step 9).
///
/// Speed-up (issue 14): source-over with an opaque source (`a = 1` after clamping) is the
/// replace, without decoding the destination. Exact: a decoded destination channel `d` is finite
/// and in `[0, 1]`, so `s·1 + d·0 = s + 0 = s` (`-0 + 0` gives `+0`, and both encode to 0) and
/// `1 + d·0 = 1`. Checked against [`source_over`] by `opaque_source_over_equals_replace`.
#[inline]
fn merge(dst: [u8; 4], src: [f32; 4], blend: Blend) -> [u8; 4] {
    let s = clamp_color(src);
    match blend {
        Blend::Replace => encode(s),
        Blend::AlphaBlend if s[3] == 1.0 => encode(s),
        Blend::AlphaBlend => source_over(dst, s),
    }
}

/// Straight-alpha source-over of a clamped source `s` onto an sRGB8 pixel, in linear light.
fn source_over(dst: [u8; 4], s: [f32; 4]) -> [u8; 4] {
    let d = decode(dst);
    let a = s[3];
    let rgb = |i: usize| s[i] * a + d[i] * (1.0 - a);
    encode([rgb(0), rgb(1), rgb(2), a + d[3] * (1.0 - a)])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic stream of `f32` in `[0, 1)` (a 64-bit LCG's top 24 bits) for the random
    /// triangles of the mask tests.
    fn unit_random(mut seed: u64) -> impl FnMut() -> f32 {
        move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    fn vertex(x: f32, y: f32) -> Vertex<0> {
        Vertex::new([x, y, 0.5, 1.0], [])
    }

    #[test]
    fn top_left_classification_of_a_clockwise_triangle() {
        // (0,0) -> (4,0) -> (0,4) in y-down pixels has positive area: top edge, hypotenuse
        // (bottom-right, not top-left), left edge.
        let p = [[0, 0], [4, 0], [0, 4]];
        assert!(edge_function(p[0], p[1], p[2]) > 0);
        assert!(is_top_left(p[0], p[1]));
        assert!(!is_top_left(p[1], p[2]));
        assert!(is_top_left(p[2], p[0]));
        // A bottom edge is not top-left.
        assert!(!is_top_left([4, 4], [0, 4]));
    }

    #[test]
    fn the_clipper_keeps_inside_triangles_untouched_and_drops_outside_ones() {
        let vp = Viewport::new(16, 16);
        let inside = [vertex(-0.5, -0.5), vertex(0.5, -0.5), vertex(0.0, 0.5)];
        assert_eq!(clip_triangle(&inside, &vp), inside.to_vec());
        let behind = inside.map(|v| Vertex::new([v.clip[0], v.clip[1], -0.1, 1.0], []));
        assert!(clip_triangle(&behind, &vp).is_empty());
        let beyond = inside.map(|v| Vertex::new([v.clip[0], v.clip[1], 1.5, 1.0], []));
        assert!(clip_triangle(&beyond, &vp).is_empty());
    }

    #[test]
    fn the_clipper_cuts_at_the_near_plane_and_keeps_the_polygon_convex() {
        let vp = Viewport::new(16, 16);
        let tri = [
            Vertex::new([0.0, 0.0, -1.0, 1.0], [0.0]),
            Vertex::new([0.5, 0.0, 1.0, 2.0], [1.0]),
            Vertex::new([0.0, 0.5, 1.0, 2.0], [1.0]),
        ];
        let poly = clip_triangle(&tri, &vp);
        assert_eq!(poly.len(), 4);
        for v in &poly {
            assert!(v.clip[2] >= 0.0 && v.clip[2] <= v.clip[3], "{v:?}");
        }
        // The cut points are halfway along the edges from the clipped vertex (z: -1 -> 1).
        assert!(poly.iter().any(|v| v.varyings == [0.5]));
    }

    #[test]
    fn a_shared_edge_is_cut_at_the_same_point_from_both_sides() {
        let vp = Viewport::new(16, 16);
        let a = Vertex::new([0.3, -0.7, -0.37, 1.3], [0.1]);
        let b = Vertex::new([-0.2, 0.9, 0.81, 1.1], [0.7]);
        let c = Vertex::new([0.9, 0.4, 0.5, 1.0], [0.3]);
        let d = Vertex::new([-0.9, -0.4, 0.5, 1.0], [0.9]);
        let p1 = clip_triangle(&[a, b, c], &vp);
        let p2 = clip_triangle(&[b, a, d], &vp);
        let new1: Vec<_> = p1.iter().filter(|v| ![a, b, c].contains(v)).collect();
        let new2: Vec<_> = p2.iter().filter(|v| ![a, b, d].contains(v)).collect();
        let common: Vec<_> = new1.iter().filter(|v| new2.contains(v)).collect();
        assert_eq!(common.len(), 1, "{p1:?}\n{p2:?}");
        assert!(common[0].clip[2].abs() < 1e-6);
    }

    #[test]
    fn blending_is_source_over_in_linear_light_with_srgb_storage() {
        let dst = encode([1.0, 0.0, 0.0, 1.0]);
        let out = merge(dst, [0.0, 0.0, 1.0, 0.5], Blend::AlphaBlend);
        assert_eq!(out, [linear_to_srgb(0.5), 0, linear_to_srgb(0.5), 255]);
        assert_eq!(
            merge(dst, [2.0, f32::NAN, -1.0, 1.0], Blend::Replace),
            [255, 0, 0, 255]
        );
        // Alpha: a + d.a (1 - a).
        let out = merge(encode([0.0; 4]), [1.0, 1.0, 1.0, 0.5], Blend::AlphaBlend);
        assert_eq!(out[3], unorm8(0.5));
    }

    /// The table encoder equals the exact one at both sides of every step, at the special values
    /// and on a sample of about 260,000 `f32`s spread over `[0, 1]`.
    /// The opaque shortcut of [`merge`] gives what [`source_over`] gives, for every destination
    /// byte in every channel and sources below, inside and above `[0, 1]`, signed zeros and NaN.
    #[test]
    fn opaque_source_over_equals_replace() {
        let values = [
            -0.0,
            0.0,
            -1.0,
            1e-9,
            0.0031308,
            0.2,
            0.5,
            0.99999994,
            1.0,
            1.5,
            f32::NAN,
        ];
        let alphas = [
            1.0,
            1.5,
            7.0,
            f32::INFINITY,
            0.99999994,
            0.999,
            0.99,
            0.9,
            0.5,
            0.0,
        ];
        let mut checked = 0;
        for b in 0..=255u8 {
            for dst in [
                [b, b, b, b],
                [b, 255 - b, b / 3, 255 - b],
                [0, b, 255, b / 2],
            ] {
                for &r in &values {
                    for (j, &a) in alphas.iter().enumerate() {
                        let src = [
                            r,
                            values[j % values.len()],
                            values[(j + 3) % values.len()],
                            a,
                        ];
                        assert_eq!(
                            merge(dst, src, Blend::AlphaBlend),
                            source_over(dst, clamp_color(src)),
                            "dst {dst:?} src {src:?}"
                        );
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 50_000);
    }

    #[test]
    fn srgb8_equals_linear_to_srgb() {
        let mut checked = 0;
        let mut check = |l: f32| {
            assert_eq!(
                srgb8(l),
                linear_to_srgb(l),
                "l = {l:e} ({:#x})",
                l.to_bits()
            );
            checked += 1;
        };
        for &t in &srgb_thresholds()[1..] {
            check(t);
            check(f32::from_bits(t.to_bits() - 1));
        }
        for l in [
            0.0,
            -0.0,
            -1.0,
            1.0,
            2.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MIN_POSITIVE,
            0.0031308,
        ] {
            check(l);
        }
        // Both ends of every bucket of `srgb_bucket_starts`.
        for i in 0..=(1.0f32.to_bits() >> SRGB_BUCKET_SHIFT) {
            check(f32::from_bits(i << SRGB_BUCKET_SHIFT));
            check(f32::from_bits(((i + 1) << SRGB_BUCKET_SHIFT) - 1));
        }
        for bits in (0..=1.0f32.to_bits()).step_by(4099) {
            check(f32::from_bits(bits));
        }
        assert!(checked > 250_000);
        // Every byte round-trips through the decoder.
        for c in 0..=255u8 {
            assert_eq!(srgb8(srgb_to_linear(c)), c);
        }
    }

    /// Every `f32` in `[0, 1]` (about 10^9 of them, a minute in release): run with
    /// `cargo test --release -p forestlod-reference srgb8_equals -- --ignored`.
    #[test]
    #[ignore = "exhaustive, about 10^9 values: run explicitly with --ignored in release"]
    fn srgb8_equals_linear_to_srgb_everywhere() {
        let end = 1.0f32.to_bits();
        let bad = (0..=end)
            .into_par_iter()
            .filter(|&b| srgb8(f32::from_bits(b)) != linear_to_srgb(f32::from_bits(b)))
            .count();
        assert_eq!(bad, 0);
    }

    /// `quad_edges` (incremental) equals `edges` evaluated at each of the quad's pixels, for
    /// triangles of every size up to the guard band, both windings.
    /// `round_ties_even_exact` and `round_exact` equal `f32::round_ties_even` and `f32::round`
    /// bit for bit: at the special values, at every half-integer below `2^23` and its two
    /// neighbours (the ties and the values either side) for a sample of them, and on a dense
    /// sample of bit patterns of both signs (every 997th).
    #[test]
    fn rounding_helpers_equal_the_standard_library() {
        let mut checked = 0u64;
        let mut check = |c: f32| {
            for c in [c, -c] {
                assert_eq!(
                    round_ties_even_exact(c).to_bits(),
                    c.round_ties_even().to_bits(),
                    "round_ties_even({c:e})"
                );
                assert_eq!(
                    round_exact(c).to_bits(),
                    c.round().to_bits(),
                    "round({c:e})"
                );
                checked += 1;
            }
        };
        for c in [
            0.0,
            0.5,
            1.5,
            2.5,
            0.49999997,
            f32::MIN_POSITIVE,
            1e-45,
            8_388_607.5,
            8_388_608.0,
            16_777_217.0,
            f32::MAX,
            f32::INFINITY,
            f32::NAN,
        ] {
            check(c);
        }
        for i in (0..(1u32 << 23)).step_by(101) {
            let half = i as f32 + 0.5;
            check(half);
            check(f32::from_bits(half.to_bits() - 1));
            check(f32::from_bits(half.to_bits() + 1));
        }
        for bits in (0..0x7f80_0000u32).step_by(997) {
            check(f32::from_bits(bits));
        }
        assert!(checked > 4_000_000, "{checked}");
    }

    /// Random set-up triangles of several sizes, depths and perspectives, for the walk's exact
    /// shortcuts below.
    fn random_setup_triangles(seed: u64, cases: usize) -> Vec<SetupTriangle<0>> {
        let vp = Viewport::new(640, 360);
        let mut next = unit_random(seed);
        let mut out = Vec::new();
        for case in 0..cases {
            let scale = [0.01, 0.2, 1.0, 4.0, 4000.0][case % 5];
            let depth_range = [1.0, 1e-3, 0.0][case % 3];
            let base = next();
            let tri = [0, 1, 2].map(|_| {
                let w = [1.0, 0.5 + 4.0 * next()][case % 2];
                let (mut x, mut y) = ((next() * 2.0 - 1.0) * scale, (next() * 2.0 - 1.0) * scale);
                if case % 7 == 0 {
                    // On pixel centres: edge functions land exactly on 0 and on multiples of
                    // their steps, the edge cases of exact integer division.
                    let centre = |c: f32, size: f32| {
                        let px = ((c.clamp(-1.0, 1.0) + 1.0) / 2.0 * size).floor() + 0.5;
                        px / size * 2.0 - 1.0
                    };
                    (x, y) = (centre(x, 640.0), -centre(-y, 360.0));
                }
                let z = (base + depth_range * next()).min(1.0);
                Vertex::new([x * w, y * w, z * w, w], [])
            });
            setup_primitive(case as u32, &tri, &vp, &DrawState::OPAQUE, &mut out);
        }
        out
    }

    #[test]
    fn covered_quad_spans_hold_every_quad_with_a_covered_pixel() {
        let (mut covered_quads, mut skipped) = (0, 0);
        for t in random_setup_triangles(0x51ab_1e5e, 600) {
            let Some(b) = t.bbox else { continue };
            // A window of the box as large as a tile, as `render_tile` walks it.
            let r = PixelRect {
                x1: b.x1.min(b.x0 + TILE_SIZE),
                y1: b.y1.min(b.y0 + TILE_SIZE),
                ..b
            };
            let (qx0, qy0) = (r.x0 & !1, r.y0 & !1);
            let steps = t.edge_steps();
            let row_quads = (r.x1 - qx0).div_ceil(2);
            for qy in (qy0..r.y1).step_by(2) {
                let span = covered_quad_span(&t, t.edges(qx0, qy), &steps, row_quads);
                for m in 0..row_quads {
                    let qx = qx0 + 2 * m;
                    let any = QUAD.iter().any(|&(dx, dy)| {
                        r.contains(qx + dx, qy + dy) && t.covers(&t.edges(qx + dx, qy + dy))
                    });
                    let inside = span.is_some_and(|(m0, m1)| (m0..m1).contains(&m));
                    assert!(
                        !any || inside,
                        "quad ({qx}, {qy}) covers a pixel, span {span:?}"
                    );
                    covered_quads += u32::from(any);
                    skipped += u32::from(!inside);
                }
            }
        }
        assert!(
            covered_quads > 2_000,
            "only {covered_quads} covered quads checked"
        );
        assert!(skipped > 2_000, "the spans skipped only {skipped} quads");
    }

    #[test]
    fn the_depth_bound_is_at_most_every_covered_depth() {
        let (mut checked, mut equal) = (0, 0);
        for t in random_setup_triangles(0xde97_4b0d, 600) {
            let Some(b) = t.bbox else { continue };
            for y in b.y0..b.y1.min(b.y0 + 48) {
                for x in b.x0..b.x1.min(b.x0 + 48) {
                    let e = t.edges(x, y);
                    if !t.covers(&e) {
                        continue;
                    }
                    let depth = t.depth(&t.barycentrics(&e));
                    assert!(
                        t.min_depth <= depth,
                        "pixel ({x}, {y}): depth {depth} below the bound {}",
                        t.min_depth
                    );
                    checked += 1;
                    equal += u32::from(t.min_depth == depth);
                }
            }
        }
        assert!(checked > 20_000, "only {checked} covered pixels checked");
        // Flat triangles reach their bound: it is not a loose one.
        assert!(
            equal > 1_000,
            "the bound was reached at only {equal} pixels"
        );
    }

    #[test]
    fn quad_edges_equal_the_edge_functions_at_each_pixel() {
        let vp = Viewport::new(640, 360);
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f32 / (1u64 << 53) as f32
        };
        let mut checked = 0;
        for case in 0..400 {
            let scale = [1.0, 4.0, 4000.0][case % 3];
            let tri = [0, 1, 2]
                .map(|_| vertex((next() * 2.0 - 1.0) * scale, (next() * 2.0 - 1.0) * scale));
            let mut pieces = Vec::new();
            setup_primitive(case as u32, &tri, &vp, &DrawState::OPAQUE, &mut pieces);
            for t in &pieces {
                let Some(b) = t.bbox else { continue };
                for qy in ((b.y0 & !1)..b.y1.min(b.y0 + 40)).step_by(2) {
                    for qx in ((b.x0 & !1)..b.x1.min(b.x0 + 40)).step_by(2) {
                        let quad = t.quad_edges(qx, qy);
                        for (k, (dx, dy)) in QUAD.iter().enumerate() {
                            assert_eq!(quad[k], t.edges(qx + dx, qy + dy), "case {case}");
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert!(checked > 10_000, "only {checked} pixels checked");
    }

    /// `n` small triangles scattered over the viewport and a little beyond it, each at one
    /// depth, of side up to `size` in NDC, varying `varying(i)` for triangle `i` (xorshift from
    /// `seed`).
    fn scattered_triangles(
        n: usize,
        size: f32,
        seed: u64,
        varying: impl Fn(usize, f32) -> f32,
    ) -> Vec<Triangle<1>> {
        let mut seed = seed;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        (0..n)
            .map(|i| {
                let (cx, cy) = (next() * 2.2 - 1.1, next() * 2.2 - 1.1);
                let z = next();
                [0, 1, 2].map(|_| {
                    let p = [cx + next() * size, cy + next() * size, z, 1.0];
                    Vertex::new(p, [varying(i, next())])
                })
            })
            .collect()
    }

    /// Asserts that two targets hold the same colour, id and depth bits.
    fn assert_same_buffers(a: &RenderTarget, b: &RenderTarget) {
        assert_eq!(a.color(), b.color());
        assert_eq!(a.aux(), b.aux());
        let bits = |t: &RenderTarget| t.depth().iter().map(|d| d.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(a), bits(b));
    }

    /// One draw of more than two setup chunks equals the same triangles drawn as consecutive
    /// draws of one chunk each (the shader ignores the primitive id, which restarts per draw):
    /// the per-draw tile buffers carry every chunk's writes to the next, in submission order.
    #[test]
    fn a_draw_across_setup_chunks_equals_consecutive_draws() {
        let (w, h) = (72, 40);
        let n = 2 * SETUP_CHUNK + 1000;
        let tris = scattered_triangles(n, 0.15, 0x2545_f491_4f6c_dd1d, |i, _| {
            (i % 251) as f32 / 251.0
        });
        let shader = |f: &Fragment<1>| {
            (f.varyings[0] > 0.1).then_some(FragmentOutput {
                color: [f.varyings[0], 1.0 - f.varyings[0], 0.5, 0.6],
                id: (f.varyings[0] * 251.0) as u32,
                depth: None,
            })
        };
        let state = DrawState {
            depth_write: true,
            ..DrawState::TRANSPARENT
        };
        let mut one = RenderTarget::new(w, h, ClearValues::default());
        let s1 = one.draw(&tris, &shader, &state);
        let mut parts = RenderTarget::new(w, h, ClearValues::default());
        let mut s2 = DrawStats::default();
        for chunk in tris.chunks(SETUP_CHUNK) {
            s2 += parts.draw(chunk, &shader, &state);
        }
        assert_eq!(s1, s2);
        assert!(s1.fragments_written > 10_000, "{s1:?}");
        assert_same_buffers(&one, &parts);
    }

    /// A target made after others were drawn into and dropped (their buffers are kept for the
    /// next target, `Spare`) holds exactly its clear values, at its own size, whichever
    /// buffers it got.
    #[test]
    fn a_new_target_is_cleared_whatever_buffers_it_reuses() {
        let tri = [
            Vertex::new([-1.0, -1.0, 0.25, 1.0], [0.0]),
            Vertex::new([3.0, -1.0, 0.25, 1.0], [0.0]),
            Vertex::new([-1.0, 3.0, 0.25, 1.0], [0.0]),
        ];
        let shader = |_: &Fragment<1>| {
            Some(FragmentOutput {
                color: [0.9, 0.1, 0.4, 1.0],
                id: 77,
                depth: None,
            })
        };
        let clear = ClearValues {
            color: [0.2, 0.3, 0.4, 1.0],
            depth: 0.75,
            aux: 5,
        };
        // (used target's size, new target's size): reused buffers longer and shorter than the
        // new target's, and longer than one parallel fill piece (65,536 values).
        for ((uw, uh), (w, h)) in [
            ((43, 30), (40, 30)),
            ((43, 30), (40, 30)),
            ((67, 48), (64, 48)),
            ((19, 8), (16, 8)),
            ((43, 30), (40, 30)),
            ((303, 250), (300, 250)),
            ((40, 30), (300, 250)),
            ((16, 8), (300, 250)),
        ] {
            let mut used = RenderTarget::new(uw, uh, ClearValues::default());
            used.draw(&[tri], &shader, &DrawState::OPAQUE);
            assert!(used.aux().iter().all(|&a| a == 77));
            drop(used);
            let fresh = RenderTarget::new(w, h, clear);
            let n = (w * h) as usize;
            assert_eq!(fresh.color().len(), n);
            assert_eq!(fresh.depth().len(), n);
            assert_eq!(fresh.aux().len(), n);
            let c = encode(clamp_color(clear.color));
            assert!(fresh.color().iter().all(|&p| p == c), "{w}x{h}");
            assert!(fresh.depth().iter().all(|&d| d == 0.75), "{w}x{h}");
            assert!(fresh.aux().iter().all(|&a| a == 5), "{w}x{h}");
        }
    }

    /// A list handed out in uneven pieces (empty ones, one triangle, more than a setup chunk)
    /// draws exactly what one draw of the whole list draws, primitive ids included: a piece's
    /// first id continues the previous piece's count (issue 14, session 11).
    #[test]
    fn a_streamed_draw_in_uneven_pieces_equals_one_draw() {
        struct Pieces<'a> {
            rest: &'a [Triangle<1>],
            sizes: std::vec::IntoIter<usize>,
        }
        impl TriangleSource<1> for Pieces<'_> {
            fn next_triangles(&mut self) -> Option<&[Triangle<1>]> {
                let n = self.sizes.next().unwrap_or(self.rest.len());
                if n == 0 && self.rest.is_empty() {
                    return None;
                }
                let (piece, rest) = self.rest.split_at(n.min(self.rest.len()));
                self.rest = rest;
                Some(piece)
            }
        }
        let (w, h) = (64, 48);
        let n = SETUP_CHUNK + 3000;
        let tris = scattered_triangles(n, 0.2, 0x9e37_79b9_7f4a_7c15, |_, r| r);
        // The id is the primitive id: a piece restarting the count would show.
        let shader = |f: &Fragment<1>| {
            (f.varyings[0] > 0.2).then_some(FragmentOutput {
                color: [f.varyings[0], 0.3, 0.5, 0.7],
                id: f.primitive_id,
                depth: None,
            })
        };
        let state = DrawState {
            depth_write: true,
            ..DrawState::TRANSPARENT
        };
        let mut one = RenderTarget::new(w, h, ClearValues::default());
        let s1 = one.draw(&tris, &shader, &state);
        let mut streamed = RenderTarget::new(w, h, ClearValues::default());
        let mut source = Pieces {
            rest: &tris,
            sizes: vec![0, 1, 0, 7, SETUP_CHUNK + 5, 0, 1000].into_iter(),
        };
        let s2 = draw_passes_streamed(&mut [&mut streamed], &One(&shader), &mut source, &state)[0];
        assert_eq!(s1, s2);
        assert_eq!(s1.triangles_in, n as u64);
        assert!(s1.fragments_written > 10_000, "{s1:?}");
        assert!(
            one.aux().iter().any(|&id| id as usize > SETUP_CHUNK + 13),
            "ids from the last pieces are visible"
        );
        assert_same_buffers(&one, &streamed);
    }

    /// Passes that keep a fragment when its first varying reaches their cutoff; the output does
    /// not depend on the cutoff (as the tree shader's alpha test), so it is `shader(cut)`'s.
    struct Cutoffs<'a, F>(&'a [f32], F);

    impl<F: Fn(&Fragment<1>) -> FragmentOutput + Sync> PassShader<1> for Cutoffs<'_, F> {
        fn shade_passes(
            &self,
            f: &Fragment<1>,
            passes: PassSet,
        ) -> Option<(FragmentOutput, PassSet)> {
            let kept = (0..self.0.len())
                .filter(|&p| passes & (1 << p) != 0 && f.varyings[0] >= self.0[p])
                .fold(0, |set, p| set | (1 << p));
            (kept != 0).then(|| (self.1(f), kept))
        }
    }

    /// A masked draw writes exactly the unmasked draw's values inside the mask and nothing
    /// outside it; `draw_passes` gives each target what its own `draw` gives.
    #[test]
    fn masked_and_shared_draws_equal_plain_draws() {
        let (w, h) = (96, 80);
        let clear = ClearValues {
            color: [0.2, 0.3, 0.4, 1.0],
            depth: 1.0,
            aux: 0,
        };
        let mut next = unit_random(12345u64);
        let tris: Vec<Triangle<1>> = (0..300)
            .map(|i| {
                [0, 1, 2].map(|_| {
                    Vertex::new(
                        [next() * 2.2 - 1.1, next() * 2.2 - 1.1, next(), 1.0],
                        [i as f32 / 300.0],
                    )
                })
            })
            .collect();
        let shader = |cut: f32| {
            move |f: &Fragment<1>| {
                (f.varyings[0] >= cut).then_some(FragmentOutput {
                    color: [f.varyings[0], 0.5, 1.0 - f.varyings[0], 0.7],
                    id: f.primitive_id,
                    depth: None,
                })
            }
        };
        let state = DrawState::TRANSPARENT;
        let (s1, s2) = (shader(0.2), shader(0.6));
        let mut plain1 = RenderTarget::new(w, h, clear);
        let st1 = plain1.draw(&tris, &s1, &state);
        let mut plain2 = RenderTarget::new(w, h, clear);
        let st2 = plain2.draw(&tris, &s2, &state);
        let mask: Vec<bool> = (0..w * h).map(|i| (i * 7919) % 13 < 3).collect();
        let mut m1 = RenderTarget::new(w, h, clear).with_pixel_mask(mask.clone());
        let mut m2 = RenderTarget::new(w, h, clear).with_pixel_mask(mask.clone());
        let mut u1 = RenderTarget::new(w, h, clear);
        let mut u2 = RenderTarget::new(w, h, clear);
        let out = |f: &Fragment<1>| FragmentOutput {
            color: [f.varyings[0], 0.5, 1.0 - f.varyings[0], 0.7],
            id: f.primitive_id,
            depth: None,
        };
        let shared = draw_passes(
            &mut [&mut u1, &mut u2],
            &Cutoffs(&[0.2, 0.6], out),
            &tris,
            &state,
        );
        assert_eq!(shared, vec![st1, st2]);
        assert_eq!(
            (u1.color(), u1.depth(), u1.aux()),
            (plain1.color(), plain1.depth(), plain1.aux())
        );
        assert_eq!(
            (u2.color(), u2.depth(), u2.aux()),
            (plain2.color(), plain2.depth(), plain2.aux())
        );
        draw_passes(
            &mut [&mut m1, &mut m2],
            &Cutoffs(&[0.2, 0.6], out),
            &tris,
            &state,
        );
        let blank = RenderTarget::new(w, h, clear);
        for (masked, plain) in [(&m1, &plain1), (&m2, &plain2)] {
            let mut inside_written = 0;
            for (i, &inside) in mask.iter().enumerate() {
                let want = if inside { plain } else { &blank };
                assert_eq!(masked.color()[i], want.color()[i], "pixel {i}");
                assert_eq!(
                    masked.depth()[i].to_bits(),
                    want.depth()[i].to_bits(),
                    "pixel {i}"
                );
                assert_eq!(masked.aux()[i], want.aux()[i], "pixel {i}");
                inside_written += usize::from(inside && plain.aux()[i] != 0);
            }
            assert!(
                inside_written > 100,
                "the mask covers {inside_written} drawn pixels"
            );
        }
    }

    /// The summed-area table counts every rectangle of a small mask right (all of them).
    #[test]
    fn mask_counts_answer_every_rectangle() {
        let (w, h) = (13u32, 9u32);
        let mask: Vec<bool> = (0..w * h).map(|i| (i * 7919) % 29 < 2).collect();
        let counts = MaskCounts::new(&mask, w, h);
        for (y0, y1) in (0..h).flat_map(|a| (a + 1..=h).map(move |b| (a, b))) {
            for (x0, x1) in (0..w).flat_map(|a| (a + 1..=w).map(move |b| (a, b))) {
                let r = PixelRect { x0, y0, x1, y1 };
                let brute = (y0..y1).any(|y| (x0..x1).any(|x| mask[(y * w + x) as usize]));
                assert_eq!(counts.any(&r), brute, "{r:?}");
            }
        }
    }

    /// Small triangles and a sparse mask, so that most triangles meet no pixel of it (the masked
    /// bins leave them out): inside the mask every value is the plain draw's, two targets with
    /// the same mask share the lists, and the counters of complementary masks add up to the
    /// plain draw's (every fragment lies in exactly one of them).
    #[test]
    fn sparse_masks_keep_every_value_and_counter() {
        let (w, h) = (160, 96);
        let clear = ClearValues {
            color: [0.2, 0.3, 0.4, 1.0],
            depth: 1.0,
            aux: 0,
        };
        let mut next = unit_random(777u64);
        let tris: Vec<Triangle<1>> = (0..3000)
            .map(|i| {
                let (cx, cy) = (next() * 2.2 - 1.1, next() * 2.2 - 1.1);
                [0, 1, 2].map(|_| {
                    Vertex::new(
                        [cx + next() * 0.06, cy + next() * 0.06, next(), 1.0],
                        [i as f32 / 3000.0],
                    )
                })
            })
            .collect();
        let shader = |cut: f32| {
            move |f: &Fragment<1>| {
                (f.varyings[0] >= cut).then_some(FragmentOutput {
                    color: [f.varyings[0], 0.5, 1.0 - f.varyings[0], 0.7],
                    id: f.primitive_id + 1,
                    depth: None,
                })
            }
        };
        let state = DrawState {
            depth_write: true,
            ..DrawState::TRANSPARENT
        };
        let (s1, s2) = (shader(0.2), shader(0.6));
        let mut plain1 = RenderTarget::new(w, h, clear);
        let st1 = plain1.draw(&tris, &s1, &state);
        let mut plain2 = RenderTarget::new(w, h, clear);
        let st2 = plain2.draw(&tris, &s2, &state);
        let mask: Vec<bool> = (0..w * h).map(|i| (i * 7919) % 97 == 0).collect();
        let outside: Vec<bool> = mask.iter().map(|&m| !m).collect();
        let mut a1 = RenderTarget::new(w, h, clear).with_pixel_mask(mask.clone());
        let mut a2 = RenderTarget::new(w, h, clear).with_pixel_mask(mask.clone());
        let mut b1 = RenderTarget::new(w, h, clear).with_pixel_mask(outside);
        let out = |f: &Fragment<1>| FragmentOutput {
            color: [f.varyings[0], 0.5, 1.0 - f.varyings[0], 0.7],
            id: f.primitive_id + 1,
            depth: None,
        };
        let stats = draw_passes(
            &mut [&mut a1, &mut a2, &mut b1],
            &Cutoffs(&[0.2, 0.6, 0.2], out),
            &tris,
            &state,
        );
        let mut inside_written = 0;
        for (masked, plain) in [(&a1, &plain1), (&a2, &plain2)] {
            for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
                assert_eq!(masked.color()[i], plain.color()[i], "pixel {i}");
                assert_eq!(masked.depth()[i].to_bits(), plain.depth()[i].to_bits());
                assert_eq!(masked.aux()[i], plain.aux()[i], "pixel {i}");
                inside_written += usize::from(plain.aux()[i] != 0);
            }
        }
        assert!(
            inside_written > 20,
            "{inside_written} drawn pixels in the mask"
        );
        let sum = |a: &DrawStats, b: &DrawStats| {
            (
                a.fragments_covered + b.fragments_covered,
                a.fragments_shaded + b.fragments_shaded,
                a.fragments_written + b.fragments_written,
            )
        };
        let all = |s: &DrawStats| (s.fragments_covered, s.fragments_shaded, s.fragments_written);
        assert_eq!(sum(&stats[0], &stats[2]), all(&st1));
        assert!(stats[0].fragments_written > 0 && stats[1].fragments_written > 0);
        assert!(stats[1].fragments_covered == stats[0].fragments_covered);
        assert!(all(&stats[1]) <= all(&st2));
        for s in &stats {
            assert_eq!(
                (s.triangles_in, s.triangles_clipped, s.triangles_rasterized),
                (
                    st1.triangles_in,
                    st1.triangles_clipped,
                    st1.triangles_rasterized
                )
            );
        }
    }
}
