//! Render targets: a colour (RGBA8 sRGB), depth (`f32`) and auxiliary (`u32`) buffer of one size,
//! their clears, pixel masks, and the tiles a draw renders them in (module docs, "Primitive
//! order"). [`RenderTarget::draw`] itself is in `passes.rs`, with the draws.
//!
//! Invariants:
//! - every buffer is row-major from the top-left pixel, one entry per pixel; a side is in
//!   `1..=`[`MAX_TARGET_SIZE`] (the guard-band bound of `setup.rs` depends on it);
//! - a new target holds exactly its clear values, whatever buffers of a dropped target it
//!   reuses (`Spare`; `a_new_target_is_cleared_whatever_buffers_it_reuses`);
//! - tiles are disjoint and of even side ([`TILE_SIZE`], [`MASKED_TILE_SIZE`]), so a 2x2 quad
//!   never straddles two tiles; a tile's private copy (`TileBuffers`) is loaded from and stored
//!   back to exactly its rectangle;
//! - `MaskCounts` answers "does this rectangle hold a mask pixel" exactly
//!   (`mask_counts_answer_every_rectangle`).
//!
//! Depends on `types` and `color` (the clear colour's encoding).

use rayon::prelude::*;

use super::color::{clamp_color, encode};
use super::types::PixelRect;
use crate::texture::Rgba8Image;

/// Largest width or height of a [`RenderTarget`] (the limit `Camera::validate` enforces too).
pub const MAX_TARGET_SIZE: u32 = 16384;

/// Side of the square screen tiles that are rendered in parallel. Even, so that 2x2 quads never
/// straddle two tiles.
pub const TILE_SIZE: u32 = 64;
const _: () = assert!(TILE_SIZE.is_multiple_of(2));

/// Tile side of a draw whose every target is masked ([`RenderTarget::with_pixel_mask`]): the
/// parity's alternatives, masked to ~1 % of the pixels in small clusters (issue 14).
pub const MASKED_TILE_SIZE: u32 = 16;
const _: () = assert!(MASKED_TILE_SIZE.is_multiple_of(2));

/// Values a [`RenderTarget`] is cleared to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClearValues {
    /// Linear-light RGBA, straight alpha (encoded to sRGB8 like a clear of an `Rgba8UnormSrgb`
    /// attachment).
    pub color: [f32; 4],
    /// Depth (1.0: the far plane, so LESS accepts anything drawn).
    pub depth: f32,
    /// Auxiliary id.
    pub aux: u32,
}

impl ClearValues {
    /// The colour as the target stores it (sRGB8, clamped).
    fn color_code(&self) -> [u8; 4] {
        encode(clamp_color(self.color))
    }
}

impl Default for ClearValues {
    /// Transparent black, depth 1.0, id 0.
    fn default() -> Self {
        Self {
            color: [0.0; 4],
            depth: 1.0,
            aux: 0,
        }
    }
}

/// The buffers of the last dropped [`RenderTarget`] of at most [`Spare::MAX_BYTES`], which the
/// next [`RenderTarget::new`] takes and clears (issue 14, session 11). What it saves: a new
/// 1280x720 target is 11 MB of fresh pages, and faulting them in was about a third of a frame
/// with no trees (the `far` camera: sky and ground, 5-6 ms); a frame loop (a sweep, a benchmark)
/// drops one target before it makes the next. What it costs: at most one target's buffers stay
/// allocated after it is dropped ([`release_spare_buffers`] frees them). It cannot change a
/// pixel: `new` sets every value through `clear`.
struct Spare;

/// A target's colour, depth and auxiliary buffers.
type Buffers = (Vec<[u8; 4]>, Vec<f32>, Vec<u32>);

static SPARE: std::sync::Mutex<Option<Buffers>> = std::sync::Mutex::new(None);

impl Spare {
    /// Largest target kept: 1920x1080 and smaller (a supersampled truth frame is not kept).
    const MAX_BYTES: usize = 32 << 20;

    fn take() -> Option<Buffers> {
        SPARE.lock().unwrap_or_else(|e| e.into_inner()).take()
    }

