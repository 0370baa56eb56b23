//! # mips: alpha-aware mip chains for billboard layers (E Alg. 3.2, E§4.1; SPEC §5.2)
//!
//! The CPU twin of `gpu/src/shaders/mips.wgsl`, written shader-shaped on purpose:
//! [`downsample_texel`] is the body of one compute invocation of the downsampling pass,
//! [`AlphaAdjust::apply`] the body of one invocation of the alpha pass, and [`build_mips`] the
//! sequence of dispatches and reductions between them.
//!
//! ## Contract
//! Input: one layer of the billboard array texture, an [`Rgba8Image`] (sRGB colour, straight linear
//! alpha, SPEC §3) that is square with a power-of-two side `r` in `1..=`[`MAX_MIP_SIDE`]; anything
//! else is a [`MipError`] naming the size, never a panic. Output: a [`MipChain`] holding every
//! level from `r x r` down to `1 x 1` ([`mip_level_count`] levels), each both as the final linear
//! `f32` values ([`MipLevel::linear`], before 8-bit quantization) and as the final
//! [`Rgba8Image`] ([`MipLevel::rgba8`], sRGB colour and linear alpha, as stored in an
//! `Rgba8UnormSrgb` array texture).
//!
//! ## Pipeline, per layer
//! 1. **decode** level 0: colour through the sRGB curve, alpha as `byte / 255`
//!    ([`decode_level`], equal to [`Rgba8Image::to_linear`]). Level 0 is never modified: its
//!    final values *are* the decoded input, and its `rgba8` is the input itself (decode then
//!    encode round-trips every byte).
//! 2. **downsample** ([`downsample_level`], one [`downsample_texel`] per output texel): level `k`
//!    is computed from level `k - 1`'s *raw* values, i.e. unquantized `f32` and *before* any alpha
//!    adjustment (the adjustment of E Alg. 3.2 runs after all down-sampling, lines 12-14, so the
//!    down-sampling only ever sees raw alpha). The raw alpha of every mode is the box average of
//!    the 2x2 footprint (E Alg. 3.2 line 7: `AlphaSum / 4`); the colour depends on the mode.
//! 3. **reduce** the raw level: its alpha range ([`alpha_range`], E Alg. 3.2 lines 9-10) and, for
//!    [`MipMode::CoveragePreserving`], alpha-test counts ([`alpha_test_count`]).
//! 4. **adjust** alpha per texel with the level's [`AlphaAdjust`] (colour is never touched).
//! 5. **quantize** ([`quantize_level`]): colour to sRGB8, alpha to UNORM8, round to nearest.
//!
//! ## Modes ([`MipMode`])
//! - **AlphaAware**, E Alg. 3.2: colour `= Σ(c·α) / AlphaSum` over the footprint (line 6), raw
//!   `α = AlphaSum / 4` (line 7); then each level's alpha is remapped linearly from its own raw
//!   range `[MinAlpha_k, MaxAlpha_k]` to level 0's `[MinAlpha_0, MaxAlpha_0]` (line 13), so that
//!   "even at the highest mipmap-levels there will always be at least one fully opaque texel"
//!   (E§3.3.2, Fig. 3.6). Transparent texels get weight 0, so their colour (usually black, E Fig.
//!   3.4) never reaches the result: no dark fringes (E Fig. 3.5).
//! - **Box**: the plain per-channel 2x2 average of linear colour and alpha, no adjustment: the
//!   "blit" the thesis rejects (E Fig. 3.5). Kept as the variant that shows the dark fringes.
//! - **CoveragePreserving** (Castaño 2010, "Computing alpha mipmaps", as in NVTT): colour as in
//!   AlphaAware (no fringes), raw alpha the box average, then `α' = clamp(α · s_k, 0, 1)` with one
//!   scale `s_k` per level chosen so that the fraction of texels passing the alpha test equals
//!   level 0's as closely as possible (see [`coverage_scale`]).
//!
//! ## Loop structure versus E Alg. 3.2, and E§4.1
//! E Alg. 3.2 computes `MinAlpha_k` and `MaxAlpha_k` **per level** while down-sampling (lines 9-10)
//! and remaps every level afterwards from its own range to level 0's (lines 12-14). E§4.1 describes
//! the compute-shader implementation in three stages instead: "first the maximum and minimum alpha
//! values for each texture are computed" (once, before down-sampling), then down-sampling, then the
//! alpha "corrected using the minima and maxima from the first stage". Read literally, that gives
//! only level 0's range: the target of the remap, but not the per-level source range the remap
//! also needs (remapping from level 0's own range would be the identity). **We implement Alg.
//! 3.2**: per-level source ranges, level 0's range as the target. We fuse its two loops (each level
//! is adjusted right after it is reduced); this is equivalent because the adjustment of level `k`
//! needs only level `k`'s and level 0's ranges, and down-sampling reads raw alpha only.
//!
//! ## Degenerate rules (each tested; no rule ever yields NaN or infinity)
//! - **AlphaSum = 0** (all four footprint texels transparent), AlphaAware and CoveragePreserving:
//!   the colour is the plain average of the four colours (finite, deterministic, and invisible
//!   anyway), `α = 0`. Box computes the same.
//! - **A level with `MinAlpha_k == MaxAlpha_k`** (always the 1x1 level; also any level whose raw
//!   alpha happens to be uniform), AlphaAware: the remap is undefined. Every texel gets
//!   `α = MaxAlpha_0` if `MaxAlpha_k > 0`, else `MinAlpha_0` ([`AlphaAdjust::Constant`]): a tree
//!   must not become more transparent with distance (E§3.3.2, Fig. 3.6). Level 0 is never remapped
//!   (the remap of level 0 to its own range is the identity).
//! - **All-transparent layer** (`MaxAlpha_0 = 0`): every level has `α = 0` and the plain-average
//!   colour, in every mode. **All-opaque layer**: `α = 1` on every level, and the alpha-weighted
//!   colour equals the box average bit for bit (the weights are all 1 and the divisor is 4, an
//!   exact power of two).
//! - CoveragePreserving ([`coverage_scale`]): `s = 1` whenever it is as good as any other scale,
//!   which covers level-0 coverage 0 and 1 and all-transparent and all-opaque layers (box
//!   averages of alphas that all fail, or all pass, the test fail, or pass, alike). A 1x1 level's
//!   single texel passes or fails, whichever is closer to level 0's coverage; on a tie (coverage
//!   exactly 1/2) `s = 1` is kept. Otherwise ties go to the more opaque scale (E§3.3.2).
//!
//! ## Floating point (bit-reproducible; the WGSL twin matches within ±1 per 8-bit channel, SPEC §8)
//! All intermediate values are linear `f32`. Every sum of a 2x2 footprint is `(t00 + t10) +
//! (t01 + t11)` (texel `tij` at `(2x + i, 2y + j)`), with products `c · α` rounded before the
//! additions (no fused multiply-add; Rust never contracts). Averages multiply by `0.25` (exact);
//! the weighted colour divides by `AlphaSum`. The remap is `t = (α - min_k) / (max_k - min_k)`,
//! `α' = min_0 · (1 - t) + max_0 · t`, clamped to `[min_0, max_0]`, which is exact at both ends.
//! Raw alpha uses only additions and an exact `· 0.25`, which WGSL also rounds correctly, so the
//! raw alpha chain and its ranges are bit-identical on the GPU (and so are the coverage counts,
//! unless a compiler fuses the quantization's `x · 255 + 0.5` and a product lands on a tie);
//! colour may differ by a few ULP (WGSL division is within 2.5 ULP and compilers may fuse
//! `a · b + c`).
//!
//! ## Invariants (tested below)
//! - AlphaAware: every level's alpha range equals level 0's (up to the degenerate rule).
//! - AlphaAware and CoveragePreserving: a texel with `α > 0` has every colour channel within the
//!   range of that channel over the non-transparent level-0 texels of its footprint (SPEC §6);
//!   Box violates this next to black transparent texels.
//! - CoveragePreserving: each level's alpha-test coverage is the closest achievable to level 0's.
//! - No NaN or infinity anywhere; output independent of the rayon thread count.

use forestlod_shared::MipMode;
use rayon::prelude::*;

use crate::texture::{Image, LinearImage, Rgba8Image, decode_texel, encode_texel, unorm8};

/// Largest layer side accepted (a 4096 x 4096 layer has 13 levels).
pub const MAX_MIP_SIDE: u32 = 4096;

