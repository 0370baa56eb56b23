//! RGBA8 texel comparison and the "one test body, several backends" adapters of the `mips` and
//! `bake` stages (SPEC §5.1, §5.2, §8), used by `tests/tests/parity/mips.rs` and
//! `tests/tests/parity/bake.rs`.
//!
//! - [`TexelTally`] counts texels compared, differing and beyond a tolerance, and keeps the largest
//!   per-channel difference and the first offender, so every parity test can report "how many,
//!   how far" (SPEC §8: "RGBA8 texels within ±1 per channel, with the count and maximum of
//!   differences reported").
//! - The [`Mips`] stage builds mip chains from level-0 layers: [`Reference`](crate::stage::Reference)
//!   ([`reference_mip_chains`]) or [`GpuMipsBackend`] (`mips.wgsl` on the same level 0, uploaded
//!   from the CPU), both returning [`LevelOut`]s in the reference's terms.
//! - The [`Bake`] stage renders level 0 of every layer: [`Reference`](crate::stage::Reference)
//!   ([`reference_bake_level0`])
//!   or [`GpuBakeBackend`] (`bake.wgsl`).
//!
//! The GPU pipelines are compiled once per test binary ([`gpu_bake`]) on the shared context of
//! [`crate::context::gpu_context`].

use std::sync::OnceLock;

use forestlod_gpu::bake::BakeMesh;
use forestlod_gpu::mips::{ADJUST_CONSTANT, ADJUST_KEEP, ADJUST_REMAP, ADJUST_SCALE};
use forestlod_gpu::{GpuBake, MipLevelStats};
use forestlod_reference::bake::{bake_depth_view, bake_view};
use forestlod_reference::mips::{AlphaAdjust, build_mip_array};
use forestlod_reference::sampler::Texture;
use forestlod_reference::scene::TreeMesh;
use forestlod_reference::texture::Rgba8Image;
use forestlod_shared::{BillboardViews, MipMode};
use rayon::prelude::*;

use crate::stage::{Backend, Bake, BakeInput, Mips, MipsInput, Named, Reference};
use crate::stats::SignedHistogram;

use crate::context::gpu_context;

/// Largest per-channel difference of two texels.
pub fn channel_diff(a: [u8; 4], b: [u8; 4]) -> u8 {
    (0..4).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0)
}

/// Largest bias of a texel comparison per distinct reference value (GPU minus reference, per
/// channel, in sRGB8 or UNORM8 units; [`TexelTally::bias_failures`], gated together with the
/// sign test of [`crate::stats`]).
///
/// Why 0.05: a correct GPU mips stage differs from the reference by a rare one-step rounding of
/// either sign (0 to 3 texels of ~600k per mode in `parity::mips`); the bake, rasterized by
/// lavapipe, differs by ±1 on 15 % of its texels, and *per element* leans one way (green +0.069,
/// blue -0.045 at r = 128: a few texture colours near an sRGB rounding boundary, repeated over
/// many texels), but per distinct value the signs balance except in one of 104 measured channel
/// comparisons (alpha of the r = 4 bake: +0.015). 0.05 keeps a factor 3 over that; a changed
/// rounding rule that moves one value in twenty by one step the same way reaches it, one that
/// moves every texel (what a ±1 tolerance cannot see) exceeds it twentyfold.
pub const TEXEL_BIAS_MAX: f64 = 0.05;

/// Largest bias per distinct reference value of the *mips* stage ([`TexelTally::bias_failures`]
/// in `parity::mips` and on the GPU bake's own level 0 in `parity::bake`).
///
/// Why 1e-3, fifty times stricter than [`TEXEL_BIAS_MAX`]: the GPU mips stage encodes through
/// tables of the reference's own formulas, so a correct build differs on 0 to 3 texels of ~600k
/// per mode, too few for the sign test to ever fire; a rounding rule changed in one channel
/// (measured with the deliberate bug `encode_byte(raw.y * 1.002, …)` in `mips.wgsl`: 0.4 % of
/// the texels +1, 168 of 232 green values up and none down) has a per-value bias of 0.0175, which
/// the bake's looser limit would let through and this one does not.
pub const MIPS_BIAS_MAX: f64 = 1e-3;

