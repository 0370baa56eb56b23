//! FLIP (Andersson et al. 2020, the `nv-flip` crate) in horizontal strips, one per thread: the
//! same error map, bit for bit, in a fraction of the wall time (issue 14: FLIP was the longest
//! part of the main job's comparison, single-threaded, about 0.5 s at 1280x720).
//!
//! ## Why strips give the same map
//!
//! `nv-flip`'s C++ core (`FLIP::image::FLIP`, compiled without OpenMP, so one thread) computes
//! every output pixel as a pure function of the input pixels within a fixed radius of it:
//! per-pixel colour transforms, then two separable convolutions with edge clamping, the spatial
//! filter (radius `calculateSpatialFilterRadius(ppd)`) and the feature filter (radius
//! `ceil(3 · 0.5 · gw · ppd)`), each summed in a fixed kernel order; there is no image-wide
//! statistic (the colour normalisation `cmax` is a constant). So a strip of rows `y0..y1`,
//! computed from rows `y0 - H..y1 + H` (clamped to the image) with `H` at least the larger
//! radius, gives exactly the whole image's values in `y0..y1`: an interior strip edge lies at
//! least `H` rows from every row the strip keeps, and a strip edge at the image's edge clamps as
//! the whole image does. Checked bit for bit by `strips_equal_the_whole_image`, whose halo-1
//! mutant fails.
//!
//! ## Rows where the images agree are not computed
//!
//! The same locality gives a second saving: where the two images are equal within `H` rows of
//! a row, every input FLIP reads for that row is the same in both images, so its filtered colours
//! and features are equal, the colour difference is `HyAB = +0`, the feature difference `+0`,
//! and the error `pow(+0, 1 - 0) = +0` exactly. Only the runs of rows within `H` of a row that
//! differs (in R, G or B) are computed, in strips as above; the rest of the map is `+0.0`. The
//! main job's sky is such a run (a third of its rows at the default camera). Checked bit for bit
//! by `rows_far_from_every_difference_are_zero`, whose dilation-short mutant fails.
//!
//! Rejected: pooling FLIP per strip and combining the means (the mean of a mean is not FLIP's
//! mean bit for bit; the map is stitched and pooled once instead).

use rayon::prelude::*;

/// Pixels per degree passed to FLIP: its default (a 0.7 m viewing distance from a 24" 4K screen).
pub const FLIP_PIXELS_PER_DEGREE: f32 = nv_flip::DEFAULT_PIXELS_PER_DEGREE;

/// Fewest rows a strip keeps: its two halos (2 x 11 rows) then cost at most a sixth more. A
/// sweep's 320x180 frames stay whole (the sweeps already run frames in parallel).
const MIN_STRIP_ROWS: usize = 128;

/// Rows of context a strip needs on each side at `ppd` pixels per degree: the larger of FLIP's
/// two filter radii (`sharedflip.h` `calculateSpatialFilterRadius`, the largest Gaussian scale
/// parameter `b1.z = 0.04`; `image.h` `FLIP`, the feature filter with `gw = 0.082`), computed in
/// `f64` and plus one row, so that `f32` rounding in the C++ `ceil` can never make it smaller than
/// FLIP's own (a larger halo changes no value, only the cost). 11 rows at the default 67 ppd.
pub fn halo_rows(ppd: f32) -> usize {
    let ppd = f64::from(ppd);
    let spatial = (3.0 * (0.04 / (2.0 * std::f64::consts::PI.powi(2))).sqrt() * ppd).ceil();
    let feature = (3.0 * 0.5 * 0.082 * ppd).ceil();
    spatial.max(feature) as usize + 1
}

/// The FLIP error map (row-major, `width · height` values in `[0, 1]`) of `test` against
/// `reference`, two sRGB8 colour buffers (alpha ignored) of `width x height`, at
/// [`FLIP_PIXELS_PER_DEGREE`]; computed in strips in parallel, only near rows that differ (module
/// docs), equal bit for bit to `nv_flip::flip` on the whole images.
///
/// # Panics
/// If a buffer's length is not `width · height`.
pub fn flip_map(reference: &[[u8; 4]], test: &[[u8; 4]], width: u32, height: u32) -> Vec<f32> {
    let (w, h) = (width as usize, height as usize);
    assert_eq!(reference.len(), w * h, "FLIP: reference buffer length");
    assert_eq!(test.len(), w * h, "FLIP: test buffer length");
    let halo = halo_rows(FLIP_PIXELS_PER_DEGREE);
    let differs: Vec<bool> = reference
        .chunks(w.max(1))
        .zip(test.chunks(w.max(1)))
        .map(|(r, t)| r.iter().zip(t).any(|(a, b)| a[..3] != b[..3]))
        .collect();
    let strips = rayon::current_num_threads();
    let pieces = pieces(&differs, halo, strips, MIN_STRIP_ROWS);
    flip_map_of_pieces(reference, test, width, height, &pieces, halo)
}

