//! The fade of one fragment of a fading command (issue 30; G§4; SPEC §6): the draw stage's
//! fragment rule ([`BlendRule::fade`], called by `draw::TreeShader`), and a probe that reports
//! that rule's decision for every fragment of every tree of a frame ([`probe_fragments`]), for
//! the properties that only hold per tree (`tests/tests/reference/blend.rs`).
//!
//! ## Contract
//! - **Progress** `t` ([`forestlod_shared::FadeGranularity`]): under `fragment`, the
//!   [`forestlod_shared::fade_progress`] of the fragment's view depth in its tree's band (as
//!   before issue 30); under `tree`, the progress of the tree's bounding-sphere centre, which the
//!   vertex stage computes once per tree and passes in the varying that otherwise carries the
//!   tree's scale (`draw::TREE_VARYINGS`): G§4's blend factor "per entity", so every fragment of
//!   both LODs of one tree reads the same `t`, bit for bit.
//! - **Threshold** `h` ([`forestlod_shared::DitherSpace`]): under `screen`, the frame pixel's
//!   [`forestlod_shared::dither_threshold`]; under `texture`, the noise texel of
//!   `shared/src/noise.rs` at the fragment's `uv` in its own LOD's texture space, at the level
//!   its `uv` derivatives choose (the rasterizer's coarse derivatives, `raster` §7).
//! - **Weight**: [`forestlod_shared::weights_at`] of the fade mode at `t` (the hard switch of
//!   `none` at the depth's band end, or at `t >= 1` for a tree), then the command's LOD.
//! - **LOD id**: a fading fragment is a transition fragment when `0 < t < 1`.
//!
//! Under the defaults (`screen`, `fragment`) every value is computed by the expressions the draw
//! stage used before, in the same order, so frames are bit-identical (the goldens).
//!
//! Twin: `gpu/src/shaders/draw.wgsl` (`tree_fragment`; the formulas in `common.wgsl`).

use forestlod_shared::coverage;
use forestlod_shared::{
    Camera, CommandData, DitherSpace, FadeGranularity, FadeMode, Params, dither_threshold,
    fade_progress, noise_index, noise_level_scaled, noise_texel, weights_at,
};

use crate::draw::{DrawResources, TREE_VARYINGS, TreeShader, vertex_stage};
use crate::raster::{
    ClearValues, DrawState, Fragment, FragmentOutput, RenderTarget, Triangle, round_exact,
};
use crate::select::{SelectUniform, Selection};

/// The fade rule of a frame's fragments (module docs): the parameters it reads.
#[derive(Clone, Copy, Debug)]
pub struct BlendRule {
    /// The fade mode.
    pub fade: FadeMode,
    /// Where the threshold comes from.
    pub space: DitherSpace,
    /// What the progress is taken from.
    pub granularity: FadeGranularity,
    /// The noise texture's side, `Params::noise_size`.
    pub noise_size: u32,
    /// What the noise level's `ρ²` is multiplied by: 1 in every frame drawn to be seen; the
    /// parity test's alternative frames move it ([`forestlod_shared::noise_level_scaled`]).
    pub rho2_scale: f32,
}

/// What [`BlendRule::fade`] decided for one fragment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FadeDecision {
    /// The fragment's weight in its command's LOD (0 discards; dithered modes give 0 or 1).
    pub weight: f32,
    /// The progress through the band it was decided at.
    pub t: f32,
    /// The threshold it was compared with.
    pub threshold: f32,
    /// The texture-space noise texel under the fragment, `[level, i, j]`, whichever space
    /// decided (the key of the per-tree properties).
    pub texel: [u32; 3],
}

impl FadeDecision {
    /// Whether the fragment lies strictly inside the band (the transition LOD id).
    pub fn in_band(&self) -> bool {
        self.t > 0.0 && self.t < 1.0
    }
}

impl BlendRule {
    /// The rule of validated parameters, `ρ²` unscaled.
    pub fn new(params: &Params) -> Self {
        Self {
            fade: params
                .fade()
                .expect("parameters are validated before drawing"),
            space: params
                .dither()
                .expect("parameters are validated before drawing"),
            granularity: params
                .granularity()
                .expect("parameters are validated before drawing"),
            noise_size: params.noise_size,
            rho2_scale: 1.0,
        }
    }