/// Running totals of a texel-by-texel comparison.
#[derive(Clone, Debug, Default)]
pub struct TexelTally {
    /// Texels compared.
    pub texels: u64,
    /// Texels with any channel different.
    pub differing: u64,
    /// Texels with a channel beyond the tolerance.
    pub over_tolerance: u64,
    /// Largest per-channel difference seen.
    pub max_diff: u8,
    /// The first texel beyond the tolerance: where, GPU value, reference value.
    pub first_over: Option<(String, [u8; 4], [u8; 4])>,
    /// Signed differences (GPU minus reference) per channel R, G, B, A, over every texel
    /// (statistical parity, [`crate::stats`]).
    pub channels: [SignedHistogram; 4],
}

impl TexelTally {
    /// Compares `got` with `want` texel by texel (equal lengths), allowing `tolerance` per
    /// channel; `what` names the image in the first offender's description.
    pub fn compare(&mut self, what: &str, got: &[[u8; 4]], want: &[[u8; 4]], tolerance: u8) {
        assert_eq!(got.len(), want.len(), "{what}: texel counts differ");
        for (i, (&g, &w)) in got.iter().zip(want).enumerate() {
            self.texel(|| format!("{what} texel {i}"), g, w, tolerance);
        }
    }

    /// Records one texel pair.
    pub fn texel(
        &mut self,
        what: impl FnOnce() -> String,
        got: [u8; 4],
        want: [u8; 4],
        tolerance: u8,
    ) {
        self.texels += 1;
        for (c, h) in self.channels.iter_mut().enumerate() {
            h.tolerance = i64::from(tolerance);
            h.record_at(i64::from(want[c]), i64::from(got[c]) - i64::from(want[c]));
        }
        let d = channel_diff(got, want);
        if d == 0 {
            return;
        }
        self.differing += 1;
        self.max_diff = self.max_diff.max(d);
        if d > tolerance {
            self.over_tolerance += 1;
            if self.first_over.is_none() {
                self.first_over = Some((what(), got, want));
            }
        }
    }

    /// Adds another tally's totals (its first offender only if this one has none).
    pub fn merge(&mut self, other: &TexelTally) {
        self.texels += other.texels;
        self.differing += other.differing;
        self.over_tolerance += other.over_tolerance;
        self.max_diff = self.max_diff.max(other.max_diff);
        if self.first_over.is_none() {
            self.first_over.clone_from(&other.first_over);
        }
        for (h, o) in self.channels.iter_mut().zip(&other.channels) {
            h.merge(o);
        }
    }

    /// Why the signed differences are biased (one line per channel), empty when they are not:
    /// [`SignedHistogram::value_bias_failure`] with `max_bias` (normally [`TEXEL_BIAS_MAX`]).
    pub fn bias_failures(&self, what: &str, max_bias: f64) -> Vec<String> {
        self.channels
            .iter()
            .zip(["R", "G", "B", "A"])
            .filter_map(|(h, c)| h.value_bias_failure(&format!("{what} channel {c}"), max_bias))
            .collect()
    }

    /// One line for the test log, then one per channel with its signed-difference statistics.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "{} texels compared, {} differing, {} beyond tolerance, max channel difference {}",
            self.texels, self.differing, self.over_tolerance, self.max_diff
        );
        for (h, c) in self.channels.iter().zip(["R", "G", "B", "A"]) {
            s.push_str(&format!("\n    {c}: {h}"));
        }
        s
    }
}

pub use crate::stage::LevelOut;

