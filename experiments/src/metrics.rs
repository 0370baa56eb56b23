//! Accuracy of a rendered frame against the ray-traced ground truth (SPEC §10,
//! [`forestlod_reference::ground_truth`]): the "accuracy" half of the speed–accuracy trade.
//!
//! - **FLIP** (Andersson et al. 2020, via the `nv-flip` crate): a per-pixel perceptual error in
//!   `[0, 1]` between the ground truth and the frame, both sRGB8. We report its mean and its 95th
//!   and 99th percentiles (nearest-rank on the sorted map), because LOD artefacts are sparse: a
//!   mean alone hides a few badly wrong trees. Viewing condition: [`FLIP_PIXELS_PER_DEGREE`].
//! - **Coverage error**: the fraction of pixels whose class differs, *tree* versus *not tree*
//!   (sky or ground). The ground truth's class is the majority of its supersamples
//!   ([`forestlod_reference::ground_truth::PixelClass`]); the frame's comes from its LOD-id aux
//!   buffer (mesh, billboard or transition ids are trees). It isolates silhouette errors (billboard
//!   coverage, mip alpha, culling) from colour errors.
//! - **Per-LOD error maps**: the FLIP map split by the frame's LOD id, so one sees *where* the error
//!   comes from (E Fig. 3.1's colours name the classes), with the mean FLIP of each class.
//! - **LOD error** ([`lod_error`]): FLIP against the *same backend's full-detail frame* (the
//!   Vegetation baseline: every visible tree at its full mesh, same camera, same sampling). The
//!   error against the ray-traced truth above is dominated by the rasterizer's one-sample aliasing
//!   of alpha-tested foliage, which every variant shares (issue 12: FLIP 0.0510–0.0514 for every
//!   K x r in `angles_texture`); against a frame with the same aliasing that part cancels and
//!   what remains is what the LOD changed. Its mean, its 99th percentile (LOD artefacts are
//!   sparse) and the fraction of pixels it changed at all ([`LOD_CHANGED_LEVELS`]); and its mean
//!   over the pixels the frame shows as billboards (issue 30: the billboards' own error, which the
//!   whole-frame mean dilutes by the sky, the ground and the meshes).

use forestlod_reference::draw::{
    LOD_ID_BACKGROUND, LOD_ID_BILLBOARD, LOD_ID_MESH, LOD_ID_TERRAIN, LOD_ID_TRANSITION,
};
use forestlod_reference::ground_truth::{GroundTruthImage, PixelClass};
use forestlod_reference::texture::Rgba8Image;
use serde::{Deserialize, Serialize};

/// FLIP's viewing condition: pixels per degree of visual angle. The `nv-flip` default, 67 ppd
/// (a 0.7 m viewing distance from a 0.7 m wide 3840-pixel monitor, FLIP's reference setup). The
/// experiments' images are smaller than 4K, so this is the stricter choice: errors look as they
/// would when the frame fills a high-resolution display.
pub const FLIP_PIXELS_PER_DEGREE: f32 = forestlod_harness::flip::FLIP_PIXELS_PER_DEGREE;

/// The LOD-id classes of the per-LOD maps, with file-name labels, in display order.
pub const LOD_CLASSES: [(u32, &str); 5] = [
    (LOD_ID_MESH, "lod0"),
    (LOD_ID_BILLBOARD, "lod1"),
    (LOD_ID_TRANSITION, "transition"),
    (LOD_ID_TERRAIN, "terrain"),
    (LOD_ID_BACKGROUND, "sky"),
];

/// Whether an aux id is a tree (any LOD).
pub fn is_tree_id(id: u32) -> bool {
    matches!(id, LOD_ID_MESH | LOD_ID_BILLBOARD | LOD_ID_TRANSITION)
}