/// Bisection steps of [`coverage_scale`]. The search runs over the bit patterns of the
/// non-negative `f32` values in `[0, f32::MAX]`, which order like the values; the pattern gap
/// `0x7F7F_FFFF` is below `2^31`, so 31 halvings always end with two adjacent floats.
pub const COVERAGE_BISECTION_STEPS: u32 = 31;

/// Texels per parallel task of the per-level passes (small levels run as one task).
const TEXELS_PER_TASK: usize = 4096;

/// Why a mip chain could not be built. Every message names the offending value.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MipError {
    /// The layer is not square, its side not a power of two, or out of `1..=MAX_MIP_SIDE`.
    #[error(
        "mip layer is {width}x{height}: expected a square layer whose side is a power of two in \
         1..={MAX_MIP_SIDE}"
    )]
    BadSize {
        /// Width of the offending layer.
        width: u32,
        /// Height of the offending layer.
        height: u32,
    },
    /// The texel vector does not hold `width * height` texels.
    #[error("mip layer is {width}x{height} but holds {texels} texels: expected width * height")]
    TexelCount {
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
        /// Texels actually present.
        texels: usize,
    },
    /// The alpha-test reference is not a finite value in `0..=1`.
    #[error("mip alpha reference is {0}: expected a finite alpha in 0..=1")]
    AlphaRef(f32),
    /// A layer of an array differs in size from layer 0 (an array texture has one size).
    #[error(
        "mip array layer {layer} is {width}x{height}: expected the size of layer 0, \
         {expected_width}x{expected_height}"
    )]
    LayerSizeMismatch {
        /// Index of the offending layer.
        layer: usize,
        /// Its width.
        width: u32,
        /// Its height.
        height: u32,
        /// Width of layer 0.
        expected_width: u32,
        /// Height of layer 0.
        expected_height: u32,
    },
    /// A layer of an array was rejected; `error` says why.
    #[error("mip array layer {layer}: {error}")]
    Layer {
        /// Index of the offending layer.
        layer: usize,
        /// What was wrong with it.
        error: Box<MipError>,
    },
}

/// How a level's raw alpha becomes its final alpha; the uniform of the WGSL alpha pass. Colour is
/// never adjusted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaAdjust {
    /// Alpha unchanged: level 0 of every mode, every level of [`MipMode::Box`].
    Keep,
    /// E Alg. 3.2 line 13: linear remap of the raw range `from` (`from[0] < from[1]`) onto `to`
    /// (level 0's range), clamped to `to`.
    Remap {
        /// This level's raw `[MinAlpha_k, MaxAlpha_k]`.
        from: [f32; 2],
        /// Level 0's `[MinAlpha_0, MaxAlpha_0]`.
        to: [f32; 2],
    },
    /// The degenerate remap (`MinAlpha_k == MaxAlpha_k`): every texel gets this alpha.
    Constant(f32),
    /// Coverage scale (Castaño 2010): `α' = clamp(α · s, 0, 1)`.
    Scale(f32),
}

impl AlphaAdjust {
    /// Adjusts one raw alpha (the body of one invocation of the WGSL alpha pass). Operation order:
    /// `Remap` computes `t = (α - from[0]) / (from[1] - from[0])`, then
    /// `to[0] · (1 - t) + to[1] · t`, then `min(max(·, to[0]), to[1])`; `Scale` computes
    /// `min(max(α · s, 0), 1)`.
    #[allow(
        clippy::manual_clamp,
        reason = "max-then-min never panics (clamp does on bad bounds) and is WGSL's clamp"
    )]
    pub fn apply(self, alpha: f32) -> f32 {
        match self {
            AlphaAdjust::Keep => alpha,
            AlphaAdjust::Remap { from, to } => {
                let t = (alpha - from[0]) / (from[1] - from[0]);
                let remapped = to[0] * (1.0 - t) + to[1] * t;
                remapped.max(to[0]).min(to[1])
            }
            AlphaAdjust::Constant(a) => a,
            AlphaAdjust::Scale(s) => (alpha * s).max(0.0).min(1.0),
        }
    }
}

/// One level of a [`MipChain`].
#[derive(Clone, Debug, PartialEq)]
pub struct MipLevel {
    /// Final values in linear `f32` (straight alpha), before 8-bit quantization.
    pub linear: LinearImage,
    /// Final texels: sRGB colour, linear alpha, rounded to nearest ([`quantize_level`]).
    pub rgba8: Rgba8Image,
    /// `[min, max]` of this level's raw alpha, before adjustment (E Alg. 3.2's `MinAlpha_k`,
    /// `MaxAlpha_k`; for level 0, the input's range).
    pub raw_alpha_range: [f32; 2],
    /// The adjustment that turned raw alpha into final alpha.
    pub adjust: AlphaAdjust,
    /// Texels of [`Self::rgba8`] that pass the alpha test (`byte / 255 > alpha_ref`), reported
    /// for every mode so that experiments can compare coverage across modes.
    pub alpha_test_pass_count: u64,
}

/// The full mip chain of one layer, level 0 (the input) first, `1 x 1` last.
#[derive(Clone, Debug, PartialEq)]
pub struct MipChain {
    /// The mode it was built with.
    pub mode: MipMode,
    /// The alpha-test reference it was built with (used by CoveragePreserving and by
    /// [`MipLevel::alpha_test_pass_count`]).
    pub alpha_ref: f32,
    /// [`mip_level_count`]`(side)` levels, halving the side each time.
    pub levels: Vec<MipLevel>,
}

impl MipChain {
    /// Side of level 0.
    pub fn side(&self) -> u32 {
        self.levels[0].linear.width
    }
}

/// Number of mip levels of a side-`side` texture, down to 1x1: `floor(log2(side)) + 1`, and 0 for
/// `side = 0` (so 1 for 1, 2 for 2, 13 for 4096).
pub fn mip_level_count(side: u32) -> u32 {
    if side == 0 {
        0
    } else {
        u32::BITS - side.leading_zeros()
    }
}

/// Checks that a layer is square, power-of-two, in range and consistent; returns its side.
pub fn validate_layer(layer: &Rgba8Image) -> Result<u32, MipError> {
    let (width, height) = (layer.width, layer.height);
    if width != height || !width.is_power_of_two() || width > MAX_MIP_SIDE {
        return Err(MipError::BadSize { width, height });
    }
    if layer.texels.len() != (width as usize) * (height as usize) {
        return Err(MipError::TexelCount {
            width,
            height,
            texels: layer.texels.len(),
        });
    }
    Ok(width)
}

fn validate_alpha_ref(alpha_ref: f32) -> Result<(), MipError> {
    if alpha_ref.is_finite() && (0.0..=1.0).contains(&alpha_ref) {
        Ok(())
    } else {
        Err(MipError::AlphaRef(alpha_ref))
    }
}

/// The fixed-order sum of a 2x2 footprint: `(t00 + t10) + (t01 + t11)`.
fn sum4(t00: f32, t10: f32, t01: f32, t11: f32) -> f32 {
    (t00 + t10) + (t01 + t11)
}

/// One raw texel of the next level: the 2x2 footprint `(2x + i, 2y + j)`, `i, j ∈ {0, 1}`, of
/// `prev` (raw values of the previous level) reduced per `mode`. The body of one invocation of the
/// WGSL downsampling pass.
///
/// Alpha (every mode): `AlphaSum · 0.25` with `AlphaSum = sum4(α)` (E Alg. 3.2 lines 5, 7).
/// Colour: Box, or AlphaSum = 0: `sum4(c) · 0.25`; otherwise `sum4(c · α) / AlphaSum`
/// (E Alg. 3.2 line 6), each product rounded before the sum.
///
/// # Panics
/// If the footprint lies outside `prev` (callers pass `x, y < prev.width / 2`).
pub fn downsample_texel(prev: &LinearImage, x: u32, y: u32, mode: MipMode) -> [f32; 4] {
    let t00 = prev.get(2 * x, 2 * y);
    let t10 = prev.get(2 * x + 1, 2 * y);
    let t01 = prev.get(2 * x, 2 * y + 1);
    let t11 = prev.get(2 * x + 1, 2 * y + 1);
    let alpha_sum = sum4(t00[3], t10[3], t01[3], t11[3]);
    let weighted = mode != MipMode::Box && alpha_sum > 0.0;
    let mut out = [0.0, 0.0, 0.0, alpha_sum * 0.25];
    for c in 0..3 {
        out[c] = if weighted {
            sum4(
                t00[c] * t00[3],
                t10[c] * t10[3],
                t01[c] * t01[3],
                t11[c] * t11[3],
            ) / alpha_sum
        } else {
            sum4(t00[c], t10[c], t01[c], t11[c]) * 0.25
        };
    }
    out
}

