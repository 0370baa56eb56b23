//! A fair comparison with the ray-traced truth (issue 12's *total error*): our frame sampled as
//! the truth is, and the truth traced on sampled tiles where the full frame is too slow.
//!
//! - **Equal sampling** ([`box_filter`]): the truth takes an `s x s` ordered grid of samples per
//!   pixel at `((i + 0.5)/s, (j + 0.5)/s)` and box-filters them in linear light
//!   ([`forestlod_reference::ground_truth`]). Rendering our frame at `s·w x s·h` puts the pixel
//!   centres of the large frame at exactly those points (`(s·x + i + 0.5)/s = x + (i + 0.5)/s`),
//!   so box-filtering each `s x s` block in linear light gives our frame at the truth's sampling
//!   rate: the foliage aliasing a 1-sample frame has and the truth has not is gone from both, and
//!   what is left of the error is the pipeline's own (LOD, mips, batching, the rasterizer's
//!   texture filtering). The one difference: our samples are sRGB8 before the filter (decoded
//!   exactly, averaged in `f32`), the truth's are `f32`, so ours may round differently by ±1 level.
//!   The large frame is a real render at the larger size (the mip level follows the pixel
//!   footprint, as in any supersampled renderer); selection does not depend on the size.
//! - **Classes of a filtered pixel** ([`box_filter`]): as the truth's, *tree* when at least half
//!   of the `s²` samples are tree ids; the pixel's LOD id is then the most frequent tree id of the
//!   block, else the most frequent other id (ties to [`crate::metrics::LOD_CLASSES`]' order). So
//!   coverage and the per-LOD maps compare like with like.
//! - **Sampled tiles** ([`TruthLayout`]): where a sweep asks (`truth_tiles = { size, fraction }`),
//!   the truth traces only `round(fraction · tiles)` of the frame's whole `size x size` tiles
//!   (at least one), chosen by a fixed hash of the tile's position: deterministic, the same for
//!   every pose, variant and backend of a frame size, and spread over the frame without a pattern
//!   that could align with the scene. Every error against the truth is then computed on those
//!   tiles only: the chosen tiles of the truth and of our frames are packed left to right into a
//!   `k·size x size` strip (the *mosaic*), and FLIP runs on each tile alone
//!   ([`crate::metrics::flip_map_tiled`]), so no filter crosses from one tile into the next. The
//!   mean over the mosaic is an unbiased estimate of the full frame's mean. A frame's right and
//!   bottom margins narrower than a tile are never sampled (none at 1280x720 and 80-pixel tiles).

use forestlod_reference::ground_truth::{GroundTruthImage, GroundTruthScene, TruthLighting};
use forestlod_reference::texture::{Rgba8Image, linear_to_srgb, srgb_to_linear};
use forestlod_shared::Camera;
use serde::{Deserialize, Serialize};

use crate::metrics::{LOD_CLASSES, is_tree_id};

/// `truth_tiles` of a sweep file: trace `fraction` of the frame's `size x size` tiles.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TileSpec {
    /// Tile side, pixels.
    pub size: u32,
    /// Fraction of the whole tiles traced, in (0, 1].
    pub fraction: f64,
}

impl TileSpec {
    /// Why this spec cannot be used, if it cannot.
    pub fn check(&self) -> Result<(), String> {
        if self.size == 0 {
            return Err("tile size must be at least 1 pixel".into());
        }
        if !(self.fraction > 0.0 && self.fraction <= 1.0) {
            return Err(format!(
                "tile fraction must be in (0, 1], got {}",
                self.fraction
            ));
        }
        Ok(())
    }
}

/// Where the truth is traced: the whole frame, or sampled tiles packed into a mosaic.
#[derive(Clone, Debug, PartialEq)]
pub enum TruthLayout {
    /// Every pixel.
    Full,
    /// The chosen tiles, `[x0, y0, size, size]` in reading order.
    Tiles {
        /// Tile side, pixels.
        size: u32,
        /// The tiles, in reading order (top row first).
        rects: Vec<[u32; 4]>,
    },
}

