//! LOD fade weights inside the transition band (E§4.3, §4.4; G§4; SPEC §6).
//!
//! The band is `[fade_start, fade_end] = [lod1_transition - fade_width, lod1_transition]` in view
//! depth `d`. Before it a tree is LOD0 only, past it LOD1 only, and inside it the progress
//! `t = (d - fade_start) / fade_width` drives the mode's weights. With `fade_width = 0` the band is
//! a single depth and `t` is a step: LOD1 from `d >= lod1_transition` on.
//!
//! Invariants (property-tested):
//! - `alpha`: `w0 + w1 = 1` within one ulp, both in `[0, 1]`, `w1` non-decreasing in `d`.
//! - `dither`: each pixel (threshold `h`) is in exactly one LOD: the two sets partition the pixels.
//! - `dither-sequential` (G§4): every pixel is in at least one LOD; the incoming LOD1 reaches full
//!   coverage at mid-band before the outgoing LOD0 starts to thin out; order-independent because
//!   both are alpha-tested, never blended.
//! - `none`: a hard switch; exactly one LOD.
//!
//! ## Where the threshold and the progress come from (G§4, issue 30)
//! Two further modes make the dithered fades Guerrero's (G§4) and leave today's frames as they
//! were at their first choices:
//! - [`DitherSpace`]: the threshold `h` of a fragment is its frame pixel's
//!   [`crate::dither_threshold`] (screen space: the pattern stays put while trees slide under
//!   it), or the noise texture of `shared/src/noise.rs` at the fragment's `uv` in its own LOD's
//!   texture space (attached to the tree; each LOD samples its own texture space, so the two
//!   LODs' thresholds at one pixel are unrelated).
//! - [`FadeGranularity`]: the progress `t` is the fragment's (from its view depth), or the
//!   tree's, from its bounding-sphere centre's view depth, computed once per tree in the vertex
//!   stage ([`tree_lod_weights`]): G§4's "blend factor" per entity, so a tree dissolves
//!   uniformly and both of its LODs share one `t` exactly.
//!
//! Under `dither-sequential` every pixel that both LODs of a tree cover keeps one of them when
//! both share `t` (one of the two covers is 1), whatever the two thresholds: the schedule, not a
//! shared noise, is what closes the holes (`dither_sequential_covers_every_pixel`). The parallel
//! `dither` partitions pixels only when both LODs read the same `h` (screen space).
//!
//! Keep in sync with `gpu/src/shaders/common.wgsl` (`fade_progress`, `lod_weights`,
//! `weights_at`).

crate::modes::modes! {
    /// Fade modes (SPEC §6).
    pub enum FadeMode {
        /// Hard switch at the transition distance.
        None = 0 => "none",
        /// Alpha cross-fade, E§4.4.
        Alpha = 1 => "alpha" ("E§4.4"),
        /// Noise-dithered complementary pixel sets.
        Dither = 2 => "dither",
        /// Noise-dithered sequential blend, G§4: first the incoming LOD in, then the outgoing out.
        DitherSequential = 3 => "dither-sequential" ("G§4"),
    }
}

crate::modes::modes! {
    /// Where a dithered fade's per-fragment threshold comes from (module docs; issue 30).
    pub enum DitherSpace {
        /// The frame pixel's hash, [`crate::dither_threshold`] (the fade modes as before).
        Screen = 0 => "screen",
        /// The texture-space noise of `shared/src/noise.rs` at the fragment's LOD `uv`.
        Texture = 1 => "texture" ("G§4"),
    }
}

crate::modes::modes! {
    /// What a fade's progress `t` through the band is taken from (module docs; issue 30).
    pub enum FadeGranularity {
        /// The fragment's own view depth (the fade modes as before).
        Fragment = 0 => "fragment",
        /// The tree's bounding-sphere centre's view depth, once per tree.
        Tree = 1 => "tree" ("G§4"),
    }
}

/// Weight (alpha multiplier) of each LOD for one fragment. Dithered modes give 0 or 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodWeights {
    /// Weight of LOD0 (meshes).
    pub lod0: f32,
    /// Weight of LOD1 (billboards).
    pub lod1: f32,
}

impl LodWeights {
    /// Weight of `lod` (0 or 1).
    pub fn of(self, lod: u32) -> f32 {
        if lod == 0 { self.lod0 } else { self.lod1 }
    }
}

/// Progress through the band: 0 before it, 1 past it, linear inside; a step at `fade_end` when the
/// band is empty. NaN `d` gives 0.
pub fn fade_progress(d: f32, fade_start: f32, fade_end: f32) -> f32 {
    let width = fade_end - fade_start;
    if width > 0.0 {
        ((d - fade_start) / width).max(0.0).min(1.0)
    } else if d >= fade_end {
        1.0
    } else {
        0.0
    }
}