    /// The fade of fragment `f` of a fading command `data` at frame pixel `(px, py)` (module
    /// docs); `view` scales the command's band by the tree's scale under a scaled LOD metric.
    pub fn fade(
        &self,
        view: &SelectUniform,
        data: &CommandData,
        f: &Fragment<TREE_VARYINGS>,
        px: u32,
        py: u32,
    ) -> FadeDecision {
        let [u, v, depth, _, _, word, ..] = f.varyings;
        let (t, past_end) = match self.granularity {
            FadeGranularity::Fragment => {
                // The tree's own band (C§4.6: its transition depths follow its scale): the
                // command's band at unit scale times the tree's scale (`word`) under a scaled
                // metric, the command's band under `distance`. The same product as the
                // per-tree selection's (`tree_band`).
                let [fade_start, fade_end] =
                    view.group_band([data.fade_start, data.fade_end], [word, word]);
                if coverage::enabled() {
                    use coverage::{Threshold::*, hit};
                    hit(DrawFadeStart, depth >= fade_start);
                    hit(DrawFadeEnd, depth >= fade_end);
                }
                (
                    fade_progress(depth, fade_start, fade_end),
                    depth >= fade_end,
                )
            }
            FadeGranularity::Tree => {
                coverage::hit(
                    coverage::Threshold::DrawTreeProgress,
                    word > 0.0 && word < 1.0,
                );
                (word, word >= 1.0)
            }
        };
        let ddx = [f.ddx[0], f.ddx[1]];
        let ddy = [f.ddy[0], f.ddy[1]];
        let level = noise_level_scaled(ddx, ddy, self.noise_size, self.rho2_scale);
        let [i, j] = noise_index([u, v], level, self.noise_size);
        let threshold = match self.space {
            DitherSpace::Screen => dither_threshold(px, py),
            DitherSpace::Texture => {
                if matches!(self.fade, FadeMode::Dither | FadeMode::DitherSequential) {
                    coverage::hit(coverage::Threshold::DrawNoiseLevel, level > 0);
                }
                noise_texel(level, i, j)
            }
        };
        FadeDecision {
            weight: weights_at(self.fade, t, past_end, threshold).of(data.lod),
            t,
            threshold,
            texel: [level, i, j],
        }
    }
}

/// One fragment of one tree as [`probe_fragments`] saw it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbedFragment {
    /// The tree (index into the scene's instances).
    pub tree: u32,
    /// The command that drew it.
    pub command: u32,
    /// The command's LOD.
    pub lod: u32,
    /// Frame pixel.
    pub pixel: [u32; 2],
    /// Whether the alpha test keeps the fragment.
    pub alpha_kept: bool,
    /// The fade's decision; `None` for a command that does not fade (weight 1).
    pub fade: Option<FadeDecision>,
}

impl ProbedFragment {
    /// Whether the draw keeps the fragment (before the depth test): alpha test passed and a
    /// positive fade weight (the far-field subset's screen door, issue 29, is not applied).
    pub fn kept(&self) -> bool {
        self.alpha_kept && self.fade.is_none_or(|d| d.weight > 0.0)
    }
}

/// Every fragment of every tree of `selection` (its commands, in order) with the fragment
/// stage's alpha test and fade decision, no depth test and no far-field subset screen door
/// (module docs). Each tree is rasterized alone, with the draw stage's own vertex stage and
/// fragment rules (`vertex_stage`, `TreeShader`): a test tool for small frames (the cost is one
/// pass over the frame's pixels per tree).
pub fn probe_fragments(
    res: &DrawResources,
    selection: &Selection,
    camera: &Camera,
    params: &Params,
) -> Vec<ProbedFragment> {
    let uniform = crate::draw::DrawUniform::new(camera, params);
    let cutoffs = [params.alpha_cutoff];
    let shader = TreeShader::new(res, selection, camera, params, &cutoffs, 1.0);
    let state = DrawState {
        depth_test: false,
        depth_write: false,
        ..DrawState::OPAQUE
    };
    let origin = camera.pixel_origin();
    let mut target = RenderTarget::new(camera.width, camera.height, ClearValues::default());
    let mut out = Vec::new();
    for (c, cmd) in selection.commands.iter().enumerate() {
        let data = &selection.data[c];
        let indices = &res.geometry.indices
            [cmd.first_index as usize..(cmd.first_index + cmd.index_count) as usize];
        for instance in cmd.first_instance..cmd.first_instance + cmd.instance_count {
            let tree = res.indirection[instance as usize];
            let vertex = |index: u32| {
                vertex_stage(
                    res,
                    selection,
                    &uniform,
                    (index as i32 + cmd.base_vertex) as u32,
                    instance,
                )
            };
            let Some(triangles) = indices
                .chunks_exact(3)
                .map(|t| Some([vertex(t[0])?, vertex(t[1])?, vertex(t[2])?]))
                .collect::<Option<Vec<Triangle<TREE_VARYINGS>>>>()
            else {
                continue;
            };
            let seen = std::sync::Mutex::new(Vec::new());
            let record = |f: &Fragment<TREE_VARYINGS>| -> Option<FragmentOutput> {
                let command = round_exact(f.varyings[4]) as u32;
                let (px, py) = (f.x + origin[0], f.y + origin[1]);
                let alpha_kept = shader.texel(f)[3] >= params.alpha_cutoff;
                let fade = (data.fading != 0).then(|| {
                    shader.blend().fade(
                        &shader.view(),
                        &selection.data[command as usize],
                        f,
                        px,
                        py,
                    )
                });
                seen.lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .push(ProbedFragment {
                        tree,
                        command,
                        lod: data.lod,
                        pixel: [px, py],
                        alpha_kept,
                        fade,
                    });
                None
            };
            target.draw(&triangles, &record, &state);
            let mut seen = seen.into_inner().unwrap_or_else(|e| e.into_inner());
            seen.sort_by_key(|p| (p.pixel[1], p.pixel[0]));
            out.extend(seen);
        }
    }
    out
}