/// Rows per parallel task for a level of side `side`.
fn rows_per_task(side: u32) -> usize {
    (TEXELS_PER_TASK / side.max(1) as usize).max(1)
}

/// One downsampling pass: the raw level after `prev` (raw, square, even side), by
/// [`downsample_texel`] per output texel. Rows are computed in parallel; each texel depends only
/// on its footprint, so the result is the same for any thread count.
///
/// # Panics
/// If `prev` is not square with an even side and `width * height` texels.
pub fn downsample_level(prev: &LinearImage, mode: MipMode) -> LinearImage {
    assert!(
        prev.width == prev.height && prev.width.is_multiple_of(2),
        "downsample_level needs a square level with an even side, got {}x{}",
        prev.width,
        prev.height
    );
    let side = prev.width / 2;
    let mut out = LinearImage::new(side, side, [0.0; 4]);
    let rows = rows_per_task(side);
    out.texels
        .par_chunks_mut(side as usize * rows)
        .enumerate()
        .for_each(|(chunk, texels)| {
            for (i, texel) in texels.iter_mut().enumerate() {
                let x = (i % side as usize) as u32;
                let y = (chunk * rows + i / side as usize) as u32;
                *texel = downsample_texel(prev, x, y, mode);
            }
        });
    out
}

/// `[min, max]` of a level's alpha (E Alg. 3.2 lines 9-10); `[0, 0]` for an empty image. Min and
/// max are exact, so any reduction order gives the same result (the GPU twin may use atomics on
/// the bit patterns, which order like the values for non-negative floats).
pub fn alpha_range(level: &LinearImage) -> [f32; 2] {
    let mut texels = level.texels.iter().map(|t| t[3]);
    let Some(first) = texels.next() else {
        return [0.0, 0.0];
    };
    texels.fold([first, first], |[lo, hi], a| [lo.min(a), hi.max(a)])
}

/// The AlphaAware adjustment of a level with raw range `raw` when level 0's range is `level0`
/// (E Alg. 3.2 line 13): [`AlphaAdjust::Remap`] when `raw[0] < raw[1]`, otherwise the degenerate
/// rule [`AlphaAdjust::Constant`]: `level0[1]` (MaxAlpha_0) if `raw[1] > 0`, else `level0[0]`.
pub fn alpha_aware_adjust(raw: [f32; 2], level0: [f32; 2]) -> AlphaAdjust {
    if raw[0] < raw[1] {
        AlphaAdjust::Remap {
            from: raw,
            to: level0,
        }
    } else if raw[1] > 0.0 {
        AlphaAdjust::Constant(level0[1])
    } else {
        AlphaAdjust::Constant(level0[0])
    }
}

/// Whether a final alpha passes the alpha test as the GPU sees it: quantized to UNORM8 first
/// (the texture stores bytes), then `byte / 255 > alpha_ref`.
pub fn passes_alpha_test(alpha: f32, alpha_ref: f32) -> bool {
    unorm8(alpha) as f32 / 255.0 > alpha_ref
}

/// Texels of `level` whose alpha, scaled by `scale` as [`AlphaAdjust::Scale`] does, passes the
/// alpha test ([`passes_alpha_test`]). `scale = 1` counts the level as is. Parallel; an integer
/// count, so independent of the reduction order.
pub fn alpha_test_count(level: &LinearImage, alpha_ref: f32, scale: f32) -> u64 {
    let adjust = AlphaAdjust::Scale(scale);
    level
        .texels
        .par_iter()
        .with_min_len(TEXELS_PER_TASK)
        .filter(|t| passes_alpha_test(adjust.apply(t[3]), alpha_ref))
        .count() as u64
}

/// The coverage-preserving scale `s_k` of a raw level (Castaño 2010, as in NVTT), given level 0's
/// alpha-test count `level0_count` out of `level0_texels` texels.
///
/// Coverage is measured as the GPU's alpha test will see it: on the quantized final alpha
/// ([`passes_alpha_test`]), so quantization cannot undo the choice. `count(s)` (texels passing
/// after `α' = clamp(α · s, 0, 1)`) is non-decreasing in `s`. The target is level 0's fraction,
/// `t = level0_count · n_k / level0_texels` texels; all comparisons are exact integer
/// cross-products.
///
/// 1. If `count(1)` is exactly the target: `s = 1`.
/// 2. If `goal = min(t, count(f32::MAX))` is 0 (level 0 has no passing texel, or no raw alpha of
///    this level is positive): `s = 1` when `count(1) = 0`, else `s = 0`. (`count(1) > 0` cannot
///    happen for valid inputs: box averages of alphas that all fail the test fail it too.)
/// 3. Otherwise bisect for the smallest `s` with `count(s) ≥ goal` (`count(f32::MAX)` being the
///    most any scale can reach): bracket `[0, f32::MAX]`, bisected over the `f32` bit patterns
///    for [`COVERAGE_BISECTION_STEPS`] steps, which ends with adjacent floats `lo < hi`,
///    `count(lo) < goal <= count(hi)`. Every count any `f32` scale can reach is then either
///    `≤ count(lo)` or `≥ count(hi)`, so the better of the two is optimal: there is no bisection
///    tolerance beyond the resolution of `f32` itself.
/// 4. Return `1` if `count(1)` is as close to `t` as that optimum (never change what needs no
///    change; this keeps 1x1 levels on a tie); otherwise `hi` if it is at least as close as `lo`
///    (the more opaque choice, E§3.3.2), else `lo`.
///
/// Counting uses the sorted raw alphas and a binary search per step (same predicate, same
/// counts as [`alpha_test_count`], which the GPU twin can run as a full pass per step).
///
/// Unlike NVTT's search (scales in `[0, 4]`, a few steps, supersampled coverage in later
/// versions) the bracket covers every scale, so sparse layers whose deep levels need `s > 4` keep
/// their coverage, and coverage is counted per texel, as Castaño 2010 first did.
pub fn coverage_scale(
    raw: &LinearImage,
    alpha_ref: f32,
    level0_count: u64,
    level0_texels: u64,
) -> f32 {
    let n_k = raw.texels.len() as u64;
    let target = level0_count * n_k; // in units of 1 / (n_k · level0_texels)
    let error = |count: u64| (count * level0_texels).abs_diff(target);
    let count_at_one = alpha_test_count(raw, alpha_ref, 1.0);
    if error(count_at_one) == 0 {
        return 1.0;
    }
    // `count(s)`, equal to `alpha_test_count(raw, alpha_ref, s)` but O(log n): the test is
    // monotone in α (products, clamp and quantization all round monotonically), so the passing
    // texels are a suffix of the sorted alphas. The GPU twin may count with a full pass instead.
    let mut sorted: Vec<f32> = raw.texels.iter().map(|t| t[3]).collect();
    sorted.par_sort_unstable_by(f32::total_cmp);
    let count = |scale: f32| {
        let adjust = AlphaAdjust::Scale(scale);
        let failing = sorted.partition_point(|&a| !passes_alpha_test(adjust.apply(a), alpha_ref));
        (sorted.len() - failing) as u64
    };
    let reachable = count(f32::MAX);
    let goal = target.min(reachable * level0_texels);
    if goal == 0 {
        return if count_at_one == 0 { 1.0 } else { 0.0 };
    }
    // Invariant: count(lo) · level0_texels < goal <= count(hi) · level0_texels.
    let (mut lo, mut hi) = (0u32, f32::MAX.to_bits());
    let (mut count_lo, mut count_hi) = (0u64, reachable);
    for _ in 0..COVERAGE_BISECTION_STEPS {
        let mid = lo + (hi - lo) / 2;
        let count_mid = count(f32::from_bits(mid));
        if count_mid * level0_texels >= goal {
            (hi, count_hi) = (mid, count_mid);
        } else {
            (lo, count_lo) = (mid, count_mid);
        }
    }
    debug_assert!(hi - lo <= 1, "bisection did not converge: {lo:#x}..{hi:#x}");
    let (best, best_error) = if error(count_hi) <= error(count_lo) {
        (f32::from_bits(hi), error(count_hi))
    } else {
        (f32::from_bits(lo), error(count_lo))
    };
    if error(count_at_one) <= best_error {
        1.0
    } else {
        best
    }
}