/// The mean of [`flip_map`] as FLIP pools it (`nv_flip::FlipPool::mean`).
pub fn flip_mean(reference: &[[u8; 4]], test: &[[u8; 4]], width: u32, height: u32) -> f32 {
    let map = flip_map(reference, test, width, height);
    let image = nv_flip::FlipImageFloat::with_data(width, height, &map);
    nv_flip::FlipPool::from_image(&image).mean()
}

/// The row ranges `[y0, y1)` to compute, in order: the runs of rows within `halo` of a row
/// where `differs`, cut into about `strips` pieces of nearly equal height overall (none below
/// `min_rows` unless its run is shorter).
fn pieces(differs: &[bool], halo: usize, strips: usize, min_rows: usize) -> Vec<(usize, usize)> {
    let h = differs.len();
    let mut live = vec![false; h];
    for (y, _) in differs.iter().enumerate().filter(|(_, d)| **d) {
        live[y.saturating_sub(halo)..(y + halo + 1).min(h)].fill(true);
    }
    let mut runs = Vec::new();
    let mut y = 0;
    while y < h {
        if !live[y] {
            y += 1;
            continue;
        }
        let start = y;
        while y < h && live[y] {
            y += 1;
        }
        runs.push((start, y));
    }
    let total: usize = runs.iter().map(|(a, b)| b - a).sum();
    let target = total.div_ceil(strips.max(1)).max(min_rows).max(1);
    let mut out = Vec::new();
    for (a, b) in runs {
        let n = (b - a).div_ceil(target);
        out.extend((0..n).map(|k| (a + k * (b - a) / n, a + (k + 1) * (b - a) / n)));
    }
    out
}