/// Accuracy figures of one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Accuracy {
    /// Mean FLIP error.
    pub flip_mean: f64,
    /// 95th percentile of the FLIP map.
    pub flip_p95: f64,
    /// 99th percentile of the FLIP map.
    pub flip_p99: f64,
    /// Fraction of pixels whose tree / not-tree class differs from the ground truth.
    pub coverage_error: f64,
    /// Fraction of pixels that are trees in the ground truth.
    pub gt_tree_fraction: f64,
    /// Fraction of pixels that are trees in the frame.
    pub tree_fraction: f64,
    /// LOD error ([`lod_error`]): mean FLIP against the same backend's full-detail frame. `NaN`
    /// in CSVs written before it existed.
    #[serde(default = "not_measured", deserialize_with = "nan_if_null")]
    pub lod_flip_mean: f64,
    /// LOD error: 99th percentile of that FLIP map.
    #[serde(default = "not_measured", deserialize_with = "nan_if_null")]
    pub lod_flip_p99: f64,
    /// LOD error: fraction of pixels whose colour differs from the full-detail frame by more
    /// than [`LOD_CHANGED_LEVELS`] in some channel.
    #[serde(default = "not_measured", deserialize_with = "nan_if_null")]
    pub lod_changed: f64,
    /// Total error ([`total_error`]): mean FLIP of our frame at the truth's sampling rate
    /// ([`crate::fair`]) against the truth. `NaN` where not measured.
    #[serde(default = "not_measured", deserialize_with = "nan_if_null")]
    pub total_flip_mean: f64,
    /// Total error: 99th percentile of that FLIP map.
    #[serde(default = "not_measured", deserialize_with = "nan_if_null")]
    pub total_flip_p99: f64,
    /// Total error: fraction of pixels whose tree / not-tree class (the truth's majority rule on
    /// both sides) differs from the truth's.
    #[serde(default = "not_measured", deserialize_with = "nan_if_null")]
    pub total_coverage_error: f64,
    /// LOD error over the billboard region (issue 30): the mean of the LOD error's FLIP map over
    /// the pixels whose LOD id is a billboard in this frame; `NaN` where the frame shows none.
    #[serde(default = "not_measured", deserialize_with = "nan_if_null")]
    pub lod_flip_billboard: f64,
}

fn not_measured() -> f64 {
    f64::NAN
}

/// A figure read back from JSON, where serde_json writes a `NaN` (not measured: e.g. the total
/// error of a sweep with `total_error = false`) as `null`.
fn nan_if_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    use serde::Deserialize;
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// A pixel counts as changed by the LOD when a channel differs from the full-detail frame by
/// more than this many 8-bit levels: 2 absorbs the ±1 rounding of two blends that differ only in
/// order (the parity tests' colour tolerance), so only real changes count.
pub const LOD_CHANGED_LEVELS: u8 = 2;

/// Fills the LOD-error figures of `acc` for `color` (LOD ids `aux`) against `full`, the same
/// backend's full-detail frame (module docs), and returns the FLIP map.
///
/// # Panics
/// If the sizes differ.
pub fn lod_error(
    acc: &mut Accuracy,
    full: &Rgba8Image,
    color: &Rgba8Image,
    aux: &[u32],
) -> Vec<f32> {
    let map = flip_map(full, color);
    let n = map.len().max(1) as f64;
    acc.lod_flip_mean = map.iter().map(|&e| e as f64).sum::<f64>() / n;
    acc.lod_flip_p99 = percentile(&map, 99.0);
    let (sum, count) = map
        .iter()
        .zip(aux)
        .filter(|&(_, &id)| id == LOD_ID_BILLBOARD)
        .fold((0.0, 0u64), |(s, c), (&e, _)| (s + f64::from(e), c + 1));
    acc.lod_flip_billboard = if count > 0 {
        sum / count as f64
    } else {
        f64::NAN
    };
    let changed = full
        .texels
        .iter()
        .zip(&color.texels)
        .filter(|(a, b)| (0..3).any(|c| a[c].abs_diff(b[c]) > LOD_CHANGED_LEVELS))
        .count();
    acc.lod_changed = changed as f64 / n;
    map
}

