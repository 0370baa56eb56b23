//! The rasterizer's interface types (the contract is the [module docs](super)): what the vertex
//! stage hands a draw ([`Vertex`], [`Triangle`]), a draw's fixed-function state ([`DrawState`]:
//! depth test and write, [`Blend`], [`CullMode`], [`FrontFace`]), what the fragment stage sees and
//! returns ([`Fragment`], [`FragmentOutput`]) through its two interfaces ([`FragmentShader`] for a
//! draw into one target, [`PassShader`] for the passes of [`draw_passes`](super::draw_passes)),
//! the work counters ([`DrawStats`]), and the half-open pixel rectangle the other files share.
//!
//! Contracts stated here and relied on by the rest of the rasterizer:
//! - a shader is called in submission order per pixel but in no particular order across pixels
//!   (tiles run in parallel), so it must not depend on call order;
//! - a shader-written depth ([`FragmentOutput::depth`]) is never below the interpolated one
//!   (SPIR-V `DepthGreater`), which keeps the early depth test valid;
//! - a [`PassShader`]'s passes differ only in which fragments they keep: a kept fragment has
//!   the same output in every pass that keeps it.
//!
//! The lowest file of the rasterizer: it imports nothing from the others.

use std::ops::{Add, AddAssign};

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

/// A half-open pixel rectangle `[x0, x1) x [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct PixelRect {
    pub(super) x0: u32,
    pub(super) y0: u32,
    pub(super) x1: u32,
    pub(super) y1: u32,
}

impl PixelRect {
    pub(super) fn width(&self) -> u32 {
        self.x1 - self.x0
    }
    pub(super) fn height(&self) -> u32 {
        self.y1 - self.y0
    }
    pub(super) fn contains(&self, x: u32, y: u32) -> bool {
        (self.x0..self.x1).contains(&x) && (self.y0..self.y1).contains(&y)
    }
    pub(super) fn intersect(&self, o: &PixelRect) -> Option<PixelRect> {
        let r = PixelRect {
            x0: self.x0.max(o.x0),
            y0: self.y0.max(o.y0),
            x1: self.x1.min(o.x1),
            y1: self.y1.min(o.y1),
        };
        (r.x0 < r.x1 && r.y0 < r.y1).then_some(r)
    }
}

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