/// Applies `adjust` to every texel's alpha (colour unchanged); parallel over texels.
pub fn adjust_level(raw: &LinearImage, adjust: AlphaAdjust) -> LinearImage {
    let mut out = raw.clone();
    out.texels
        .par_iter_mut()
        .with_min_len(TEXELS_PER_TASK)
        .for_each(|t| t[3] = adjust.apply(t[3]));
    out
}

/// Decodes level 0 to linear with [`decode_texel`] (colour by the sRGB curve, alpha as
/// `byte / 255`); the same result as [`Rgba8Image::to_linear`], computed in parallel.
pub fn decode_level(level0: &Rgba8Image) -> LinearImage {
    par_map(level0, decode_texel)
}

/// Quantizes a final level to RGBA8 with [`encode_texel`] (colour by the inverse sRGB curve, alpha
/// by [`unorm8`]); the same result as [`LinearImage::to_rgba8`], computed in parallel.
pub fn quantize_level(level: &LinearImage) -> Rgba8Image {
    par_map(level, encode_texel)
}

/// [`Image::map`] in parallel over texels (order kept).
fn par_map<T: Copy + Sync, U: Send>(image: &Image<T>, f: impl Fn(T) -> U + Sync) -> Image<U> {
    Image {
        width: image.width,
        height: image.height,
        texels: image
            .texels
            .par_iter()
            .with_min_len(TEXELS_PER_TASK)
            .map(|&t| f(t))
            .collect(),
    }
}

/// Builds the mip chain of one layer (see the module docs for the contract and degenerate rules).
/// `alpha_ref` is the alpha-test reference (`Params::alpha_cutoff`), used by
/// [`MipMode::CoveragePreserving`] and for [`MipLevel::alpha_test_pass_count`].
///
/// Errors: [`MipError::BadSize`] for a non-square, non-power-of-two, empty or larger than
/// [`MAX_MIP_SIDE`] layer, [`MipError::TexelCount`] for an inconsistent one,
/// [`MipError::AlphaRef`] for a reference outside `0..=1`.
pub fn build_mips(
    level0: &Rgba8Image,
    mode: MipMode,
    alpha_ref: f32,
) -> Result<MipChain, MipError> {
    let side = validate_layer(level0)?;
    validate_alpha_ref(alpha_ref)?;
    let level_count = mip_level_count(side) as usize;

    let linear0 = decode_level(level0);
    let range0 = alpha_range(&linear0);
    let count0 = alpha_test_count(&linear0, alpha_ref, 1.0);
    let texels0 = linear0.texels.len() as u64;
    let mut levels = Vec::with_capacity(level_count);
    levels.push(MipLevel {
        linear: linear0,
        rgba8: level0.clone(),
        raw_alpha_range: range0,
        adjust: AlphaAdjust::Keep,
        alpha_test_pass_count: count0,
    });

    // The raw previous level when it differs from its final values (alpha adjusted).
    let mut detached_raw: Option<LinearImage> = None;
    for k in 1..level_count {
        let raw = downsample_level(detached_raw.as_ref().unwrap_or(&levels[k - 1].linear), mode);
        let raw_range = alpha_range(&raw);
        let adjust = match mode {
            MipMode::Box => AlphaAdjust::Keep,
            MipMode::AlphaAware => alpha_aware_adjust(raw_range, range0),
            MipMode::CoveragePreserving => {
                AlphaAdjust::Scale(coverage_scale(&raw, alpha_ref, count0, texels0))
            }
        };
        let linear = if adjust == AlphaAdjust::Keep {
            detached_raw = None;
            raw
        } else {
            let adjusted = adjust_level(&raw, adjust);
            detached_raw = Some(raw);
            adjusted
        };
        let rgba8 = quantize_level(&linear);
        let alpha_test_pass_count = rgba8
            .texels
            .iter()
            .filter(|t| t[3] as f32 / 255.0 > alpha_ref)
            .count() as u64;
        levels.push(MipLevel {
            linear,
            rgba8,
            raw_alpha_range: raw_range,
            adjust,
            alpha_test_pass_count,
        });
    }
    Ok(MipChain {
        mode,
        alpha_ref,
        levels,
    })
}