    fn keep(buffers: Buffers) {
        let bytes = buffers.0.capacity() * 4 + buffers.1.capacity() * 4 + buffers.2.capacity() * 4;
        if bytes > 0 && bytes <= Self::MAX_BYTES {
            *SPARE.lock().unwrap_or_else(|e| e.into_inner()) = Some(buffers);
        }
    }
}

/// Frees the buffers a dropped [`RenderTarget`] left for the next one (see [`RenderTarget::new`]):
/// for a caller about to measure or hand back its resident memory.
pub fn release_spare_buffers() {
    drop(Spare::take());
}

impl Drop for RenderTarget {
    fn drop(&mut self) {
        Spare::keep((
            std::mem::take(&mut self.color),
            std::mem::take(&mut self.depth),
            std::mem::take(&mut self.aux),
        ));
    }
}

/// A colour (RGBA8 sRGB), depth (`f32`) and auxiliary (`u32`) target of one size, drawn into by any
/// number of [`RenderTarget::draw`] calls. All buffers are row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderTarget {
    pub(super) width: u32,
    pub(super) height: u32,
    color: Vec<[u8; 4]>,
    depth: Vec<f32>,
    aux: Vec<u32>,
    /// [`RenderTarget::with_pixel_mask`]: the only pixels draws may touch (row-major); `None`,
    /// every pixel.
    pub(super) mask: Option<Vec<bool>>,
}

impl RenderTarget {
    /// A `width` x `height` target cleared to `clear`.
    ///
    /// # Panics
    /// If a side is 0 or larger than [`MAX_TARGET_SIZE`] (the guard band bound depends on it).
    pub fn new(width: u32, height: u32, clear: ClearValues) -> Self {
        assert!(
            (1..=MAX_TARGET_SIZE).contains(&width) && (1..=MAX_TARGET_SIZE).contains(&height),
            "render target {width}x{height}: expected 1..={MAX_TARGET_SIZE} pixels per side"
        );
        let n = width as usize * height as usize;
        // A dropped target's buffers when there are some (`Spare`), else new ones; every value
        // is written once, the clear value, so which memory it is changes nothing.
        let (color, depth, aux) = Spare::take().unwrap_or_default();
        // The reused part is filled in parallel, in pieces of `FILL_CHUNK` values (a 1280x720
        // target's three buffers are 11 MB; issue 14, session 12), the rest as it is allocated.
        fn filled<T: Copy + Send + Sync>(mut v: Vec<T>, n: usize, value: T) -> Vec<T> {
            const FILL_CHUNK: usize = 1 << 16;
            v.truncate(n);
            v.par_chunks_mut(FILL_CHUNK).for_each(|c| c.fill(value));
            v.resize(n, value);
            v
        }
        Self {
            width,
            height,
            color: filled(color, n, clear.color_code()),
            depth: filled(depth, n, clear.depth),
            aux: filled(aux, n, clear.aux),
            mask: None,
        }
    }

    /// Restricts every later draw to the pixels where `mask` (row-major, one entry per pixel) is
    /// true: a sample outside it counts as uncovered, so it is never tested, shaded or written,
    /// and a quad or tile with no pixel inside is skipped. A pixel inside receives exactly the
    /// fragments, in the same order, with the same quad derivatives (helpers are still
    /// interpolated) as without a mask, so its colour, depth and id are **bit-identical** to an
    /// unmasked draw's; pixels outside keep their clear values. What this is for: the parity
    /// comparison reads its alternative frames (cutoff moved) only at the few pixels where the GPU
    /// and the reference disagree, so those frames need only those pixels (issue 14: 6 of the main
    /// job's 7 reference frames). The work counters ([`DrawStats`]) count only the masked pixels.
    ///
    /// # Panics
    /// If `mask` does not have one entry per pixel.
    pub fn with_pixel_mask(mut self, mask: Vec<bool>) -> Self {
        assert_eq!(
            mask.len(),
            self.width as usize * self.height as usize,
            "pixel mask length"
        );
        self.mask = Some(mask);
        self
    }