/// The CPU oracle's chains, `forestlod_reference::mips::build_mip_array`, as [`LevelOut`]s (the
/// [`Reference`](crate::stage::Reference) backend of [`Mips`]).
pub fn reference_mip_chains(
    layers: &[Rgba8Image],
    mode: MipMode,
    alpha_ref: f32,
) -> Vec<Vec<LevelOut>> {
    build_mip_array(layers, mode, alpha_ref)
        .expect("build_mip_array")
        .into_iter()
        .map(|chain| {
            chain
                .levels
                .into_iter()
                .map(|l| LevelOut {
                    image: l.rgba8,
                    raw_alpha_range: l.raw_alpha_range,
                    adjust: l.adjust,
                    pass_count: l.alpha_test_pass_count,
                })
                .collect()
        })
        .collect()
}

/// `mips.wgsl` on level 0 uploaded from the CPU (`GpuMips::run_from_cpu`): a [`Backend<Mips>`].
pub struct GpuMipsBackend {
    /// The compiled stages.
    pub bake: &'static GpuBake<'static>,
}

/// A GPU [`MipLevelStats`] adjustment as the reference's [`AlphaAdjust`].
pub fn adjust_of(stats: &MipLevelStats) -> AlphaAdjust {
    let p = stats.adjust;
    match stats.adjust_kind {
        ADJUST_KEEP => AlphaAdjust::Keep,
        ADJUST_REMAP => AlphaAdjust::Remap {
            from: [p[0], p[1]],
            to: [p[2], p[3]],
        },
        ADJUST_CONSTANT => AlphaAdjust::Constant(p[0]),
        ADJUST_SCALE => AlphaAdjust::Scale(p[0]),
        other => panic!("GPU wrote an unknown adjust kind {other}"),
    }
}

impl Named for GpuMipsBackend {
    fn name(&self) -> String {
        "gpu".into()
    }
}

impl Backend<Mips> for GpuMipsBackend {
    fn run(&self, i: MipsInput<'_>) -> Vec<Vec<LevelOut>> {
        let (layers, mode, alpha_ref) = (i.layers, i.mode, i.alpha_ref);
        let ctx = self.bake.mips().context();
        let side = layers[0].width;
        let texels: Vec<&[[u8; 4]]> = layers.iter().map(|l| l.texels.as_slice()).collect();
        let array = self
            .bake
            .mips()
            .run_from_cpu(side, &texels, mode, alpha_ref)
            .expect("GpuMips::run_from_cpu");
        let chains = array.read_chains(ctx).expect("read chains");
        let stats = array
            .read_stats(ctx)
            .expect("read stats")
            .expect("GPU-built arrays have stats");
        chains
            .into_iter()
            .zip(stats)
            .map(|(chain, stats)| {
                chain
                    .into_iter()
                    .zip(stats)
                    .map(|(level, s)| LevelOut {
                        image: Rgba8Image {
                            width: level.side,
                            height: level.side,
                            texels: level.texels,
                        },
                        raw_alpha_range: s.raw_alpha_range(),
                        adjust: adjust_of(&s),
                        pass_count: u64::from(s.pass_count),
                    })
                    .collect()
            })
            .collect()
    }
}

/// The CPU oracle's level 0 of every layer, `forestlod_reference::bake::bake_layer` per layer
/// (the [`Reference`](crate::stage::Reference) backend of [`Bake`]; level 0 of the mesh texture is all the bake samples).
pub fn reference_bake_level0(
    meshes: &[TreeMesh],
    views: BillboardViews,
    side: u32,
) -> Vec<Rgba8Image> {
    reference_bake_layers(meshes, views, side, false)
}

/// [`reference_bake_level0`]'s layers, or the depth channel's (issue 32, `bake_depth_view`).
fn reference_bake_layers(
    meshes: &[TreeMesh],
    views: BillboardViews,
    side: u32,
    depth: bool,
) -> Vec<Rgba8Image> {
    let textures: Vec<Texture> = meshes
        .iter()
        .map(|m| Texture::new(vec![m.texture.clone()]).expect("mesh texture"))
        .collect();
    let jobs: Vec<(usize, u32, u32)> = views.views(meshes.len()).collect();
    jobs.par_iter()
        .map(|&(m, k, j)| {
            let (mesh, meta) = (&meshes[m], meshes[m].meta());
            if depth {
                bake_depth_view(mesh, &meta, &textures[m], views, k, side)
            } else {
                bake_view(mesh, &meta, &textures[m], views, k, j, side)
            }
        })
        .collect()
}