/// Builds the chains of every layer of an array texture, in parallel over layers (rayon); the
/// result is in layer order and identical for any thread count. All layers must have layer 0's
/// size. Layers are validated in order before any work, so the error (naming the first bad
/// layer) is deterministic too.
pub fn build_mip_array(
    layers: &[Rgba8Image],
    mode: MipMode,
    alpha_ref: f32,
) -> Result<Vec<MipChain>, MipError> {
    validate_alpha_ref(alpha_ref)?;
    for (layer, image) in layers.iter().enumerate() {
        validate_layer(image).map_err(|error| MipError::Layer {
            layer,
            error: Box::new(error),
        })?;
        let first = &layers[0];
        if (image.width, image.height) != (first.width, first.height) {
            return Err(MipError::LayerSizeMismatch {
                layer,
                width: image.width,
                height: image.height,
                expected_width: first.width,
                expected_height: first.height,
            });
        }
    }
    layers
        .par_iter()
        .enumerate()
        .map(|(layer, image)| {
            build_mips(image, mode, alpha_ref).map_err(|error| MipError::Layer {
                layer,
                error: Box::new(error),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::srgb_to_linear;
    use approx::assert_abs_diff_eq;
    use proptest::prelude::*;
    use std::sync::OnceLock;

    /// Hand-computed values are short decimals; the `f32` chain (alpha bytes divided by 255, one
    /// division per level, sums of four) lands within a few ULP of them, far below this.
    const HAND_TOL: f32 = 1e-6;
    /// Brief: every remapped level's alpha range equals level 0's within 1e-6 (the remap is in
    /// fact exact at both ends; the slack only guards the formula against future edits).
    const RANGE_TOL: f32 = 1e-6;
    /// A weighted average of values in `[lo, hi]` can leave the range by a few ULP per level
    /// (products and one division rounded); 12 levels of that stay below 1e-5.
    const FRINGE_TOL: f32 = 1e-5;

    fn image(side: u32, texels: Vec<[u8; 4]>) -> Rgba8Image {
        Rgba8Image {
            width: side,
            height: side,
            texels,
        }
    }

    fn assert_texel(actual: [f32; 4], expected: [f32; 4], tol: f32) {
        for c in 0..4 {
            assert_abs_diff_eq!(actual[c], expected[c], epsilon = tol);
        }
    }

    fn build(layer: &Rgba8Image, mode: MipMode) -> MipChain {
        build_mips(layer, mode, 0.5).unwrap()
    }

    // ---------------------------------------------------------------- sizes and errors

    #[test]
    fn level_counts() {
        assert_eq!(mip_level_count(0), 0);
        assert_eq!(mip_level_count(1), 1);
        assert_eq!(mip_level_count(2), 2);
        assert_eq!(mip_level_count(3), 2);
        assert_eq!(mip_level_count(128), 8);
        assert_eq!(mip_level_count(4096), 13);
    }

    #[test]
    fn bad_sizes_are_errors_naming_the_size() {
        for (w, h) in [(3, 3), (4, 2), (0, 0), (8192, 8192), (6, 6)] {
            let layer = Rgba8Image::new(w, h, [0; 4]);
            let err = build_mips(&layer, MipMode::AlphaAware, 0.5).unwrap_err();
            assert_eq!(
                err,
                MipError::BadSize {
                    width: w,
                    height: h
                }
            );
            assert!(err.to_string().contains(&format!("{w}x{h}")), "{err}");
        }
        let mut short = Rgba8Image::new(4, 4, [0; 4]);
        short.texels.pop();
        let err = build_mips(&short, MipMode::Box, 0.5).unwrap_err();
        assert!(
            matches!(err, MipError::TexelCount { texels: 15, .. }),
            "{err}"
        );
        assert!(err.to_string().contains("4x4"), "{err}");
    }

    #[test]
    fn bad_alpha_ref_is_an_error() {
        let layer = Rgba8Image::new(2, 2, [0; 4]);
        for a in [f32::NAN, -0.1, 1.5, f32::INFINITY] {
            let err = build_mips(&layer, MipMode::CoveragePreserving, a).unwrap_err();
            assert!(matches!(err, MipError::AlphaRef(_)), "{err}");
        }
        assert!(build_mips(&layer, MipMode::CoveragePreserving, 0.0).is_ok());
        assert!(build_mips(&layer, MipMode::CoveragePreserving, 1.0).is_ok());
    }

    #[test]
    fn array_errors_name_the_layer() {
        let ok = Rgba8Image::new(4, 4, [0; 4]);
        let small = Rgba8Image::new(2, 2, [0; 4]);
        let bad = Rgba8Image::new(3, 4, [0; 4]);
        let err = build_mip_array(&[ok.clone(), small], MipMode::AlphaAware, 0.5).unwrap_err();
        assert!(
            matches!(
                err,
                MipError::LayerSizeMismatch {
                    layer: 1,
                    width: 2,
                    ..
                }
            ),
            "{err}"
        );
        let err = build_mip_array(&[ok.clone(), ok.clone(), bad], MipMode::Box, 0.5).unwrap_err();
        assert!(matches!(err, MipError::Layer { layer: 2, .. }), "{err}");
        assert!(
            err.to_string().contains("layer 2") && err.to_string().contains("3x4"),
            "{err}"
        );
        assert_eq!(build_mip_array(&[], MipMode::Box, 0.5).unwrap(), vec![]);
        let chains = build_mip_array(&[ok.clone(), ok], MipMode::Box, 0.5).unwrap();
        assert_eq!(chains.len(), 2);
        assert_eq!(chains[0].levels.len(), 3);
    }

    // ---------------------------------------------------------------- level 0 and quantization

    #[test]
    fn level0_is_the_input_and_quantization_round_trips() {
        let texels: Vec<[u8; 4]> = (0..=255u8).map(|b| [b, 255 - b, b / 2, b]).collect();
        let layer = image(16, texels);
        for mode in MipMode::ALL {
            let chain = build(&layer, mode);
            assert_eq!(chain.levels[0].rgba8, layer);
            assert_eq!(chain.levels[0].linear, layer.to_linear());
            assert_eq!(chain.levels[0].adjust, AlphaAdjust::Keep);
            assert_eq!(quantize_level(&chain.levels[0].linear), layer);
            for level in &chain.levels {
                assert_eq!(level.rgba8, level.linear.to_rgba8());
            }
        }
    }

    #[test]
    fn one_texel_layer_is_its_own_chain() {
        let layer = image(1, vec![[10, 20, 30, 40]]);
        for mode in MipMode::ALL {
            let chain = build(&layer, mode);
            assert_eq!(chain.levels.len(), 1);
            assert_eq!(chain.levels[0].rgba8, layer);
            assert_eq!(chain.side(), 1);
        }
    }

    // ---------------------------------------------------------------- hand-made 2x2

    /// Red opaque, green alpha 0.2, black transparent, blue alpha 0.4.
    fn hand_2x2() -> Rgba8Image {
        image(
            2,
            vec![
                [255, 0, 0, 255],
                [0, 255, 0, 51],
                [0, 0, 0, 0],
                [0, 0, 255, 102],
            ],
        )
    }

    /// Builds [`hand_2x2`]'s chain in `mode` and checks its 1x1 level: the alpha adjustment, the
    /// linear texel (within [`HAND_TOL`]) and the RGBA8 texel. Returns the chain.
    fn check_hand_2x2_top(
        mode: MipMode,
        adjust: AlphaAdjust,
        linear: [f32; 4],
        rgba8: [u8; 4],
    ) -> MipChain {
        let chain = build(&hand_2x2(), mode);
        let top = &chain.levels[1];
        assert_eq!(top.adjust, adjust);
        assert_texel(top.linear.texels[0], linear, HAND_TOL);
        assert_eq!(top.rgba8.texels[0], rgba8);
        chain
    }

    #[test]
    fn hand_2x2_alpha_aware() {
        // AlphaSum = 1 + 0.2 + 0 + 0.4 = 1.6; colour = (1, 0.2, 0.4) / 1.6; raw alpha 0.4.
        // The 1x1 level is degenerate: alpha = MaxAlpha_0 = 1.
        // linear_to_srgb: 0.625 -> 207.15, 0.125 -> 99.09, 0.25 -> 136.96.
        let chain = check_hand_2x2_top(
            MipMode::AlphaAware,
            AlphaAdjust::Constant(1.0),
            [0.625, 0.125, 0.25, 1.0],
            [207, 99, 137, 255],
        );
        assert_abs_diff_eq!(chain.levels[1].raw_alpha_range[0], 0.4, epsilon = HAND_TOL);
    }

    #[test]
    fn hand_2x2_box() {
        // Plain average: every colour channel (1 + 0 + 0 + 0) / 4 = 0.25, alpha 0.4, no
        // equalization.
        check_hand_2x2_top(
            MipMode::Box,
            AlphaAdjust::Keep,
            [0.25, 0.25, 0.25, 0.4],
            [137, 137, 137, 102],
        );
    }

    #[test]
    fn hand_2x2_coverage() {
        // alpha_ref 0.5: level 0 passes 1 of 4 (red). The 1x1 raw alpha 0.4 fails at s = 1:
        // coverage 0 (error 1/4) beats coverage 1 (error 3/4), so s = 1 and alpha stays 0.4.
        let chain = check_hand_2x2_top(
            MipMode::CoveragePreserving,
            AlphaAdjust::Scale(1.0),
            [0.625, 0.125, 0.25, 0.4],
            [207, 99, 137, 102],
        );
        assert_eq!(chain.levels[0].alpha_test_pass_count, 1);
        assert_eq!(chain.levels[1].alpha_test_pass_count, 0);
        // alpha_ref 0.3: level 0 passes 2 of 4 (red, blue); the 1x1 level's 0.4 passes at s = 1
        // (coverage 1, error 1/2) and coverage 0 is no closer (error 1/2): s = 1 is kept.
        let chain = build_mips(&hand_2x2(), MipMode::CoveragePreserving, 0.3).unwrap();
        assert_eq!(chain.levels[1].adjust, AlphaAdjust::Scale(1.0));
        assert_eq!(chain.levels[1].alpha_test_pass_count, 1);
        // alpha_ref 0.45: level 0 passes 1 of 4 (blue's 102/255 = 0.4 fails); coverage 0
        // (error 1/4) beats 1 (error 3/4): s = 1 again.
        let chain = build_mips(&hand_2x2(), MipMode::CoveragePreserving, 0.45).unwrap();
        assert_eq!(chain.levels[0].alpha_test_pass_count, 1);
        assert_eq!(chain.levels[1].adjust, AlphaAdjust::Scale(1.0));
    }

    // ---------------------------------------------------------------- hand-made 4x4

    /// Four 2x2 blocks (x right, y down):
    /// - A (top-left): white, alpha 0.8 everywhere;
    /// - B (top-right): red opaque at (2, 0), the other three transparent black;
    /// - C (bottom-left): all transparent black;
    /// - D (bottom-right): green alpha 0.6 at (2, 2), green alpha 0.2 at (3, 2), blue opaque at
    ///   (2, 3), and a transparent *white* texel at (3, 3) that must never show.
    fn hand_4x4() -> Rgba8Image {
        let a = [255, 255, 255, 204];
        let t = [0, 0, 0, 0];
        image(
            4,
            vec![
                a,
                a,
                [255, 0, 0, 255],
                t, //
                a,
                a,
                t,
                t, //
                t,
                t,
                [0, 255, 0, 153],
                [0, 255, 0, 51], //
                t,
                t,
                [0, 0, 255, 255],
                [255, 255, 255, 0],
            ],
        )
    }

    #[test]
    fn hand_4x4_alpha_aware() {
        let chain = build(&hand_4x4(), MipMode::AlphaAware);
        assert_eq!(chain.levels[0].raw_alpha_range, [0.0, 1.0]);
        // Level 1 raw: A white 0.8; B red 0.25; C black (plain average) 0; D: AlphaSum 1.8,
        // colour (0, 0.8, 1) / 1.8, alpha 0.45. Raw range [0, 0.8] -> remap alpha / 0.8.
        let l1 = &chain.levels[1];
        assert_abs_diff_eq!(l1.raw_alpha_range[0], 0.0);
        assert_abs_diff_eq!(l1.raw_alpha_range[1], 0.8, epsilon = HAND_TOL);
        assert!(matches!(
            l1.adjust,
            AlphaAdjust::Remap { to: [0.0, 1.0], .. }
        ));
        assert_texel(l1.linear.get(0, 0), [1.0, 1.0, 1.0, 1.0], HAND_TOL);
        assert_texel(l1.linear.get(1, 0), [1.0, 0.0, 0.0, 0.3125], HAND_TOL);
        assert_texel(l1.linear.get(0, 1), [0.0, 0.0, 0.0, 0.0], HAND_TOL);
        assert_texel(
            l1.linear.get(1, 1),
            [0.0, 0.8 / 1.8, 1.0 / 1.8, 0.5625],
            HAND_TOL,
        );
        // Level 2 from level 1's *raw* values: AlphaSum = 0.8 + 0.25 + 0 + 0.45 = 1.5,
        // colour = ((0.8, 0.8, 0.8) + (0.25, 0, 0) + (0, 0.2, 0.25)) / 1.5 = (0.7, 2/3, 0.7).
        // 1x1: degenerate, alpha = MaxAlpha_0 = 1.
        let l2 = &chain.levels[2];
        assert_abs_diff_eq!(l2.raw_alpha_range[0], 0.375, epsilon = HAND_TOL);
        assert_eq!(l2.adjust, AlphaAdjust::Constant(1.0));
        assert_texel(l2.linear.texels[0], [0.7, 2.0 / 3.0, 0.7, 1.0], HAND_TOL);
    }

    #[test]
    fn hand_4x4_box() {
        let chain = build(&hand_4x4(), MipMode::Box);
        let l1 = &chain.levels[1];
        assert_texel(l1.linear.get(0, 0), [1.0, 1.0, 1.0, 0.8], HAND_TOL);
        assert_texel(l1.linear.get(1, 0), [0.25, 0.0, 0.0, 0.25], HAND_TOL);
        assert_texel(l1.linear.get(0, 1), [0.0, 0.0, 0.0, 0.0], HAND_TOL);
        // D: green, green, blue, and the transparent white leaks in: (1, 2, 1, 1...) / 4.
        assert_texel(l1.linear.get(1, 1), [0.25, 0.75, 0.5, 0.45], HAND_TOL);
        let l2 = &chain.levels[2];
        assert_texel(l2.linear.texels[0], [0.375, 0.4375, 0.375, 0.375], HAND_TOL);
        assert!(chain.levels.iter().all(|l| l.adjust == AlphaAdjust::Keep));
    }

    #[test]
    fn hand_4x4_coverage() {
        // alpha_ref 0.5: level 0 passes 7 of 16 (A x4 at 0.8, red, green 0.6, blue): 7/16.
        let chain = build(&hand_4x4(), MipMode::CoveragePreserving);
        assert_eq!(chain.levels[0].alpha_test_pass_count, 7);
        // Level 1 raw alpha (0.8, 0.25, 0, 0.45): at s = 1 one texel passes (error |4 - 7| / 16 ...
        // in quarter units: 1/4 vs 7/16 -> 3/16), two texels (2/4 vs 7/16 -> 1/16) is better and
        // needs the D texel to reach byte 128: 0.45 s >= 127.5 / 255 = 0.5, s = 10/9. Three
        // texels would need B's 0.25 to pass too (error 5/16).
        let l1 = &chain.levels[1];
        let AlphaAdjust::Scale(s) = l1.adjust else {
            panic!("{:?}", l1.adjust)
        };
        assert_abs_diff_eq!(s, 10.0 / 9.0, epsilon = HAND_TOL);
        assert_eq!(l1.alpha_test_pass_count, 2);
        assert_eq!(
            l1.rgba8.texels.iter().map(|t| t[3]).collect::<Vec<_>>(),
            vec![227, 71, 0, 128]
        );
        // Colour as AlphaAware (alpha-weighted).
        assert_texel(
            l1.linear.get(1, 1),
            [0.0, 0.8 / 1.8, 1.0 / 1.8, 0.5],
            HAND_TOL,
        );
        // Level 2 raw alpha 0.375 fails: coverage 0 (error 7/16) beats 1 (error 9/16): s = 1.
        let l2 = &chain.levels[2];
        assert_eq!(l2.adjust, AlphaAdjust::Scale(1.0));
        assert_texel(l2.linear.texels[0], [0.7, 2.0 / 3.0, 0.7, 0.375], HAND_TOL);
    }

    // ---------------------------------------------------------------- degenerate rules

    #[test]
    fn alpha_sum_zero_gives_the_plain_average() {
        let layer = image(
            2,
            vec![
                [255, 0, 0, 0],
                [0, 255, 0, 0],
                [0, 0, 255, 0],
                [255, 255, 255, 0],
            ],
        );
        for mode in MipMode::ALL {
            let chain = build(&layer, mode);
            let top = &chain.levels[1];
            assert_eq!(top.linear.texels[0], [0.5, 0.5, 0.5, 0.0], "{mode:?}");
            assert_eq!(top.rgba8.texels[0], [188, 188, 188, 0], "{mode:?}");
        }
        assert_eq!(
            build(&layer, MipMode::AlphaAware).levels[1].adjust,
            AlphaAdjust::Constant(0.0)
        );
    }

    #[test]
    fn uniform_raw_level_takes_level0_max() {
        // Each 2x2 block: one opaque texel, three transparent -> level 1 raw alpha 0.25 everywhere
        // (min = max on a 2x2 level): every texel gets MaxAlpha_0 = 1.
        let o = [200, 100, 50, 255];
        let t = [0, 0, 0, 0];
        let layer = image(4, vec![o, t, t, o, t, t, t, t, t, t, t, t, o, t, t, o]);
        let chain = build(&layer, MipMode::AlphaAware);
        let l1 = &chain.levels[1];
        assert_eq!(l1.raw_alpha_range, [0.25, 0.25]);
        assert_eq!(l1.adjust, AlphaAdjust::Constant(1.0));
        assert!(l1.linear.texels.iter().all(|t| t[3] == 1.0));
        // Colour is the opaque texel's exactly (the only weighted one in each footprint).
        assert!(l1.rgba8.texels.iter().all(|t| *t == o));
        // Level-0 min > 0 with a uniform level: still MaxAlpha_0.
        assert_eq!(
            alpha_aware_adjust([0.3, 0.3], [0.2, 0.9]),
            AlphaAdjust::Constant(0.9)
        );
        assert_eq!(
            alpha_aware_adjust([0.0, 0.0], [0.0, 0.0]),
            AlphaAdjust::Constant(0.0)
        );
    }

    #[test]
    fn remap_is_exact_at_both_ends_and_clamped() {
        let adjust = AlphaAdjust::Remap {
            from: [0.1, 0.7],
            to: [0.2, 1.0],
        };
        assert_eq!(adjust.apply(0.1), 0.2);
        assert_eq!(adjust.apply(0.7), 1.0);
        assert_abs_diff_eq!(adjust.apply(0.4), 0.6, epsilon = HAND_TOL);
        assert_eq!(adjust.apply(0.0), 0.2);
        assert_eq!(adjust.apply(2.0), 1.0);
        assert_eq!(AlphaAdjust::Scale(3.0).apply(0.5), 1.0);
        assert_eq!(AlphaAdjust::Scale(0.0).apply(0.5), 0.0);
    }

    #[test]
    fn all_transparent_and_all_opaque_layers() {
        let mut state = 0x9e37_79b9u32;
        let mut noise = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            (state >> 24) as u8
        };
        let colours: Vec<[u8; 3]> = (0..64).map(|_| [noise(), noise(), noise()]).collect();
        let transparent = image(8, colours.iter().map(|c| [c[0], c[1], c[2], 0]).collect());
        let opaque = image(8, colours.iter().map(|c| [c[0], c[1], c[2], 255]).collect());
        let box_t = build(&transparent, MipMode::Box);
        let box_o = build(&opaque, MipMode::Box);
        for mode in MipMode::ALL {
            let t = build(&transparent, mode);
            let o = build(&opaque, mode);
            for k in 0..t.levels.len() {
                // Colour: plain average, bit for bit the Box result; alpha 0 / 1 everywhere.
                assert_eq!(
                    t.levels[k].linear, box_t.levels[k].linear,
                    "{mode:?} level {k}"
                );
                assert_eq!(
                    o.levels[k].linear, box_o.levels[k].linear,
                    "{mode:?} level {k}"
                );
                assert!(t.levels[k].rgba8.texels.iter().all(|x| x[3] == 0));
                assert!(o.levels[k].rgba8.texels.iter().all(|x| x[3] == 255));
            }
        }
    }

    #[test]
    fn box_mode_shows_the_dark_fringe() {
        // A green opaque texel beside three black transparent ones (E Fig. 3.4): Box darkens the
        // visible texel to a quarter of the green, AlphaAware and CoveragePreserving keep green.
        let g = [0, 200, 0, 255];
        let t = [0, 0, 0, 0];
        let layer = image(2, vec![g, t, t, t]);
        let green = srgb_to_linear(200);
        let boxed = build(&layer, MipMode::Box).levels[1].linear.texels[0];
        assert!(boxed[3] > 0.0);
        assert_abs_diff_eq!(boxed[1], green * 0.25, epsilon = HAND_TOL);
        assert!(fringe_violations(&build(&layer, MipMode::Box)) > 0);
        for mode in [MipMode::AlphaAware, MipMode::CoveragePreserving] {
            let chain = build(&layer, mode);
            assert_eq!(chain.levels[1].linear.texels[0][1], green, "{mode:?}");
            assert_eq!(fringe_violations(&chain), 0);
        }
        // And on a real-sized crown: a disc of foliage on black transparency.
        let crown = disc_layer(64);
        assert!(fringe_violations(&build(&crown, MipMode::Box)) > 0);
        assert_eq!(fringe_violations(&build(&crown, MipMode::AlphaAware)), 0);
        assert_eq!(
            fringe_violations(&build(&crown, MipMode::CoveragePreserving)),
            0
        );
    }

    /// A foliage-like disc: opaque or semi-transparent green-brown texels inside a circle, black
    /// transparent outside, with deterministic noise (distinct-ish alpha values).
    fn disc_layer(side: u32) -> Rgba8Image {
        let mut texels = Vec::with_capacity((side * side) as usize);
        let c = side as f32 / 2.0;
        for y in 0..side {
            for x in 0..side {
                let h = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663))
                    .wrapping_mul(2_654_435_761);
                let d = ((x as f32 + 0.5 - c).powi(2) + (y as f32 + 0.5 - c).powi(2)).sqrt() / c;
                if d > 0.9 || h % 7 == 0 {
                    texels.push([0, 0, 0, 0]);
                } else {
                    let a = (255.0 * (1.0 - d * d * 0.8)) as u8 - (h >> 28) as u8;
                    texels.push([40 + (h >> 24) as u8 % 60, 90 + (h >> 16) as u8 % 120, 30, a]);
                }
            }
        }
        image(side, texels)
    }

    #[test]
    fn side_4096_is_finite() {
        // One 4096 x 4096 layer (SPEC §7: r = 4096), all modes; a disc tiled with noise.
        let disc = disc_layer(64);
        let mut layer = Rgba8Image::new(4096, 4096, [0; 4]);
        for y in 0..4096u32 {
            for x in 0..4096u32 {
                layer.texels[(y * 4096 + x) as usize] = disc.get(x % 64, y % 64);
            }
        }
        for mode in MipMode::ALL {
            let chain = build(&layer, mode);
            assert_eq!(chain.levels.len(), 13);
            assert_eq!(chain.levels[12].linear.width, 1);
            assert!(all_finite(&chain), "{mode:?}");
            if mode == MipMode::AlphaAware {
                // The 1x1 level takes MaxAlpha_0 (the disc's densest texel).
                let max0 = layer.texels.iter().map(|t| t[3]).max().unwrap();
                assert_eq!(chain.levels[12].rgba8.texels[0][3], max0);
            }
        }
    }

    // ---------------------------------------------------------------- property helpers

    fn all_finite(chain: &MipChain) -> bool {
        chain
            .levels
            .iter()
            .all(|l| l.linear.texels.iter().flatten().all(|v| v.is_finite()))
    }

    /// Texels (over all levels >= 1) with alpha > 0 whose colour leaves, by more than
    /// [`FRINGE_TOL`], the per-channel range of the non-transparent level-0 texels of their
    /// footprint.
    fn fringe_violations(chain: &MipChain) -> usize {
        let level0 = &chain.levels[0].linear;
        let mut violations = 0;
        for (k, level) in chain.levels.iter().enumerate().skip(1) {
            let f = 1u32 << k;
            for y in 0..level.linear.height {
                for x in 0..level.linear.width {
                    let t = level.linear.get(x, y);
                    if t[3] <= 0.0 {
                        continue;
                    }
                    let mut lo = [f32::INFINITY; 3];
                    let mut hi = [f32::NEG_INFINITY; 3];
                    for v in y * f..(y + 1) * f {
                        for u in x * f..(x + 1) * f {
                            let s = level0.get(u, v);
                            if s[3] > 0.0 {
                                for c in 0..3 {
                                    lo[c] = lo[c].min(s[c]);
                                    hi[c] = hi[c].max(s[c]);
                                }
                            }
                        }
                    }
                    if (0..3).any(|c| !(t[c] >= lo[c] - FRINGE_TOL && t[c] <= hi[c] + FRINGE_TOL)) {
                        violations += 1;
                    }
                }
            }
        }
        violations
    }

    /// The best coverage error any `f32` scale can reach for a raw level, by exhaustion, in the
    /// units of [`coverage_scale`]. The set of passing texels only changes at the smallest scale
    /// `s_v` at which some raw alpha `v` passes, so the reachable counts are 0 and `count(s_v)`
    /// for every distinct positive `v`. Each `s_v` is found on its own (a scalar bisection over
    /// the bit patterns) and each count by a full pass: independent of `coverage_scale`'s sorted
    /// search. Exact in `f32`: two raw alphas one ULP apart (different sums rounding apart) may
    /// be inseparable by any scale, which a real-valued oracle would miss.
    fn best_coverage_error(raw: &LinearImage, alpha_ref: f32, count0: u64, n0: u64) -> u64 {
        let target = count0 * raw.texels.len() as u64;
        let mut alphas: Vec<f32> = raw
            .texels
            .iter()
            .map(|t| t[3])
            .filter(|a| *a > 0.0)
            .collect();
        alphas.sort_by(f32::total_cmp);
        alphas.dedup();
        let passes = |v: f32, s: f32| passes_alpha_test(AlphaAdjust::Scale(s).apply(v), alpha_ref);
        let mut best = target; // count 0
        for v in alphas {
            if !passes(v, f32::MAX) {
                continue;
            }
            let (mut lo, mut hi) = (0u32, f32::MAX.to_bits());
            while hi - lo > 1 {
                let mid = lo + (hi - lo) / 2;
                if passes(v, f32::from_bits(mid)) {
                    hi = mid
                } else {
                    lo = mid
                }
            }
            let count = alpha_test_count(raw, alpha_ref, f32::from_bits(hi));
            best = best.min((count * n0).abs_diff(target));
        }
        best
    }

    fn with_alpha(alpha: u8) -> impl Strategy<Value = [u8; 4]> {
        any::<[u8; 3]>().prop_map(move |c| [c[0], c[1], c[2], alpha])
    }

    fn texel() -> impl Strategy<Value = [u8; 4]> {
        prop_oneof![
            4 => Just([0u8, 0, 0, 0]),
            1 => with_alpha(0),
            2 => with_alpha(255),
            3 => any::<[u8; 4]>(),
        ]
    }

    /// Square power-of-two layers of side `2^min_log2 ..= 2^max_log2`: mostly mixed texels (many
    /// black transparent ones), sometimes all transparent or all opaque.
    fn layer(min_log2: u32, max_log2: u32) -> impl Strategy<Value = Rgba8Image> {
        (min_log2..=max_log2).prop_flat_map(|e| {
            let side = 1u32 << e;
            let n = (side * side) as usize;
            prop_oneof![
                8 => prop::collection::vec(texel(), n),
                1 => prop::collection::vec(with_alpha(0), n),
                1 => prop::collection::vec(with_alpha(255), n),
            ]
            .prop_map(move |texels| image(side, texels))
        })
    }

    fn mode() -> impl Strategy<Value = MipMode> {
        prop::sample::select(MipMode::ALL.to_vec())
    }

    fn pool(threads: usize) -> &'static rayon::ThreadPool {
        static POOLS: OnceLock<[rayon::ThreadPool; 2]> = OnceLock::new();
        let pools = POOLS.get_or_init(|| {
            [1, 2].map(|n| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .unwrap()
            })
        });
        &pools[threads - 1]
    }

    /// Every output bit of a set of chains.
    fn fingerprint(chains: &[MipChain]) -> Vec<u32> {
        let mut bits = Vec::new();
        for chain in chains {
            for level in &chain.levels {
                bits.extend(level.linear.texels.iter().flatten().map(|v| v.to_bits()));
                bits.extend(level.rgba8.texels.iter().map(|t| u32::from_le_bytes(*t)));
                bits.extend(level.raw_alpha_range.map(f32::to_bits));
                bits.push(level.alpha_test_pass_count as u32);
                let adjust = match level.adjust {
                    AlphaAdjust::Keep => [0, 0, 0, 0, 0],
                    AlphaAdjust::Remap { from, to } => [
                        1,
                        from[0].to_bits(),
                        from[1].to_bits(),
                        to[0].to_bits(),
                        to[1].to_bits(),
                    ],
                    AlphaAdjust::Constant(a) => [2, a.to_bits(), 0, 0, 0],
                    AlphaAdjust::Scale(s) => [3, s.to_bits(), 0, 0, 0],
                };
                bits.extend(adjust);
            }
        }
        bits
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

        #[test]
        fn alpha_aware_levels_keep_level0_range(layer in layer(0, 6)) {
            let chain = build(&layer, MipMode::AlphaAware);
            let [min0, max0] = chain.levels[0].raw_alpha_range;
            prop_assert_eq!([min0, max0], alpha_range(&chain.levels[0].linear));
            for (k, level) in chain.levels.iter().enumerate().skip(1) {
                let [lo, hi] = alpha_range(&level.linear);
                let [raw_lo, raw_hi] = level.raw_alpha_range;
                if raw_lo == raw_hi {
                    // Degenerate (always the 1x1 level): every texel gets the rule's alpha.
                    let rule = if raw_hi > 0.0 { max0 } else { min0 };
                    prop_assert_eq!(level.adjust, AlphaAdjust::Constant(rule));
                    prop_assert!(level.linear.texels.iter().all(|t| t[3] == rule), "level {}", k);
                } else {
                    prop_assert!(level.linear.width > 1);
                    prop_assert!((lo - min0).abs() <= RANGE_TOL, "level {}: {} vs {}", k, lo, min0);
                    prop_assert!((hi - max0).abs() <= RANGE_TOL, "level {}: {} vs {}", k, hi, max0);
                }
            }
        }

        #[test]
        fn no_dark_fringe(layer in layer(0, 6)) {
            for mode in [MipMode::AlphaAware, MipMode::CoveragePreserving] {
                let chain = build(&layer, mode);
                prop_assert_eq!(fringe_violations(&chain), 0, "{:?}", mode);
            }
        }

        #[test]
        fn outputs_are_finite(layer in layer(0, 6), mode in mode(), alpha_ref in 0.0f32..=1.0) {
            let chain = build_mips(&layer, mode, alpha_ref).unwrap();
            prop_assert!(all_finite(&chain));
            prop_assert_eq!(chain.levels.len() as u32, mip_level_count(layer.width));
            for (k, level) in chain.levels.iter().enumerate() {
                prop_assert_eq!(level.linear.width, layer.width >> k);
                prop_assert_eq!(&level.rgba8, &level.linear.to_rgba8());
                prop_assert!(level.linear.texels.iter().all(|t| (0.0..=1.0).contains(&t[3])));
            }
        }

        #[test]
        fn thread_count_does_not_change_output(
            layers in (0u32..=5).prop_flat_map(|e| {
                let side = 1u32 << e;
                prop::collection::vec(
                    prop::collection::vec(texel(), (side * side) as usize)
                        .prop_map(move |t| image(side, t)),
                    1..4,
                )
            }),
            mode in mode(),
        ) {
            let one = pool(1).install(|| build_mip_array(&layers, mode, 0.5)).unwrap();
            let two = pool(2).install(|| build_mip_array(&layers, mode, 0.5)).unwrap();
            prop_assert_eq!(fingerprint(&one), fingerprint(&two));
            for (chain, layer) in one.iter().zip(&layers) {
                prop_assert_eq!(fingerprint(std::slice::from_ref(chain)),
                    fingerprint(&[build_mips(layer, mode, 0.5).unwrap()]));
            }
        }

        #[test]
        fn coverage_is_the_closest_achievable(layer in layer(3, 6), alpha_ref in 0.05f32..0.95) {
            let chain = build_mips(&layer, MipMode::CoveragePreserving, alpha_ref).unwrap();
            let n0 = layer.texels.len() as u64;
            let count0 = chain.levels[0].alpha_test_pass_count;
            let mut raw = chain.levels[0].linear.clone();
            for (k, level) in chain.levels.iter().enumerate().skip(1) {
                raw = downsample_level(&raw, MipMode::CoveragePreserving);
                let n_k = raw.texels.len() as u64;
                let count_k = level.alpha_test_pass_count;
                prop_assert_eq!(count_k, alpha_test_count(&level.linear, alpha_ref, 1.0));
                let error = (count_k * n0).abs_diff(count0 * n_k);
                let best = best_coverage_error(&raw, alpha_ref, count0, n0);
                prop_assert!(error <= best, "level {}: error {} best {}", k, error, best);
            }
        }

        #[test]
        fn alpha_aware_all_opaque_colour_is_the_box_average(
            colours in prop::collection::vec(any::<[u8; 3]>(), 256),
        ) {
            let layer = image(16, colours.iter().map(|c| [c[0], c[1], c[2], 255]).collect());
            let aa = build(&layer, MipMode::AlphaAware);
            let bx = build(&layer, MipMode::Box);
            for (a, b) in aa.levels.iter().zip(&bx.levels) {
                prop_assert_eq!(&a.linear, &b.linear);
            }
        }
    }

    #[test]
    fn coverage_within_one_texel_on_a_smooth_crown() {
        // Brief: each level's coverage within 1 / (texels of the level) of level 0's, for layers
        // with enough texels. (In general the bound is the size of the group of equal raw alphas
        // at the crossing; the property test above checks optimality against exhaustion.)
        let crown = disc_layer(64);
        for alpha_ref in [0.3, 0.5, 0.7] {
            let chain = build_mips(&crown, MipMode::CoveragePreserving, alpha_ref).unwrap();
            let c0 = chain.levels[0].alpha_test_pass_count as f64 / 4096.0;
            for level in chain.levels.iter().skip(1).filter(|l| l.linear.width >= 4) {
                let n = level.linear.texels.len() as f64;
                let c = level.alpha_test_pass_count as f64 / n;
                assert!(
                    (c - c0).abs() <= 1.0 / n,
                    "ref {alpha_ref} side {}: {c} vs {c0}",
                    level.linear.width
                );
            }
        }
    }

    #[test]
    fn chosen_scales_count_like_a_full_pass() {
        // The bisection counts on sorted alphas; the level's final count (a full pass over the
        // quantized texels) must agree with `alpha_test_count` at the chosen scale.
        let crown = disc_layer(64);
        let chain = build_mips(&crown, MipMode::CoveragePreserving, 0.5).unwrap();
        let mut raw = chain.levels[0].linear.clone();
        let mut scaled = 0;
        for level in chain.levels.iter().skip(1) {
            raw = downsample_level(&raw, MipMode::CoveragePreserving);
            let AlphaAdjust::Scale(s) = level.adjust else {
                panic!("{:?}", level.adjust)
            };
            scaled += usize::from(s != 1.0);
            assert_eq!(alpha_test_count(&raw, 0.5, s), level.alpha_test_pass_count);
            assert_eq!(adjust_level(&raw, level.adjust), level.linear);
        }
        assert!(
            scaled > 0,
            "the crown should need at least one non-unit scale"
        );
    }

    #[test]
    fn downsample_level_is_the_texelwise_function() {
        let linear = disc_layer(32).to_linear();
        for mode in MipMode::ALL {
            let level = downsample_level(&linear, mode);
            for y in 0..16 {
                for x in 0..16 {
                    assert_eq!(level.get(x, y), downsample_texel(&linear, x, y, mode));
                }
            }
        }
    }
}