/// SplitMix64's finalizer: the fixed hash that ranks tiles.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl TruthLayout {
    /// The layout for a `width x height` frame: [`TruthLayout::Full`] without tiles, or when the
    /// tiles would cover every pixel anyway (fraction 1 on a frame the tiles divide) or the frame
    /// holds no whole tile.
    pub fn new(width: u32, height: u32, tiles: Option<TileSpec>) -> Self {
        let Some(t) = tiles else {
            return Self::Full;
        };
        let (nx, ny) = (width / t.size, height / t.size);
        let n = nx as usize * ny as usize;
        let k = ((t.fraction * n as f64).round() as usize).clamp(1, n.max(1));
        if n == 0 || (k == n && nx * t.size == width && ny * t.size == height) {
            return Self::Full;
        }
        let mut all: Vec<(u64, u32, u32)> = (0..ny)
            .flat_map(|j| (0..nx).map(move |i| (mix(((j as u64) << 32) | i as u64), i, j)))
            .collect();
        all.sort_unstable();
        let mut chosen: Vec<(u32, u32)> = all[..k].iter().map(|&(_, i, j)| (j, i)).collect();
        chosen.sort_unstable();
        Self::Tiles {
            size: t.size,
            rects: chosen
                .into_iter()
                .map(|(j, i)| [i * t.size, j * t.size, t.size, t.size])
                .collect(),
        }
    }

    /// The FLIP block size: the tile side, or `None` for the full frame.
    pub fn tile(&self) -> Option<u32> {
        match self {
            Self::Full => None,
            Self::Tiles { size, .. } => Some(*size),
        }
    }

    /// Fraction of a `width x height` frame's pixels the truth traces.
    pub fn fraction(&self, width: u32, height: u32) -> f64 {
        match self {
            Self::Full => 1.0,
            Self::Tiles { size, rects } => {
                (rects.len() as f64 * (*size as f64).powi(2)) / (width as f64 * height as f64)
            }
        }
    }

    /// A short description for CSVs and the report.
    pub fn describe(&self, width: u32, height: u32) -> String {
        match self {
            Self::Full => "full frame".into(),
            Self::Tiles { size, rects } => format!(
                "{} tiles of {size}x{size} ({:.1}% of the frame's pixels)",
                rects.len(),
                100.0 * self.fraction(width, height)
            ),
        }
    }

    /// The pixels of a `width`-wide row-major buffer at the layout's tiles, packed into the
    /// mosaic (row-major, `k·size` wide); the buffer itself for the full frame.
    pub fn gather<T: Copy>(&self, values: &[T], width: u32) -> Vec<T> {
        match self {
            Self::Full => values.to_vec(),
            Self::Tiles { size, rects } => {
                let s = *size as usize;
                let mut out = Vec::with_capacity(rects.len() * s * s);
                for y in 0..s {
                    for r in rects {
                        let start = (r[1] as usize + y) * width as usize + r[0] as usize;
                        out.extend_from_slice(&values[start..start + s]);
                    }
                }
                out
            }
        }
    }

    /// [`TruthLayout::gather`] of an image.
    pub fn gather_image(&self, img: &Rgba8Image) -> Rgba8Image {
        let (w, h) = self.mosaic_size(img.width, img.height);
        Rgba8Image {
            width: w,
            height: h,
            texels: self.gather(&img.texels, img.width),
        }
    }

    /// The mosaic's size for a `width x height` frame.
    pub fn mosaic_size(&self, width: u32, height: u32) -> (u32, u32) {
        match self {
            Self::Full => (width, height),
            Self::Tiles { size, rects } => (rects.len() as u32 * size, *size),
        }
    }

    /// The truth on this layout, lit by `lighting` (`None`: unlit): the full frame, or each tile traced alone
    /// ([`GroundTruthScene::render_region`]) and packed into the mosaic.
    pub fn render_truth(
        &self,
        scene: &GroundTruthScene,
        camera: &Camera,
        samples_per_axis: u32,
        lighting: Option<TruthLighting>,
    ) -> GroundTruthImage {
        let Self::Tiles { size, rects } = self else {
            return scene.render_lit(camera, samples_per_axis, lighting);
        };
        let tiles: Vec<GroundTruthImage> = rects
            .iter()
            .map(|&r| scene.render_region(camera, samples_per_axis, r, lighting))
            .collect();
        let s = *size as usize;
        let mut out = GroundTruthImage {
            width: rects.len() as u32 * size,
            height: *size,
            samples_per_axis: samples_per_axis.max(1),
            linear: Vec::new(),
            srgb: Rgba8Image {
                width: rects.len() as u32 * size,
                height: *size,
                texels: Vec::new(),
            },
            class: Vec::new(),
            tree_fraction: Vec::new(),
            rays: tiles.iter().map(|t| t.rays).sum(),
        };
        for y in 0..s {
            for t in &tiles {
                let row = y * s..(y + 1) * s;
                out.linear.extend_from_slice(&t.linear[row.clone()]);
                out.srgb
                    .texels
                    .extend_from_slice(&t.srgb.texels[row.clone()]);
                out.class.extend_from_slice(&t.class[row.clone()]);
                out.tree_fraction.extend_from_slice(&t.tree_fraction[row]);
            }
        }
        out
    }
}

