//! The colour target's pixel format and the output merge (module docs, step 9): the shader's
//! linear, straight-alpha colour is clamped to `[0, 1]` (NaN to 0), blended in `f32` with the
//! destination decoded to linear, and re-encoded to sRGB8 (round to nearest) after every
//! fragment, as wgpu's `Rgba8UnormSrgb` does.
//!
//! Invariants (each an equality, module docs "Speed-ups"):
//! - `srgb8` equals [`linear_to_srgb`] bit for bit (a table plus per-bucket start codes; relies on
//!   `linear_to_srgb` being non-decreasing in its `f32` input; `srgb8_equals_linear_to_srgb`,
//!   exhaustively the ignored `srgb8_equals_linear_to_srgb_everywhere`);
//! - opaque source-over is a replace (`merge`; `opaque_source_over_equals_replace`).
//!
//! Depends only on `types` ([`Blend`]).

use super::types::Blend;
use crate::texture::{linear_to_srgb, srgb_to_linear, unorm8};

/// Clamps to `[0, 1]`, NaN to 0 (Vulkan: fixed-point attachments clamp source values before
/// blending).
#[inline]
pub(super) fn clamp_color(c: [f32; 4]) -> [f32; 4] {
    c.map(|v| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) })
}

/// sRGB8 colour, UNORM8 alpha, rounded to nearest.
#[inline]
pub(super) fn encode(c: [f32; 4]) -> [u8; 4] {
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
pub(super) fn merge(dst: [u8; 4], src: [f32; 4], blend: Blend) -> [u8; 4] {
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
    use rayon::prelude::*;

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
}