/// The views a bake input asks for.
fn bake_views(i: &BakeInput<'_>) -> BillboardViews {
    BillboardViews {
        angle_count: i.angle_count,
        azimuth_count: i.azimuth_count,
        sphere: i.sphere,
        grid: i.grid,
    }
}

/// `bake.wgsl`, level 0 read back before the mips stage: a [`Backend<Bake>`].
pub struct GpuBakeBackend {
    /// The compiled stages.
    pub bake: &'static GpuBake<'static>,
}

/// A reference mesh as the GPU bake takes it.
pub fn bake_mesh(mesh: &TreeMesh) -> BakeMesh<'_> {
    BakeMesh {
        positions: &mesh.positions,
        uvs: &mesh.uvs,
        indices: &mesh.indices,
        texture_width: mesh.texture.width,
        texture_height: mesh.texture.height,
        texture: &mesh.texture.texels,
        meta: mesh.meta(),
    }
}

impl Named for GpuBakeBackend {
    fn name(&self) -> String {
        "gpu".into()
    }
}

impl Backend<Bake> for GpuBakeBackend {
    fn run(&self, i: BakeInput<'_>) -> Vec<Rgba8Image> {
        let (meshes, views, side) = (i.meshes, bake_views(&i), i.side);
        let ctx = self.bake.mips().context();
        let inputs: Vec<BakeMesh<'_>> = meshes.iter().map(bake_mesh).collect();
        let read = |texture: wgpu::Texture| {
            let array = forestlod_gpu::MipArray::from_texture(ctx, texture, MipMode::Box, 0.5)
                .expect("wrap the baked texture");
            array
                .read_level0(ctx)
                .expect("read level 0")
                .into_iter()
                .map(|l| Rgba8Image {
                    width: l.side,
                    height: l.side,
                    texels: l.texels,
                })
                .collect::<Vec<_>>()
        };
        let mut layers = read(
            self.bake
                .bake_level0(&inputs, views, side)
                .expect("GpuBake::bake_level0"),
        );
        if i.depth {
            layers.extend(read(
                self.bake
                    .bake_depth_level0(&inputs, views, side)
                    .expect("GpuBake::bake_depth_level0"),
            ));
        }
        layers
    }
}

/// The bake and mips stages compiled once for this test binary on the shared context; `None`
/// without an adapter when `FORESTLOD_ALLOW_NO_GPU=1`.
pub fn gpu_bake() -> Option<&'static GpuBake<'static>> {
    static BAKE: OnceLock<Option<GpuBake<'static>>> = OnceLock::new();
    BAKE.get_or_init(|| gpu_context().map(|ctx| GpuBake::new(ctx).expect("compile bake and mips")))
        .as_ref()
}

impl Backend<Mips> for Reference {
    fn run(&self, i: MipsInput<'_>) -> Vec<Vec<LevelOut>> {
        reference_mip_chains(i.layers, i.mode, i.alpha_ref)
    }
}