/// Box-filters an `s·w x s·h` frame and its LOD-id buffer down to `w x h` (module docs): colour
/// averaged in linear light and encoded to sRGB8 once, the LOD id by the truth's majority rule.
///
/// # Panics
/// If the frame's size is not a multiple of `s` or the id buffer's length differs.
pub fn box_filter(color: &Rgba8Image, aux: &[u32], s: u32) -> (Rgba8Image, Vec<u32>) {
    let s = s.max(1);
    assert!(
        color.width.is_multiple_of(s) && color.height.is_multiple_of(s),
        "supersampled size"
    );
    assert_eq!(aux.len(), color.texels.len(), "id buffer size");
    let (w, h) = (color.width / s, color.height / s);
    let big_w = color.width as usize;
    let n = (s * s) as f32;
    let mut ids = Vec::with_capacity(w as usize * h as usize);
    let out = Rgba8Image::from_fn(w, h, |x, y| {
        let mut sum = [0.0f32; 3];
        for j in 0..s {
            for i in 0..s {
                let t = color.texels[(y * s + j) as usize * big_w + (x * s + i) as usize];
                for c in 0..3 {
                    sum[c] += srgb_to_linear(t[c]);
                }
            }
        }
        [
            linear_to_srgb(sum[0] / n),
            linear_to_srgb(sum[1] / n),
            linear_to_srgb(sum[2] / n),
            255,
        ]
    });
    for y in 0..h {
        for x in 0..w {
            let mut counts = [0u32; LOD_CLASSES.len()];
            for j in 0..s {
                for i in 0..s {
                    let id = aux[(y * s + j) as usize * big_w + (x * s + i) as usize];
                    // Every id the draw stage writes is a class (an unknown one is not counted).
                    if let Some(k) = LOD_CLASSES.iter().position(|&(c, _)| c == id) {
                        counts[k] += 1;
                    }
                }
            }
            let trees: u32 = LOD_CLASSES
                .iter()
                .zip(&counts)
                .filter(|((id, _), _)| is_tree_id(*id))
                .map(|(_, c)| c)
                .sum();
            let want_tree = 2 * trees >= s * s;
            let best = LOD_CLASSES
                .iter()
                .zip(&counts)
                .filter(|((id, _), _)| is_tree_id(*id) == want_tree)
                .fold(None::<(u32, u32)>, |best, (&(id, _), &c)| match best {
                    Some((_, bc)) if bc >= c => best,
                    _ => Some((id, c)),
                });
            ids.push(best.map_or(LOD_CLASSES[LOD_CLASSES.len() - 1].0, |b| b.0));
        }
    }
    (out, ids)
}