    /// Resets every pixel of every buffer.
    pub fn clear(&mut self, clear: ClearValues) {
        self.color.fill(clear.color_code());
        self.depth.fill(clear.depth);
        self.aux.fill(clear.aux);
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The colour, depth and auxiliary buffers, moved out (no copy).
    pub fn into_buffers(mut self) -> (Vec<[u8; 4]>, Vec<f32>, Vec<u32>) {
        (
            std::mem::take(&mut self.color),
            std::mem::take(&mut self.depth),
            std::mem::take(&mut self.aux),
        )
    }

    /// The colour buffer: sRGB-encoded RGB, linear alpha.
    pub fn color(&self) -> &[[u8; 4]] {
        &self.color
    }

    /// The depth buffer.
    pub fn depth(&self) -> &[f32] {
        &self.depth
    }

    /// The auxiliary id buffer.
    pub fn aux(&self) -> &[u32] {
        &self.aux
    }

    /// The colour buffer as an image (ready for PNG encoding).
    pub fn color_image(&self) -> Rgba8Image {
        Rgba8Image {
            width: self.width,
            height: self.height,
            texels: self.color.clone(),
        }
    }

    /// Screen tiles, row by row.
    pub(super) fn tiles(&self, size: u32) -> Vec<PixelRect> {
        let mut tiles = Vec::new();
        for y0 in (0..self.height).step_by(size as usize) {
            for x0 in (0..self.width).step_by(size as usize) {
                tiles.push(PixelRect {
                    x0,
                    y0,
                    x1: (x0 + size).min(self.width),
                    y1: (y0 + size).min(self.height),
                });
            }
        }
        tiles
    }

    pub(super) fn load_tile(&self, rect: PixelRect) -> TileBuffers {
        let n = rect.width() as usize * rect.height() as usize;
        let mut b = TileBuffers {
            rect,
            color: Vec::with_capacity(n),
            depth: Vec::with_capacity(n),
            aux: Vec::with_capacity(n),
            mask: self.mask.as_ref().map(|_| Vec::with_capacity(n)),
        };
        for y in rect.y0..rect.y1 {
            let row = self.index(rect.x0, y)..self.index(rect.x1, y);
            b.color.extend_from_slice(&self.color[row.clone()]);
            b.depth.extend_from_slice(&self.depth[row.clone()]);
            if let (Some(local), Some(mask)) = (&mut b.mask, &self.mask) {
                local.extend_from_slice(&mask[row.clone()]);
            }
            b.aux.extend_from_slice(&self.aux[row]);
        }
        b
    }

    /// Whether a draw may touch any pixel of `rect` (always, without a pixel mask).
    pub(super) fn tile_has_pixels(&self, rect: PixelRect) -> bool {
        self.mask.as_ref().is_none_or(|mask| {
            (rect.y0..rect.y1)
                .any(|y| mask[self.index(rect.x0, y)..self.index(rect.x1, y)].contains(&true))
        })
    }

    pub(super) fn store_tile(&mut self, b: &TileBuffers) {
        let w = b.rect.width() as usize;
        for (j, y) in (b.rect.y0..b.rect.y1).enumerate() {
            let row = self.index(b.rect.x0, y)..self.index(b.rect.x1, y);
            let local = j * w..(j + 1) * w;
            self.color[row.clone()].copy_from_slice(&b.color[local.clone()]);
            self.depth[row.clone()].copy_from_slice(&b.depth[local.clone()]);
            self.aux[row].copy_from_slice(&b.aux[local]);
        }
    }

    fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }
}

/// How many pixels of a pixel mask lie in any rectangle, in four lookups: the mask's summed-area
/// table, `(width + 1) x (height + 1)` counts, `sums[y][x]` the mask pixels above and left of
/// `(x, y)`. [`draw_passes`] uses it to leave out, per tile, the triangles whose box meets no
/// pixel of a masked target (issue 14), and [`crate::draw`] to leave out whole trees.
pub(crate) struct MaskCounts {
    stride: usize,
    sums: Vec<u32>,
}

impl MaskCounts {
    pub(crate) fn new(mask: &[bool], width: u32, height: u32) -> Self {
        let (w, h) = (width as usize, height as usize);
        let stride = w + 1;
        let mut sums = vec![0u32; stride * (h + 1)];
        for y in 0..h {
            let mut row = 0u32;
            for x in 0..w {
                row += u32::from(mask[y * w + x]);
                sums[(y + 1) * stride + x + 1] = sums[y * stride + x + 1] + row;
            }
        }
        Self { stride, sums }
    }

