//! The temporal (popping) error (issue 12, issue 29): how much a frame changes from the one
//! before along a camera path, in ways the motion itself does not explain. One implementation,
//! used by the `popping` program (`experiments/src/bin/popping.rs`, which adds its pop score on
//! tiles) and by every sweep with a camera path (`crate::sweep`'s `temporal_mean` and
//! `temporal_p99` columns).
//!
//! For consecutive frames `(t, t + 1)` of a path, with `v` the frames with LOD and `f` the
//! full-detail frames (the Vegetation baseline: every visible tree at its full mesh, the same
//! camera and the same one-sample rasterization; the sweeps' LOD error compares against the same
//! frames), both sequences box-filtered by [`DEFAULT_POOL`] ([`pool`]):
//!
//! ```text
//! excess(p) = max(0, FLIP(v_t, v_t+1)(p) − FLIP(f_t, f_t+1)(p))
//! ```
//!
//! the change between the two LOD frames beyond the change between the two full-detail frames
//! at the same pixel. Motion and aliasing change both sequences alike and cancel; what remains is
//! change the LOD made: a pop (a hard switch) or shimmer (a dither moving its pixel sets). Its
//! mean over pixels and its 99th percentile ([`TemporalError`]; a popping tree is a few hundred
//! pixels of a frame, so the mean alone hides it).
//!
//! **Why the box filter** (`experiments/popping/README.md`, "The measure"): one-sample
//! alpha-tested foliage shimmers under any sub-pixel motion, in the full-detail frames as much as
//! in ours, and at different pixels; that shimmer is not what a pop is, and a supersampled render
//! would not have it. Averaging 4x4 blocks removes it, while a tree that changes LOD still
//! changes the mean colour of the blocks it covers. The factor is clamped so that a pooled frame
//! keeps at least one pixel a side.

use forestlod_reference::texture::Rgba8Image;

use crate::metrics::{flip_map, percentile};

/// The box filter both sequences get before scoring: 4 (a 640x360 frame scored at 160x90), the
/// `popping` program's default and the sweeps' factor.
pub const DEFAULT_POOL: u32 = 4;

/// One frame pair's temporal error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TemporalError {
    /// Mean over (pooled) pixels of the excess change.
    pub mean: f64,
    /// 99th percentile over pixels of it (nearest rank).
    pub p99: f64,
}

/// `img` box-filtered by `k` in each direction (sRGB bytes averaged: a measure, not a
/// rendering); a partial block at the right or bottom edge is dropped. `k` is clamped to
/// `[1, min(width, height)]`, so a non-empty image stays non-empty.
pub fn pool(img: &Rgba8Image, k: u32) -> Rgba8Image {
    let k = k.min(img.width).min(img.height).max(1);
    if k == 1 {
        return img.clone();
    }
    let n = k * k;
    Rgba8Image::from_fn(img.width / k, img.height / k, |x, y| {
        let mut sum = [0u32; 4];
        for (dx, dy) in (0..k).flat_map(|dy| (0..k).map(move |dx| (dx, dy))) {
            let t = img.get(x * k + dx, y * k + dy);
            for c in 0..4 {
                sum[c] += u32::from(t[c]);
            }
        }
        sum.map(|v| ((v + n / 2) / n) as u8)
    })
}

/// The change between two (pooled) full-detail frames: the FLIP map `FLIP(f0, f1)`, shared by
/// every LOD variant of the pair.
///
/// # Panics
/// If the sizes differ.
pub fn full_change(f0: &Rgba8Image, f1: &Rgba8Image) -> Vec<f32> {
    flip_map(f0, f1)
}

/// The change between two (pooled) LOD frames, `FLIP(v0, v1)`, and its excess over
/// `full_map`, the change between the two full-detail frames at the same pixels
/// ([`full_change`]): `max(0, FLIP(v0, v1) − full_map)`.
///
/// # Panics
/// If the sizes differ.
pub fn pair_excess(v0: &Rgba8Image, v1: &Rgba8Image, full_map: &[f32]) -> (Vec<f32>, Vec<f32>) {
    let lod_map = flip_map(v0, v1);
    assert_eq!(lod_map.len(), full_map.len(), "maps of one frame size");
    let excess = lod_map
        .iter()
        .zip(full_map)
        .map(|(v, f)| (v - f).max(0.0))
        .collect();
    (lod_map, excess)
}