/// `camera` at `s` times its size in each direction: the same view, `s²` times the pixels.
pub fn supersampled(camera: &Camera, s: u32) -> Camera {
    let mut c = *camera;
    c.width *= s.max(1);
    c.height *= s.max(1);
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use forestlod_reference::draw::{
        LOD_ID_BACKGROUND, LOD_ID_BILLBOARD, LOD_ID_MESH, LOD_ID_TERRAIN,
    };

    #[test]
    fn tiles_are_deterministic_whole_spread_and_the_mosaic_holds_their_pixels() {
        let spec = TileSpec {
            size: 80,
            fraction: 0.125,
        };
        let a = TruthLayout::new(1280, 720, Some(spec));
        assert_eq!(a, TruthLayout::new(1280, 720, Some(spec)));
        let TruthLayout::Tiles { size, rects } = &a else {
            panic!("expected tiles")
        };
        assert_eq!((*size, rects.len()), (80, 18)); // round(144 / 8)
        assert!((a.fraction(1280, 720) - 0.125).abs() < 1e-12);
        // Spread: more than two tile rows and columns are sampled.
        let rows: std::collections::BTreeSet<_> = rects.iter().map(|r| r[1]).collect();
        let cols: std::collections::BTreeSet<_> = rects.iter().map(|r| r[0]).collect();
        assert!(rows.len() > 2 && cols.len() > 2, "{rows:?} {cols:?}");
        for r in rects {
            assert!(r[0] + r[2] <= 1280 && r[1] + r[3] <= 720);
        }
        // The mosaic of an index buffer holds exactly the tiles' pixels.
        let values: Vec<u32> = (0..1280 * 720).collect();
        let m = a.gather(&values, 1280);
        assert_eq!(m.len(), 18 * 80 * 80);
        let (mw, _) = a.mosaic_size(1280, 720);
        for (k, r) in rects.iter().enumerate() {
            for (x, y) in [(0, 0), (79, 0), (0, 79), (37, 51)] {
                let v = m[(y * mw + k as u32 * 80 + x) as usize];
                assert_eq!(v, (r[1] + y) * 1280 + r[0] + x);
            }
        }
        // No tiles, or all of them on a frame they divide: the full frame.
        assert_eq!(TruthLayout::new(1280, 720, None), TruthLayout::Full);
        let all = TileSpec {
            size: 80,
            fraction: 1.0,
        };
        assert_eq!(TruthLayout::new(1280, 720, Some(all)), TruthLayout::Full);
        assert!(matches!(
            TruthLayout::new(1280, 700, Some(all)),
            TruthLayout::Tiles { .. }
        ));
        assert!(spec.check().is_ok());
        assert!(TileSpec { size: 0, ..spec }.check().is_err());
        assert!(
            TileSpec {
                fraction: 0.0,
                ..spec
            }
            .check()
            .is_err()
        );
        assert!(
            TileSpec {
                fraction: f64::NAN,
                ..spec
            }
            .check()
            .is_err()
        );
    }

    #[test]
    fn box_filter_averages_in_linear_light_and_classes_by_the_truths_majority() {
        // 2x2 samples per pixel, 2x1 pixels.
        let color = Rgba8Image::from_fn(4, 2, |x, _| {
            if x < 2 {
                [0, 0, 0, 255]
            } else if x == 2 {
                [255, 255, 255, 255]
            } else {
                [0, 0, 0, 255]
            }
        });
        let aux = vec![
            LOD_ID_MESH,
            LOD_ID_BILLBOARD,
            LOD_ID_TERRAIN,
            LOD_ID_BACKGROUND,
            LOD_ID_TERRAIN,
            LOD_ID_BACKGROUND,
            LOD_ID_BACKGROUND,
            LOD_ID_BACKGROUND,
        ];
        let (img, ids) = box_filter(&color, &aux, 2);
        assert_eq!((img.width, img.height), (2, 1));
        assert_eq!(img.texels[0], [0, 0, 0, 255]);
        // Half white, half black in linear light is linear 0.5: sRGB 188, not 128.
        assert_eq!(img.texels[1], [188, 188, 188, 255]);
        // Pixel 0: two tree samples of four is a tree (the truth's rule), mesh first on a tie.
        assert_eq!(ids[0], LOD_ID_MESH);
        // Pixel 1: no tree; three sky samples beat one terrain.
        assert_eq!(ids[1], LOD_ID_BACKGROUND);
    }
}
