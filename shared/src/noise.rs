//! The texture-space noise of Guerrero's LOD blend (G§4, issue 30): "a grey-level noise texture is
//! created in multiple resolutions. This texture is then used by the two blending LOD levels to
//! determine which texels are visible ... Only texels with an intensity smaller than the blend
//! factor are rendered", with texture filtering turned off (G§4 fn. 5). The screen-space threshold
//! of the other dithered fades is [`crate::dither_threshold`]; [`crate::DitherSpace`] chooses.
//!
//! ## Contract
//! - **The texture.** `r_n × r_n` texels (`Params::noise_size`, a power of two) with a full chain
//!   of levels `0..=q`, `q = log2 r_n`; level `l` has `(r_n >> l)²` texels, and texel `(l, i, j)`
//!   holds [`noise_texel`]`(l, i, j)`, an integer hash of the three, 24 bits as a fraction in
//!   `[0, 1)`. Every level is **re-hashed**, not averaged from the level below: the mean of the
//!   `4^l` uniform texels under a texel of level `l` has a standard deviation of
//!   `1 / (√12 · 2^l)`, so an averaged chain turns grey with distance and a threshold test on it
//!   keeps nearly all or nearly nothing: the blend becomes a step, G§4's "blurred to only a few
//!   grey values". Each level of a re-hashed chain is uniform on its own
//!   (`each_level_is_uniform_where_an_averaged_chain_is_grey`).
//! - **Addressing**: repeat (the noise tiles the LOD's texture space): texel
//!   `i = floor(u · s) mod s`, `j = floor(v · s) mod s`, `s = r_n >> l`, the LOD's own `uv`
//!   (the mesh texture's for LOD0, the billboard layer's for LOD1), so the noise is attached to
//!   the tree and moves with it. Nearest: no filtering.
//! - **Level** ([`noise_level`]): explicit, from the `uv` derivatives along framebuffer x and y as
//!   the implicit level of detail of `reference/src/sampler.rs` computes its scale factor (Vulkan
//!   §"Scale Factor Operation", isotropic: `ρ = max(|∂uv/∂x|, |∂uv/∂y|) · r_n`), then Vulkan's
//!   nearest mip of `λ = log2 ρ`: `ceil(λ + 1/2) − 1` (halves go down), clamped to `[0, q]`, so
//!   about one noise texel falls on a pixel. It is computed without `log2`, exactly, from the
//!   bits of `ρ²` (`λ > k + 1/2` ⇔ `ρ² > 2^(2k+1)`), and as the larger of the two axes' levels
//!   (the level is monotone in `ρ²`), so both twins choose the same level from the same
//!   derivatives, and a NaN or infinite derivative gives the coarsest level (the sampler's rule
//!   for a NaN `ρ`).
//!
//! ## A hash, not a texture (issue 30's design choice)
//! Both twins compute [`noise_texel`] where they need it; nothing is uploaded. A texture (R8, or
//! R32F to keep 24 bits) built by the reference and uploaded would hold exactly these values; the
//! hash reads the same values without a binding, memory (any `r_n` up to 4096 costs nothing), an
//! upload or a sampler, and it is exactly reproducible: `u32` wrapping arithmetic and one
//! conversion, the same bits on both sides ([`crate::dither_threshold`]'s argument). 24 bits,
//! not 8 (R8): the screen-space threshold has 24, so the two spaces differ in their domain only,
//! and the kept fraction is not quantised to 1/256. [`noise_level_texels`] is the texture as
//! data, for tests and for anyone who wants to upload it.
//!
//! The derivatives are where the twins may differ: the reference's are the rasterizer's coarse,
//! per-quad differences (`reference/src/raster/mod.rs` §7); the GPU's are `dpdxCoarse` /
//! `dpdyCoarse` of its own interpolated `uv`. A quad whose `ρ²` lies within rounding of a level
//! boundary `2^(2k+1)` may take the next level on one side: the parity test counts these
//! fragments and classifies the pixels they change (`tests/tests/parity/blend.rs`).
//!
//! Keep in sync with `gpu/src/shaders/common.wgsl` (`noise_texel`, `noise_level`,
//! `texture_noise`).