/// Fills the total-error figures of `acc`: `color` and `aux` are our frame box-filtered to the
/// truth's sampling rate ([`crate::fair::box_filter`]) and gathered onto the truth's layout
/// (`tile`: FLIP per tile, [`flip_map_tiled`]). Returns the FLIP map.
///
/// # Panics
/// If the sizes differ.
pub fn total_error(
    acc: &mut Accuracy,
    gt: &GroundTruthImage,
    color: &Rgba8Image,
    aux: &[u32],
    tile: Option<u32>,
) -> Vec<f32> {
    let (a, map) = accuracy(gt, color, aux, tile);
    acc.total_flip_mean = a.flip_mean;
    acc.total_flip_p99 = a.flip_p99;
    acc.total_coverage_error = a.coverage_error;
    map
}

/// [`flip_map`] on each `tile`-wide square of a mosaic ([`crate::fair::TruthLayout`]) alone, so
/// that FLIP's filters never reach from one tile into its neighbour; the whole image for `None`.
///
/// # Panics
/// If the sizes differ, or the image is not one row of whole tiles.
pub fn flip_map_tiled(reference: &Rgba8Image, test: &Rgba8Image, tile: Option<u32>) -> Vec<f32> {
    let Some(t) = tile else {
        return flip_map(reference, test);
    };
    assert!(
        reference.height == t && reference.width.is_multiple_of(t),
        "a mosaic is one row of whole tiles"
    );
    let crop = |img: &Rgba8Image, k: u32| Rgba8Image::from_fn(t, t, |x, y| img.get(k * t + x, y));
    let maps: Vec<Vec<f32>> = (0..reference.width / t)
        .map(|k| flip_map(&crop(reference, k), &crop(test, k)))
        .collect();
    let mut out = Vec::with_capacity(reference.texels.len());
    for y in 0..t as usize {
        for m in &maps {
            out.extend_from_slice(&m[y * t as usize..(y + 1) * t as usize]);
        }
    }
    out
}

/// The FLIP error map of `test` against `reference` (equal sizes), row-major, at
/// [`FLIP_PIXELS_PER_DEGREE`]: `forestlod_harness::flip::flip_map` (strips in parallel, the
/// whole-image map bit for bit).
///
/// # Panics
/// If the sizes differ.
pub fn flip_map(reference: &Rgba8Image, test: &Rgba8Image) -> Vec<f32> {
    assert_eq!(
        (reference.width, reference.height),
        (test.width, test.height),
        "FLIP needs equally sized images"
    );
    forestlod_harness::flip::flip_map(&reference.texels, &test.texels, test.width, test.height)
}

/// Nearest-rank percentile `p` in `[0, 100]` of unsorted values (0 for none).
pub fn percentile(values: &[f32], p: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut v = values.to_vec();
    let rank = ((p / 100.0) * v.len() as f64).ceil().max(1.0) as usize;
    // The rank-th smallest in `total_cmp` order: what a full sort would put there, found in
    // linear time (a sweep takes two percentiles of every frame's FLIP map).
    let at = rank.min(v.len()) - 1;
    let (_, nth, _) = v.select_nth_unstable_by(at, f32::total_cmp);
    *nth as f64
}

/// The median of timings (the upper one of an even count; `NaN` for none): what the benchmarks
/// report per configuration.
pub fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Accuracy of a frame (colour and LOD-id aux buffer) against the ground truth, and the FLIP map.
/// With `tile`, the images are mosaics of sampled tiles ([`crate::fair::TruthLayout`]) and FLIP
/// runs per tile ([`flip_map_tiled`]).
///
/// # Panics
/// If the sizes differ.
pub fn accuracy(
    gt: &GroundTruthImage,
    color: &Rgba8Image,
    aux: &[u32],
    tile: Option<u32>,
) -> (Accuracy, Vec<f32>) {
    assert_eq!(aux.len(), gt.class.len(), "aux buffer size");
    let map = flip_map_tiled(&gt.srgb, color, tile);
    let n = map.len().max(1) as f64;
    let mean = map.iter().map(|&e| e as f64).sum::<f64>() / n;
    let mut differ = 0u64;
    let mut gt_trees = 0u64;
    let mut trees = 0u64;
    for (c, &id) in gt.class.iter().zip(aux) {
        let a = *c == PixelClass::Tree;
        let b = is_tree_id(id);
        differ += (a != b) as u64;
        gt_trees += a as u64;
        trees += b as u64;
    }
    (
        Accuracy {
            flip_mean: mean,
            flip_p95: percentile(&map, 95.0),
            flip_p99: percentile(&map, 99.0),
            coverage_error: differ as f64 / n,
            gt_tree_fraction: gt_trees as f64 / n,
            tree_fraction: trees as f64 / n,
            lod_flip_mean: f64::NAN,
            lod_flip_p99: f64::NAN,
            lod_changed: f64::NAN,
            total_flip_mean: f64::NAN,
            total_flip_p99: f64::NAN,
            total_coverage_error: f64::NAN,
            lod_flip_billboard: f64::NAN,
        },
        map,
    )
}