/// Mean and 99th percentile of an excess map (0 for an empty map: never NaN).
pub fn score(excess: &[f32]) -> TemporalError {
    let n = excess.len().max(1) as f64;
    TemporalError {
        mean: excess.iter().map(|&e| e as f64).sum::<f64>() / n,
        p99: percentile(excess, 99.0),
    }
}

/// The temporal error of the pair `(t, t + 1)` from frames already pooled ([`pool`]): LOD frames
/// `v0`, `v1` and full-detail frames `f0`, `f1`, all of one size.
///
/// # Panics
/// If the sizes differ.
pub fn temporal_error(
    v0: &Rgba8Image,
    v1: &Rgba8Image,
    f0: &Rgba8Image,
    f1: &Rgba8Image,
) -> TemporalError {
    score(&pair_excess(v0, v1, &full_change(f0, f1)).1)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GREEN: [u8; 4] = [40, 90, 30, 255];
    const SKY: [u8; 4] = [165, 195, 225, 255];
    const HILL: [u8; 4] = [110, 100, 70, 255];

    /// A frame of sky over a hill whose top moves with `shift` (the camera's motion), with a
    /// tree-sized block where `tree` says.
    fn frame(shift: u32, tree: bool) -> Rgba8Image {
        Rgba8Image::from_fn(64, 48, |x, y| {
            if tree && (20..36).contains(&x) && (10..30).contains(&y) {
                GREEN
            } else if y + x / 8 > 30 + shift {
                HILL
            } else {
                SKY
            }
        })
    }

    #[test]
    fn pooling_averages_blocks_and_never_empties_a_frame() {
        let img = Rgba8Image::from_fn(4, 2, |x, _| {
            if x % 2 == 0 {
                [0, 0, 0, 255]
            } else {
                [200, 100, 50, 255]
            }
        });
        let p = pool(&img, 2);
        assert_eq!((p.width, p.height), (2, 1));
        assert_eq!(p.texels, vec![[100, 50, 25, 255]; 2]);
        let tiny = pool(&img, DEFAULT_POOL);
        assert_eq!(
            (tiny.width, tiny.height),
            (2, 1),
            "clamped to the short side"
        );
        assert_eq!(pool(&img, 1), img);
        assert_eq!(pool(&img, 0), img);
    }

    /// LOD frames identical to the full-detail frames: whatever the motion, no excess. A tree
    /// popping in between two otherwise identical LOD frames, while the full-detail frames do
    /// not change: an excess, in the mean and (it covers more than 1 % of the frame) the p99.
    /// The mutations this guards against: scoring the LOD frames' change alone (the first case
    /// is then > 0) or subtracting the wrong way round (the second is then 0).
    #[test]
    fn identical_sequences_score_zero_and_a_popping_tree_scores_above_zero() {
        for k in [1, DEFAULT_POOL] {
            let (f0, f1) = (pool(&frame(0, false), k), pool(&frame(3, false), k));
            let same = temporal_error(&f0, &f1, &f0, &f1);
            assert_eq!(
                same,
                TemporalError {
                    mean: 0.0,
                    p99: 0.0
                },
                "pool {k}"
            );
            // The tree in both full-detail frames and both LOD frames, with motion: still 0.
            let (t0, t1) = (pool(&frame(0, true), k), pool(&frame(3, true), k));
            assert_eq!(temporal_error(&t0, &t1, &t0, &t1).mean, 0.0, "pool {k}");

            let still = pool(&frame(0, false), k);
            let popped = pool(&frame(0, true), k);
            let pop = temporal_error(&still, &popped, &still, &still);
            assert!(pop.mean > 0.0 && pop.p99 > 0.0, "pool {k}: {pop:?}");
            // The same change in the full-detail frames is the scene's, not the LOD's.
            let shared = temporal_error(&still, &popped, &still, &popped);
            assert_eq!(shared.mean, 0.0, "pool {k}");
        }
    }

    #[test]
    fn an_empty_map_scores_zero_not_nan() {
        assert_eq!(
            score(&[]),
            TemporalError {
                mean: 0.0,
                p99: 0.0
            }
        );
    }
}