/// The 24-bit fraction of a PCG-style output permutation of `v` (Jarzynski & Olano 2020): the
/// last step of [`crate::dither_threshold`], in `[0, 1)`.
fn pcg_unit(v: u32) -> f32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    let v = (word >> 22) ^ word;
    (v >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// The value of texel `(i, j)` of noise level `level` (module docs), in `[0, 1)`: a hash of the
/// three. The level's own odd multiplier re-hashes every level; the constant keeps level 0 apart
/// from [`crate::dither_threshold`] of the same pixel coordinates.
pub fn noise_texel(level: u32, i: u32, j: u32) -> f32 {
    pcg_unit(
        i.wrapping_mul(1_664_525)
            .wrapping_add(j.wrapping_mul(1_013_904_223))
            .wrapping_add(level.wrapping_mul(0x632B_E5AB))
            .wrapping_add(0x85EB_CA6B),
    )
}

/// The noise level whose squared scale factor along one axis is `rho2` (module docs): the least
/// `k` with `ρ² <= 2^(2k+1)`, from the bits of `rho2` (below 1, zero and subnormal: 0; infinite
/// and NaN: past every level), not clamped.
pub fn noise_level_of(rho2: f32) -> u32 {
    let bits = rho2.to_bits() & 0x7FFF_FFFF;
    let exponent = bits >> 23;
    if exponent < 127 {
        return 0;
    }
    let whole = exponent - 127;
    let above = u32::from(bits & 0x7F_FFFF != 0);
    (whole + above) / 2
}

/// The squared length of a `uv` derivative `d` in texels of a side `size` texture.
fn scaled_length2(d: [f32; 2], size: f32) -> f32 {
    let (a, b) = (d[0] * size, d[1] * size);
    a * a + b * b
}

/// The explicit noise level of a fragment whose `uv` derivatives along framebuffer x and y are
/// `ddx` and `ddy`, for a noise texture of side `size` (module docs): Vulkan's nearest mip of
/// `log2(max(|ddx|, |ddy|) · size)`, in `0..=log2(size)`.
pub fn noise_level(ddx: [f32; 2], ddy: [f32; 2], size: u32) -> u32 {
    noise_level_scaled(ddx, ddy, size, 1.0)
}

/// [`noise_level`] with `ρ²` multiplied by `rho2_scale` first: 1 is [`noise_level`]; the parity
/// test's alternative reference frames move it by a small factor either way, to classify the
/// fragments whose level lies within the twins' derivative differences of a boundary
/// (`reference::draw::draw_frame_noise_scaled`).
pub fn noise_level_scaled(ddx: [f32; 2], ddy: [f32; 2], size: u32, rho2_scale: f32) -> u32 {
    let q = size.max(1).ilog2();
    let s = size as f32;
    let lx = noise_level_of(scaled_length2(ddx, s) * rho2_scale);
    let ly = noise_level_of(scaled_length2(ddy, s) * rho2_scale);
    lx.max(ly).min(q)
}

/// The texel `[i, j]` of noise level `level` of a side `size` texture that `uv` falls in
/// (module docs): nearest, repeat addressing.
pub fn noise_index(uv: [f32; 2], level: u32, size: u32) -> [u32; 2] {
    let side = (size >> level).max(1);
    let s = side as f32;
    let mask = side - 1;
    // `as i32` saturates (NaN to 0), as WGSL's `i32()` of an `f32` clamps; then wrap by the mask.
    let i = ((uv[0] * s).floor() as i32 as u32) & mask;
    let j = ((uv[1] * s).floor() as i32 as u32) & mask;
    [i, j]
}

/// The value at `uv` of noise level `level` of a side `size` texture ([`noise_index`]).
pub fn noise_at(uv: [f32; 2], level: u32, size: u32) -> f32 {
    let [i, j] = noise_index(uv, level, size);
    noise_texel(level, i, j)
}

/// The texture-space threshold of a fragment at `uv` with derivatives `ddx`, `ddy`: the noise
/// at its explicit level ([`noise_level`], [`noise_at`]).
pub fn texture_noise(uv: [f32; 2], ddx: [f32; 2], ddy: [f32; 2], size: u32) -> f32 {
    noise_at(uv, noise_level(ddx, ddy, size), size)
}

/// Level `level` of the noise texture of side `size` as data, row-major (`j` rows of `i`
/// columns): what an uploaded texture would hold (module docs).
pub fn noise_level_texels(level: u32, size: u32) -> Vec<f32> {
    let side = (size >> level).max(1);
    (0..side)
        .flat_map(|j| (0..side).map(move |i| noise_texel(level, i, j)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    use crate::test_support::proptest_config;

    /// `log2` the slow way, for the level's reference: Vulkan's `ceil(λ + 0.5) - 1` of
    /// `λ = 0.5 · log2(ρ²)`, in `f64`.
    fn level_by_log2(rho2: f64) -> u32 {
        if rho2 <= 1.0 {
            return 0;
        }
        let lambda = 0.5 * rho2.log2();
        ((lambda + 0.5).ceil() - 1.0).max(0.0) as u32
    }

    proptest! {
        #![proptest_config(proptest_config())]

        /// The bit-level level equals Vulkan's nearest-mip rounding of `log2 ρ`.
        #[test]
        fn the_level_is_vulkans_nearest_mip(rho2 in 0.0f32..1e12) {
            prop_assert_eq!(noise_level_of(rho2), level_by_log2(f64::from(rho2)), "ρ² = {}", rho2);
        }

        /// The level is the larger axis's and at most `log2 r_n`; it grows with the derivatives.
        #[test]
        fn the_level_is_monotone_and_clamped(
            dx in prop::array::uniform2(-0.5f32..0.5), dy in prop::array::uniform2(-0.5f32..0.5),
            k in 1.0f32..8.0, size_log in 0u32..13,
        ) {
            let size = 1 << size_log;
            let l = noise_level(dx, dy, size);
            prop_assert!(l <= size_log);
            let grown = noise_level([dx[0] * k, dx[1] * k], [dy[0] * k, dy[1] * k], size);
            prop_assert!(grown >= l, "{} then {}", l, grown);
            prop_assert_eq!(l, noise_level(dy, dx, size));
        }

        /// G§4's blend factor is the kept fraction: 64x64 pixels whose `uv` steps one texel of
        /// level `level` per pixel (so [`texture_noise`] chooses that level and every pixel reads
        /// a distinct texel) keep `cover` of themselves within 5σ of binomial sampling
        /// (`σ = √(c(1-c)/N)`) plus one pixel.
        #[test]
        fn the_kept_fraction_is_the_cover(
            level in 0u32..7, cover in 0.0f32..=1.0, u0 in -2.0f32..2.0, v0 in -2.0f32..2.0,
        ) {
            const SIDE: u32 = 64;
            let size = 4096u32;
            let step = (1u32 << level) as f32 / size as f32;
            let (ddx, ddy) = ([step, 0.0], [0.0, step]);
            prop_assert_eq!(noise_level(ddx, ddy, size), level);
            let n = (SIDE * SIDE) as f32;
            let kept = (0..SIDE * SIDE)
                .filter(|k| {
                    let uv = [u0 + (k % SIDE) as f32 * step, v0 + (k / SIDE) as f32 * step];
                    texture_noise(uv, ddx, ddy, size) < cover
                })
                .count() as f32
                / n;
            let sigma = (cover * (1.0 - cover) / n).sqrt();
            prop_assert!(
                (kept - cover).abs() <= 5.0 * sigma + 1.0 / n,
                "level {}: kept {} of cover {} (σ {})", level, kept, cover, sigma
            );
        }

        /// Addressing repeats: a whole texture period away is the same texel.
        #[test]
        fn the_noise_repeats(u in -4.0f32..4.0, v in -4.0f32..4.0, level in 0u32..8, n in -3i32..3) {
            let size = 256;
            let a = noise_at([u, v], level, size);
            let b = noise_at([u + n as f32, v - n as f32], level, size);
            // Exact where the shift keeps the product's rounding (whole numbers are exact below 2^24).
            if (u + n as f32) - n as f32 == u && (v - n as f32) + n as f32 == v {
                prop_assert_eq!(a, b);
            }
        }
    }

    #[test]
    fn levels_at_their_boundaries() {
        // ρ² = 2^(2k+1) exactly is level k (λ = k + 1/2 rounds down); the next f32 is k + 1.
        for k in 0..12u32 {
            let b = (2.0f32).powi(2 * k as i32 + 1);
            assert_eq!(noise_level_of(b), k, "k {k}");
            assert_eq!(noise_level_of(b.next_up()), k + 1, "k {k}");
            assert_eq!(noise_level_of(b.next_down()), k, "k {k}");
        }
        assert_eq!(noise_level_of(0.0), 0);
        assert_eq!(noise_level_of(1.0), 0);
        assert_eq!(noise_level_of(f32::MIN_POSITIVE / 2.0), 0);
        assert_eq!(noise_level([f32::NAN, 0.0], [0.0, 0.0], 256), 8);
        assert_eq!(noise_level([f32::INFINITY, 0.0], [0.0, 0.0], 256), 8);
        // One noise texel per pixel: level 0 at ρ = 1, level 3 at 8 texels per pixel.
        assert_eq!(noise_level([1.0 / 256.0, 0.0], [0.0, 1.0 / 256.0], 256), 0);
        assert_eq!(noise_level([8.0 / 256.0, 0.0], [0.0, 1.0 / 256.0], 256), 3);
        assert_eq!(noise_level([1.0, 1.0], [1.0, 1.0], 1), 0);
    }

    /// The G§4 warning, as a test: every re-hashed level is uniform (its kept fraction at a
    /// threshold is the threshold), while a box-filtered chain of the same level 0 collapses
    /// toward grey (at level 4 a threshold of 0.4 keeps almost nothing).
    #[test]
    fn each_level_is_uniform_where_an_averaged_chain_is_grey() {
        let size = 256u32;
        let mut averaged = noise_level_texels(0, size);
        for level in 0..=5u32 {
            let side = (size >> level) as usize;
            let texels = noise_level_texels(level, size);
            assert_eq!(texels.len(), side * side);
            for c in [0.1f32, 0.4, 0.75] {
                let n = texels.len() as f32;
                let kept = texels.iter().filter(|&&h| h < c).count() as f32 / n;
                let sigma = (c * (1.0 - c) / n).sqrt();
                assert!(
                    (kept - c).abs() <= 4.0 * sigma + 1.0 / n,
                    "level {level} cover {c}: kept {kept}"
                );
            }
            if level == 4 {
                let kept = averaged.iter().filter(|&&h| h < 0.4).count();
                assert!(
                    (kept as f32) < 0.01 * averaged.len() as f32,
                    "an averaged level 4 keeps {kept} of {}",
                    averaged.len()
                );
            }
            // The box filter of this level's averaged values: the chain G§4 warns against.
            let half = side / 2;
            if half > 0 {
                averaged = (0..half * half)
                    .map(|k| {
                        let (i, j) = (2 * (k % half), 2 * (k / half));
                        (averaged[j * side + i]
                            + averaged[j * side + i + 1]
                            + averaged[(j + 1) * side + i]
                            + averaged[(j + 1) * side + i + 1])
                            * 0.25
                    })
                    .collect();
            }
        }
    }

    #[test]
    fn texels_are_addressed_by_level_and_position() {
        let size = 64;
        for level in 0..=6u32 {
            let side = size >> level;
            let texels = noise_level_texels(level, size);
            for (j, i) in [(0, 0), (side - 1, 0), (0, side - 1), (side / 2, side / 3)] {
                let uv = [
                    (i as f32 + 0.5) / side as f32,
                    (j as f32 + 0.5) / side as f32,
                ];
                assert_eq!(noise_at(uv, level, size), texels[(j * side + i) as usize]);
            }
        }
        // Levels differ (re-hashed), and level 0 is not the screen threshold of the same pixel.
        assert_ne!(noise_texel(0, 5, 7), noise_texel(1, 5, 7));
        assert_ne!(noise_texel(0, 5, 7), crate::dither_threshold(5, 7));
    }
}