/// A FLIP map as a magma-coloured image (black: no error, yellow-white: error 1), FLIP's own LUT.
pub fn error_image(map: &[f32], width: u32, height: u32) -> Rgba8Image {
    let lut = nv_flip::magma_lut().to_vec();
    let entries = lut.len() / 3;
    Rgba8Image {
        width,
        height,
        texels: map
            .iter()
            .map(|&e| {
                let i = ((e.clamp(0.0, 1.0) * 255.0).round() as usize) % entries;
                [lut[3 * i], lut[3 * i + 1], lut[3 * i + 2], 255]
            })
            .collect(),
    }
}

/// One class of the per-LOD split.
pub struct LodErrorMap {
    /// File-name label ([`LOD_CLASSES`]).
    pub label: &'static str,
    /// The FLIP map where the frame's id is this class, dark grey elsewhere.
    pub image: Rgba8Image,
    /// Pixels of this class.
    pub pixels: u64,
    /// Mean FLIP over them (0 when none).
    pub flip_mean: f64,
}

/// The FLIP map split by the frame's LOD id ([`LOD_CLASSES`]).
pub fn per_lod_error_maps(map: &[f32], aux: &[u32], width: u32, height: u32) -> Vec<LodErrorMap> {
    let full = error_image(map, width, height);
    LOD_CLASSES
        .iter()
        .map(|&(id, label)| {
            let mut sum = 0.0f64;
            let mut pixels = 0u64;
            let texels = full
                .texels
                .iter()
                .zip(map.iter().zip(aux))
                .map(|(t, (&e, &a))| {
                    if a == id {
                        sum += e as f64;
                        pixels += 1;
                        *t
                    } else {
                        [40, 40, 40, 255]
                    }
                })
                .collect();
            LodErrorMap {
                label,
                image: Rgba8Image {
                    width,
                    height,
                    texels,
                },
                pixels,
                flip_mean: if pixels == 0 {
                    0.0
                } else {
                    sum / pixels as f64
                },
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> Rgba8Image {
        Rgba8Image::from_fn(w, h, f)
    }

    #[test]
    fn flip_is_zero_for_identical_images_and_grows_with_the_difference() {
        let a = image(32, 32, |x, y| [(x * 8) as u8, (y * 8) as u8, 90, 255]);
        assert!(flip_map(&a, &a).iter().all(|&e| e == 0.0));
        let small = image(32, 32, |x, y| [(x * 8) as u8 + 3, (y * 8) as u8, 90, 255]);
        let large = image(32, 32, |x, y| {
            [255 - (x * 8) as u8, (y * 8) as u8, 200, 255]
        });
        let m = |b: &Rgba8Image| flip_map(&a, b).iter().map(|&e| e as f64).sum::<f64>();
        assert!(m(&small) < m(&large));
    }

    #[test]
    fn tiled_flip_is_each_tiles_own_flip() {
        let a = image(48, 16, |x, y| [(x * 5) as u8, (y * 9) as u8, 90, 255]);
        // A change in the middle tile only: the tiled map is zero in the other two tiles (a
        // whole-image FLIP spreads it across the seams) and equals that tile's own FLIP.
        let b = image(48, 16, |x, y| {
            let mut t = a.get(x, y);
            if (16..32).contains(&x) && (4..12).contains(&y) {
                t[0] = 255 - t[0];
            }
            t
        });
        let tiled = flip_map_tiled(&a, &b, Some(16));
        let whole = flip_map(&a, &b);
        let at = |m: &[f32], x: u32, y: u32| m[(y * 48 + x) as usize];
        for y in 0..16 {
            for x in (0..16).chain(32..48) {
                assert_eq!(at(&tiled, x, y), 0.0, "({x}, {y})");
            }
        }
        assert!(
            (0..16).any(|y| at(&whole, 15, y) > 0.0),
            "whole-image FLIP crosses seams"
        );
        let crop = |img: &Rgba8Image| Rgba8Image::from_fn(16, 16, |x, y| img.get(16 + x, y));
        let own = flip_map(&crop(&a), &crop(&b));
        for y in 0..16 {
            for x in 0..16 {
                assert_eq!(at(&tiled, 16 + x, y), own[(y * 16 + x) as usize]);
            }
        }
        assert_eq!(flip_map_tiled(&a, &b, None), whole);
    }

    #[test]
    fn percentiles_are_nearest_rank() {
        let v: Vec<f32> = (1..=100).map(|i| i as f32).collect();
        assert_eq!(percentile(&v, 95.0), 95.0);
        assert_eq!(percentile(&v, 99.0), 99.0);
        assert_eq!(percentile(&v, 100.0), 100.0);
        assert_eq!(percentile(&[], 50.0), 0.0);
    }

    /// The selection finds what sorting finds, on unsorted values with repeats, negatives,
    /// `-0.0` and NaN (`total_cmp` order), for every rank.
    #[test]
    fn percentiles_equal_the_sorted_rank_on_unsorted_values() {
        let mut v: Vec<f32> = (0..257u32)
            .map(|i| ((i.wrapping_mul(2_654_435_761) >> 7) % 50) as f32 * 0.25 - 3.0)
            .collect();
        v.extend([f32::NAN, -0.0, 0.0, 7.5, 7.5]);
        let mut sorted = v.clone();
        sorted.sort_by(f32::total_cmp);
        for k in 0..=200 {
            let p = k as f64 / 2.0;
            let rank = ((p / 100.0) * v.len() as f64).ceil().max(1.0) as usize;
            let want = sorted[rank.min(v.len()) - 1] as f64;
            let got = percentile(&v, p);
            assert!(got.to_bits() == want.to_bits(), "p{p}: {got} != {want}");
        }
    }

    #[test]
    fn coverage_error_counts_tree_versus_not_tree() {
        let (w, h) = (4, 2);
        let srgb = image(w, h, |_, _| [10, 20, 30, 255]);
        let class = vec![
            PixelClass::Tree,
            PixelClass::Tree,
            PixelClass::Sky,
            PixelClass::Ground,
            PixelClass::Tree,
            PixelClass::Sky,
            PixelClass::Sky,
            PixelClass::Ground,
        ];
        let gt = GroundTruthImage {
            width: w,
            height: h,
            samples_per_axis: 1,
            linear: vec![[0.0; 3]; 8],
            srgb: srgb.clone(),
            class,
            tree_fraction: vec![0.0; 8],
            rays: 8,
        };
        // Billboard and transition count as trees; terrain vs sky does not matter.
        let aux = [
            LOD_ID_BILLBOARD,
            LOD_ID_TRANSITION,
            LOD_ID_TERRAIN,
            LOD_ID_BACKGROUND,
            LOD_ID_TERRAIN, // miss
            LOD_ID_MESH,    // extra
            LOD_ID_BACKGROUND,
            LOD_ID_BACKGROUND,
        ];
        let (acc, map) = accuracy(&gt, &srgb, &aux, None);
        assert_eq!(acc.coverage_error, 2.0 / 8.0);
        assert_eq!(acc.flip_mean, 0.0);
        assert_eq!(map.len(), 8);
        let maps = per_lod_error_maps(&map, &aux, w, h);
        assert_eq!(maps.iter().map(|m| m.pixels).sum::<u64>(), 8);
    }
}