    /// Whether `r` holds a pixel of the mask.
    pub(super) fn any(&self, r: &PixelRect) -> bool {
        let at = |x: u32, y: u32| self.sums[y as usize * self.stride + x as usize];
        at(r.x1, r.y1) + at(r.x0, r.y0) > at(r.x0, r.y1) + at(r.x1, r.y0)
    }

    /// Whether the half-open rectangle `[x0, x1) x [y0, y1)` (within the mask) holds a pixel of
    /// the mask; an empty rectangle holds none.
    pub(crate) fn any_in(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> bool {
        x0 < x1 && y0 < y1 && self.any(&PixelRect { x0, y0, x1, y1 })
    }
}

/// A tile's private copy of its pixels.
pub(super) struct TileBuffers {
    pub(super) rect: PixelRect,
    pub(super) color: Vec<[u8; 4]>,
    pub(super) depth: Vec<f32>,
    pub(super) aux: Vec<u32>,
    /// The target's pixel mask over this tile, if it has one.
    pub(super) mask: Option<Vec<bool>>,
}

#[cfg(test)]
mod tests {
    use super::super::types::{DrawState, Fragment, FragmentOutput, Vertex};
    use super::*;

    /// A target made after others were drawn into and dropped (their buffers are kept for the
    /// next target, `Spare`) holds exactly its clear values, at its own size, whichever
    /// buffers it got.
    #[test]
    fn a_new_target_is_cleared_whatever_buffers_it_reuses() {
        let tri = [
            Vertex::new([-1.0, -1.0, 0.25, 1.0], [0.0]),
            Vertex::new([3.0, -1.0, 0.25, 1.0], [0.0]),
            Vertex::new([-1.0, 3.0, 0.25, 1.0], [0.0]),
        ];
        let shader = |_: &Fragment<1>| {
            Some(FragmentOutput {
                color: [0.9, 0.1, 0.4, 1.0],
                id: 77,
                depth: None,
            })
        };
        let clear = ClearValues {
            color: [0.2, 0.3, 0.4, 1.0],
            depth: 0.75,
            aux: 5,
        };
        // (used target's size, new target's size): reused buffers longer and shorter than the
        // new target's, and longer than one parallel fill piece (65,536 values).
        for ((uw, uh), (w, h)) in [
            ((43, 30), (40, 30)),
            ((43, 30), (40, 30)),
            ((67, 48), (64, 48)),
            ((19, 8), (16, 8)),
            ((43, 30), (40, 30)),
            ((303, 250), (300, 250)),
            ((40, 30), (300, 250)),
            ((16, 8), (300, 250)),
        ] {
            let mut used = RenderTarget::new(uw, uh, ClearValues::default());
            used.draw(&[tri], &shader, &DrawState::OPAQUE);
            assert!(used.aux().iter().all(|&a| a == 77));
            drop(used);
            let fresh = RenderTarget::new(w, h, clear);
            let n = (w * h) as usize;
            assert_eq!(fresh.color().len(), n);
            assert_eq!(fresh.depth().len(), n);
            assert_eq!(fresh.aux().len(), n);
            let c = encode(clamp_color(clear.color));
            assert!(fresh.color().iter().all(|&p| p == c), "{w}x{h}");
            assert!(fresh.depth().iter().all(|&d| d == 0.75), "{w}x{h}");
            assert!(fresh.aux().iter().all(|&a| a == 5), "{w}x{h}");
        }
    }

    /// The summed-area table counts every rectangle of a small mask right (all of them).
    #[test]
    fn mask_counts_answer_every_rectangle() {
        let (w, h) = (13u32, 9u32);
        let mask: Vec<bool> = (0..w * h).map(|i| (i * 7919) % 29 < 2).collect();
        let counts = MaskCounts::new(&mask, w, h);
        for (y0, y1) in (0..h).flat_map(|a| (a + 1..=h).map(move |b| (a, b))) {
            for (x0, x1) in (0..w).flat_map(|a| (a + 1..=w).map(move |b| (a, b))) {
                let r = PixelRect { x0, y0, x1, y1 };
                let brute = (y0..y1).any(|y| (x0..x1).any(|x| mask[(y * w + x) as usize]));
                assert_eq!(counts.any(&r), brute, "{r:?}");
            }
        }
    }
}