/// LOD weights of a fragment at view depth `d`; `dither` is the fragment's threshold in `[0, 1)`
/// (a per-pixel noise value, ignored by `none` and `alpha`).
pub fn lod_weights(
    mode: FadeMode,
    d: f32,
    fade_start: f32,
    fade_end: f32,
    dither: f32,
) -> LodWeights {
    let t = fade_progress(d, fade_start, fade_end);
    weights_at(mode, t, d >= fade_end, dither)
}

/// LOD weights of every fragment of a tree whose own progress ([`FadeGranularity::Tree`]) is
/// `t` (the [`fade_progress`] of its centre's view depth): [`weights_at`] with the hard switch
/// of `none` at `t >= 1`.
pub fn tree_lod_weights(mode: FadeMode, t: f32, dither: f32) -> LodWeights {
    weights_at(mode, t, t >= 1.0, dither)
}

/// The fade modes' schedules at progress `t` ([`fade_progress`]): `past_end` is where `none`
/// switches (the fragment's depth at or past the band's end, or a tree's `t >= 1`), `dither`
/// the threshold in `[0, 1)` of the dithered modes.
pub fn weights_at(mode: FadeMode, t: f32, past_end: bool, dither: f32) -> LodWeights {
    let step = |covered: bool| if covered { 1.0 } else { 0.0 };
    match mode {
        FadeMode::None => {
            let one = step(past_end);
            LodWeights {
                lod0: 1.0 - one,
                lod1: one,
            }
        }
        FadeMode::Alpha => LodWeights {
            lod0: 1.0 - t,
            lod1: t,
        },
        FadeMode::Dither => {
            let in1 = dither < t;
            LodWeights {
                lod0: step(!in1),
                lod1: step(in1),
            }
        }
        FadeMode::DitherSequential => {
            let cover1 = (2.0 * t).min(1.0);
            let cover0 = (2.0 - 2.0 * t).min(1.0);
            LodWeights {
                lod0: step(dither < cover0),
                lod1: step(dither < cover1),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    use crate::test_support::proptest_config;

    proptest! {
        #![proptest_config(proptest_config())]

        #[test]
        fn alpha_weights_sum_to_one(d in -1e4f32..1e4, start in -1e3f32..2e3, width in 0.0f32..1e3) {
            let end = start + width;
            let w = lod_weights(FadeMode::Alpha, d, start, end, 0.0);
            prop_assert!((0.0..=1.0).contains(&w.lod0) && (0.0..=1.0).contains(&w.lod1));
            let sum = w.lod0 + w.lod1;
            prop_assert!((sum - 1.0).abs() <= f32::EPSILON, "sum {sum} at d={d}");
        }

        #[test]
        fn alpha_lod1_weight_is_monotone(a in -1e4f32..1e4, b in -1e4f32..1e4, start in -1e3f32..2e3, width in 0.0f32..1e3) {
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            let end = start + width;
            prop_assert!(lod_weights(FadeMode::Alpha, lo, start, end, 0.0).lod1 <= lod_weights(FadeMode::Alpha, hi, start, end, 0.0).lod1);
        }

        #[test]
        fn dither_partitions_pixels(d in -1e4f32..1e4, start in -1e3f32..2e3, width in 0.0f32..1e3, h in 0.0f32..1.0) {
            let w = lod_weights(FadeMode::Dither, d, start, start + width, h);
            prop_assert_eq!(w.lod0 + w.lod1, 1.0);
        }

        /// Every pixel keeps one LOD, in every [`DitherSpace`] x [`FadeGranularity`]: the two
        /// LODs' fragments at a pixel read one threshold in screen space and two unrelated ones
        /// in texture space (each LOD's own `uv`), and share `t` (the tree's, or the depth's for
        /// fragments at one depth).
        #[test]
        fn dither_sequential_covers_every_pixel(
            d in -1e4f32..1e4, start in -1e3f32..2e3, width in 0.0f32..1e3,
            h in 0.0f32..1.0, h_other in 0.0f32..1.0,
        ) {
            let end = start + width;
            for space in DitherSpace::ALL {
                let (h0, h1) = match space {
                    DitherSpace::Screen => (h, h),
                    DitherSpace::Texture => (h, h_other),
                };
                for granularity in FadeGranularity::ALL {
                    let (w0, w1) = match granularity {
                        FadeGranularity::Fragment => (
                            lod_weights(FadeMode::DitherSequential, d, start, end, h0).lod0,
                            lod_weights(FadeMode::DitherSequential, d, start, end, h1).lod1,
                        ),
                        FadeGranularity::Tree => {
                            let t = fade_progress(d, start, end);
                            (
                                tree_lod_weights(FadeMode::DitherSequential, t, h0).lod0,
                                tree_lod_weights(FadeMode::DitherSequential, t, h1).lod1,
                            )
                        }
                    };
                    prop_assert!(
                        w0 + w1 >= 1.0,
                        "{} {}: pixel h=({}, {}) at d={} lost both LODs",
                        space.name(), granularity.name(), h0, h1, d
                    );
                }
            }
        }

        /// The tree schedule is the fragment schedule at the tree's `t` (every mode but `none`,
        /// whose switch moves from `d >= end` to `t >= 1`, the same wherever the band is not
        /// empty and `d - start` rounds as `end - start` does).
        #[test]
        fn the_tree_schedule_is_the_fragment_schedule_at_its_t(
            d in -1e4f32..1e4, start in -1e3f32..2e3, width in 0.0f32..1e3, h in 0.0f32..1.0,
        ) {
            let end = start + width;
            let t = fade_progress(d, start, end);
            for mode in [FadeMode::Alpha, FadeMode::Dither, FadeMode::DitherSequential] {
                prop_assert_eq!(tree_lod_weights(mode, t, h), lod_weights(mode, d, start, end, h));
            }
        }

        #[test]
        fn dithered_coverage_matches_progress(start in -1e3f32..2e3, width in 1.0f32..1e3, s in 0.0f32..=1.0) {
            // Over a uniform grid of thresholds, the fraction of pixels in LOD1 is t (within 1/N).
            const N: usize = 1024;
            let end = start + width;
            let d = start + s * width;
            let t = fade_progress(d, start, end);
            let covered = (0..N).filter(|i| lod_weights(FadeMode::Dither, d, start, end, (*i as f32 + 0.5) / N as f32).lod1 == 1.0).count();
            prop_assert!((covered as f32 / N as f32 - t).abs() <= 1.0 / N as f32 + 1e-6);
        }

        #[test]
        fn none_is_exactly_one_lod(d in -1e4f32..1e4, start in -1e3f32..2e3, width in 0.0f32..1e3) {
            let w = lod_weights(FadeMode::None, d, start, start + width, 0.3);
            prop_assert_eq!(w.lod0 + w.lod1, 1.0);
            prop_assert_eq!(w.lod1 == 1.0, d >= start + width);
        }
    }

    #[test]
    fn zero_width_band_is_a_step_at_the_transition() {
        assert_eq!(fade_progress(999.9, 1000.0, 1000.0), 0.0);
        assert_eq!(fade_progress(1000.0, 1000.0, 1000.0), 1.0);
        assert_eq!(fade_progress(f32::NAN, 0.0, 10.0), 0.0);
        let w = lod_weights(FadeMode::Alpha, 1000.0, 1000.0, 1000.0, 0.0);
        assert_eq!((w.lod0, w.lod1), (0.0, 1.0));
    }

    /// What the sequential schedule is for (G§4 Fig. 5, "not blended in parallel"): with the
    /// two LODs' thresholds unrelated (texture space), parallel complementary covers
    /// (`cover1 = t`, `cover0 = 1 - t`) lose about `t (1 - t)` of the pixels, a quarter at
    /// mid-band; the sequential ones lose none.
    #[test]
    fn parallel_covers_with_unrelated_noise_lose_pixels() {
        let n = 256u32;
        let (mut lost_parallel, mut lost_sequential) = (0u32, 0u32);
        for k in 0..n * n {
            let (h0, h1) = (
                crate::noise_texel(0, k % n, k / n),
                crate::noise_texel(1, k % n, k / n),
            );
            let t = 0.5;
            lost_parallel += u32::from(h0 >= 1.0 - t && h1 >= t);
            let w = |h0, h1| {
                tree_lod_weights(FadeMode::DitherSequential, t, h0).lod0
                    + tree_lod_weights(FadeMode::DitherSequential, t, h1).lod1
            };
            lost_sequential += u32::from(w(h0, h1) < 1.0);
        }
        let frac = lost_parallel as f32 / (n * n) as f32;
        assert!((frac - 0.25).abs() < 0.01, "parallel lost {frac}");
        assert_eq!(lost_sequential, 0);
    }

    #[test]
    fn sequential_fades_incoming_in_before_outgoing_out() {
        // First half: LOD0 untouched, LOD1 coverage grows; second half: the reverse.
        let at = |t: f32, h: f32| lod_weights(FadeMode::DitherSequential, t * 100.0, 0.0, 100.0, h);
        assert_eq!(at(0.25, 0.99).lod0, 1.0);
        assert_eq!(at(0.25, 0.49).lod1, 1.0);
        assert_eq!(at(0.25, 0.51).lod1, 0.0);
        assert_eq!(at(0.75, 0.99).lod1, 1.0);
        assert_eq!(at(0.75, 0.49).lod0, 1.0);
        assert_eq!(at(0.75, 0.51).lod0, 0.0);
    }
}