impl Backend<Bake> for Reference {
    fn run(&self, i: BakeInput<'_>) -> Vec<Rgba8Image> {
        let mut layers = reference_bake_level0(i.meshes, bake_views(&i), i.side);
        if i.depth {
            layers.extend(reference_bake_layers(
                i.meshes,
                bake_views(&i),
                i.side,
                true,
            ));
        }
        layers
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tally of `values` distinct reference values in red (`texels_per_value` texels each, every
    /// other channel equal), where the first `shifted` values have one texel one step up: a
    /// per-value bias of exactly `shifted / (texels_per_value · values)`.
    fn red_shift(values: u8, texels_per_value: u32, shifted: u8) -> TexelTally {
        let mut tally = TexelTally::default();
        for v in 0..values {
            for k in 0..texels_per_value {
                let want = [v, 7, 7, 255];
                let got = [v + u8::from(v < shifted && k == 0), 7, 7, 255];
                tally.texel(|| format!("value {v} texel {k}"), got, want, 1);
            }
        }
        tally
    }

    /// Sensitivity of the texel bias gates (issue 36, class 2), each at its limit and one value
    /// past: [`TEXEL_BIAS_MAX`] (200 values, 1 of 4 texels up on 40 of them: exactly 0.05; 41
    /// fail) and [`MIPS_BIAS_MAX`] (250 values, 1 of 128 texels up on 32 of them: exactly 1e-3;
    /// 33 fail). Both have at least 26 values up, so the sign test fires and the mean decides.
    #[test]
    fn gate_texel_and_mips_bias_at_limit_pass_one_past_fail() {
        for (what, limit, values, per, at) in [
            ("texel", TEXEL_BIAS_MAX, 200, 4, 40),
            ("mips", MIPS_BIAS_MAX, 250, 128, 32),
        ] {
            let tally = red_shift(values, per, at);
            assert_eq!(tally.channels[0].value_bias(), (limit, u64::from(at), 0));
            assert_eq!(tally.over_tolerance, 0);
            assert!(
                tally.bias_failures(what, limit).is_empty(),
                "{what} at {limit}: {}",
                tally.summary()
            );
            let past = red_shift(values, per, at + 1);
            let failures = past.bias_failures(what, limit);
            assert!(
                failures.len() == 1 && failures[0].starts_with(&format!("{what} channel R: ")),
                "{what} one value past {limit}: {failures:?}"
            );
        }
    }

    /// The per-texel tolerance: a channel `tolerance` away is differing but within it, one more
    /// is over it and is the first offender.
    #[test]
    fn gate_texel_tolerance_at_tolerance_passes_one_more_fails() {
        let mut tally = TexelTally::default();
        tally.compare("a", &[[11, 0, 0, 0]], &[[10, 0, 0, 0]], 1);
        assert_eq!((tally.differing, tally.over_tolerance), (1, 0));
        tally.compare("b", &[[12, 0, 0, 0]], &[[10, 0, 0, 0]], 1);
        assert_eq!(
            (tally.differing, tally.over_tolerance, tally.max_diff),
            (2, 1, 2)
        );
        assert_eq!(
            tally.first_over,
            Some(("b texel 0".to_string(), [12, 0, 0, 0], [10, 0, 0, 0]))
        );
    }

    #[test]
    fn every_texel_one_step_up_is_within_tolerance_but_biased() {
        let want: Vec<[u8; 4]> = (0..4096u32)
            .map(|i| {
                [
                    (i % 250) as u8,
                    (i / 17) as u8,
                    (i * 3 % 250) as u8,
                    (i % 240) as u8,
                ]
            })
            .collect();
        let got: Vec<[u8; 4]> = want.iter().map(|t| t.map(|c| c + 1)).collect();
        let mut tally = TexelTally::default();
        tally.compare("shifted", &got, &want, 1);
        assert_eq!(tally.over_tolerance, 0);
        let failures = tally.bias_failures("shifted", TEXEL_BIAS_MAX);
        assert_eq!(failures.len(), 4, "{failures:?}");
        // Symmetric ±1 noise is not.
        let noisy: Vec<[u8; 4]> = want
            .iter()
            .enumerate()
            .map(|(i, t)| {
                t.map(|c| {
                    if i % 2 == 0 {
                        c + 1
                    } else {
                        c.saturating_sub(1)
                    }
                })
            })
            .collect();
        let mut tally = TexelTally::default();
        tally.compare("noise", &noisy, &want, 1);
        assert!(
            tally.bias_failures("noise", TEXEL_BIAS_MAX).is_empty(),
            "{}",
            tally.summary()
        );
    }
}