/// The FLIP map with the rows of `pieces` computed (each in parallel, from its rows plus `halo`
/// rows on each side) and every other row `+0.0`.
fn flip_map_of_pieces(
    reference: &[[u8; 4]],
    test: &[[u8; 4]],
    width: u32,
    height: u32,
    pieces: &[(usize, usize)],
    halo: usize,
) -> Vec<f32> {
    let (w, h) = (width as usize, height as usize);
    let rgb = |c: &[[u8; 4]]| -> Vec<u8> { c.iter().flat_map(|p| [p[0], p[1], p[2]]).collect() };
    let parts: Vec<Vec<f32>> = pieces
        .par_iter()
        .map(|&(y0, y1)| {
            let (a, b) = (y0.saturating_sub(halo), (y1 + halo).min(h));
            let rows = (b - a) as u32;
            let r = nv_flip::FlipImageRgb8::with_data(width, rows, &rgb(&reference[a * w..b * w]));
            let t = nv_flip::FlipImageRgb8::with_data(width, rows, &rgb(&test[a * w..b * w]));
            let map = nv_flip::flip(r, t, FLIP_PIXELS_PER_DEGREE).to_vec();
            map[(y0 - a) * w..(y1 - a) * w].to_vec()
        })
        .collect();
    let mut out = vec![0.0f32; w * h];
    for (&(y0, y1), part) in pieces.iter().zip(parts) {
        out[y0 * w..y1 * w].copy_from_slice(&part);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Noise with large flat patches and sharp edges, so that both filters see structure at
    /// every strip boundary.
    fn image(w: u32, h: u32, seed: u64) -> Vec<[u8; 4]> {
        let mut s = seed;
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 33) as u8
        };
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if (x / 7 + y / 5) % 3 == 0 {
                    [next(), next(), next(), 255]
                } else {
                    [(x * 3) as u8, (y * 5) as u8, 90, 255]
                }
            })
            .collect()
    }

    fn whole(r: &[[u8; 4]], t: &[[u8; 4]], w: u32, h: u32) -> Vec<f32> {
        let rgb =
            |c: &[[u8; 4]]| -> Vec<u8> { c.iter().flat_map(|p| [p[0], p[1], p[2]]).collect() };
        let r = nv_flip::FlipImageRgb8::with_data(w, h, &rgb(r));
        let t = nv_flip::FlipImageRgb8::with_data(w, h, &rgb(t));
        nv_flip::flip(r, t, FLIP_PIXELS_PER_DEGREE).to_vec()
    }

    /// Even strips of the whole image.
    fn even(h: usize, strips: usize) -> Vec<(usize, usize)> {
        (0..strips)
            .map(|s| (s * h / strips, (s + 1) * h / strips))
            .collect()
    }

    fn bits(map: &[f32]) -> Vec<u32> {
        map.iter().map(|v| v.to_bits()).collect()
    }

    /// Every strip count, including strips thinner than the halo and one per row, gives the
    /// whole image's map bit for bit; and a halo one row shorter than FLIP's radius does not (so
    /// the test can see a wrong halo).
    #[test]
    fn strips_equal_the_whole_image() {
        let (w, h) = (53, 97);
        let (r, t) = (image(w, h, 1), image(w, h, 2));
        let want = bits(&whole(&r, &t, w, h));
        let halo = halo_rows(FLIP_PIXELS_PER_DEGREE);
        assert_eq!(halo, 11, "the default ppd's radii are 10 and 9");
        for strips in [1, 2, 3, 5, 8, 13, 97] {
            let got = flip_map_of_pieces(&r, &t, w, h, &even(h as usize, strips), halo);
            assert_eq!(bits(&got), want, "{strips} strips");
        }
        assert_eq!(bits(&flip_map(&r, &t, w, h)), want);
        let short = flip_map_of_pieces(&r, &t, w, h, &even(h as usize, 4), halo - 2);
        assert_ne!(
            bits(&short),
            want,
            "a halo shorter than FLIP's radius must show"
        );
        let mean = flip_mean(&r, &t, w, h);
        let pooled = nv_flip::FlipPool::from_image(&nv_flip::FlipImageFloat::with_data(
            w,
            h,
            &whole(&r, &t, w, h),
        ))
        .mean();
        assert_eq!(mean.to_bits(), pooled.to_bits());
        assert!(mean > 0.05, "the images differ: mean {mean}");
    }

    /// Images equal but in a few scattered rows (one at the top edge, one at the bottom, two
    /// close together, one alone): the map computed only near those rows is the whole image's
    /// bit for bit (zeros elsewhere), for several strip counts; dilating by two rows less
    /// than the halo is not.
    #[test]
    fn rows_far_from_every_difference_are_zero() {
        let (w, h) = (41u32, 160u32);
        let r = image(w, h, 3);
        let noise = image(w, h, 4);
        let rows = [0usize, 37, 40, 95, 159];
        let t: Vec<[u8; 4]> = r
            .iter()
            .zip(&noise)
            .enumerate()
            .map(|(i, (a, b))| {
                if rows.contains(&(i / w as usize)) {
                    *b
                } else {
                    *a
                }
            })
            .collect();
        let want = bits(&whole(&r, &t, w, h));
        let zeros = want.iter().filter(|&&v| v == 0).count();
        assert!(
            zeros > want.len() / 4,
            "most of the map is far from a difference: {zeros} zeros"
        );
        assert_eq!(bits(&flip_map(&r, &t, w, h)), want);
        let differs: Vec<bool> = (0..h as usize).map(|y| rows.contains(&y)).collect();
        let halo = halo_rows(FLIP_PIXELS_PER_DEGREE);
        for strips in [1, 2, 5] {
            for min_rows in [1, 16, 64] {
                let p = pieces(&differs, halo, strips, min_rows);
                let skipped = h as usize - p.iter().map(|(a, b)| b - a).sum::<usize>();
                assert!(skipped > 40, "{skipped} rows skipped");
                let got = flip_map_of_pieces(&r, &t, w, h, &p, halo);
                assert_eq!(
                    bits(&got),
                    want,
                    "{strips} strips, {min_rows} rows at least"
                );
            }
        }
        let narrow = pieces(&differs, halo - 2, 2, 1);
        assert_ne!(
            bits(&flip_map_of_pieces(&r, &t, w, h, &narrow, halo)),
            want,
            "rows within FLIP's radius of a difference must be computed"
        );
        assert!(
            flip_map(&r, &r, w, h).iter().all(|&v| v.to_bits() == 0),
            "equal images: all +0"
        );
    }
}
