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

mod color;
mod passes;
mod setup;
mod target;
#[cfg(test)]
mod test_util;
mod tiles;
mod types;

pub use passes::{SETUP_CHUNK, TriangleSource, draw_passes, draw_passes_streamed};
pub(crate) use setup::round_exact;
pub use setup::{GUARD_BAND_PX, SUBPIXEL_BITS};
pub(crate) use target::MaskCounts;
pub use target::{
    ClearValues, MASKED_TILE_SIZE, MAX_TARGET_SIZE, RenderTarget, TILE_SIZE, release_spare_buffers,
};
pub use types::{
    Blend, CullMode, DrawState, DrawStats, Fragment, FragmentOutput, FragmentShader, FrontFace,
    MAX_PASSES, PassSet, PassShader, Triangle, Vertex,
};
