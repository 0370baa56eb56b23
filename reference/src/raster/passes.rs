//! Draw orchestration: [`RenderTarget::draw`], [`draw_passes`] and [`draw_passes_streamed`].
//! Chunks of [`SETUP_CHUNK`] triangles are set up in parallel runs of `SETUP_RUN` (collected in
//! order) and binned by pixel box; the targets are grouped by equal pixel masks (a masked
//! group's bins filtered by its mask); each group's tiles are rendered in parallel, one tile per
//! job, into private copies of their pixels that are written back after the last chunk.
//!
//! Invariants:
//! - buffers and counters are bit-identical for any thread count: tiles are disjoint and each
//!   renders its bin in submission order, chunk after chunk and piece after piece;
//! - a triangle's primitive id is its index in the concatenation of a stream's pieces;
//! - each target of [`draw_passes`] ends with exactly the buffers and counters of its own
//!   [`RenderTarget::draw`] with its pass's shader.
//!
//! The top of the rasterizer's files: it uses all the others, and none uses it.

use rayon::prelude::*;

use super::setup::{SetupCounts, SetupTriangle, Viewport, setup_primitive};
use super::target::{MASKED_TILE_SIZE, MaskCounts, RenderTarget, TILE_SIZE, TileBuffers};
use super::tiles::{FragmentCounts, masked_pixels, render_tile};
use super::types::{
    DrawState, DrawStats, Fragment, FragmentOutput, FragmentShader, MAX_PASSES, PassSet,
    PassShader, PixelRect, Triangle,
};

/// Triangles set up per chunk of [`draw_passes`]: bounds the setup's memory (a setup triangle is
/// about 250 bytes; a million-triangle frame set up at once held over 500 MB, issue 14) without
/// changing any pixel: chunks go in submission order and each tile renders a chunk's triangles in
/// order before the next chunk's, so every pixel still merges its fragments in submission order.
pub const SETUP_CHUNK: usize = 1 << 16;

/// Triangles per parallel work item of the setup (one output vector each).
const SETUP_RUN: usize = 256;

/// One [`FragmentShader`] as the only pass of a draw ([`RenderTarget::draw`]).
struct One<'a, S: ?Sized>(&'a S);

impl<const N: usize, S> PassShader<N> for One<'_, S>
where
    S: FragmentShader<N> + ?Sized,
{
    #[inline(always)]
    fn shade_passes(
        &self,
        fragment: &Fragment<N>,
        passes: PassSet,
    ) -> Option<(FragmentOutput, PassSet)> {
        self.0.shade(fragment).map(|out| (out, passes))
    }
}

/// Draws one triangle list into several targets of one size (the passes of `shader`, pass `p`
/// into `targets[p]`), sharing the clipping, setup and binning (they depend only on the
/// triangles, the size and `state`) and, for the targets with equal pixel masks, the walk over
/// the quads and everything before the shader (coverage, early depth test, barycentrics,
/// varyings): each target's buffers and counters are exactly those of its own
/// [`RenderTarget::draw`] with its pass's shader. What it is for: the reference frames that
/// differ only in a shader constant (the parity's alternative frames, cutoff moved) cost one
/// setup and one walk, not one each (issue 14).
///
/// Order of work: per chunk of [`SETUP_CHUNK`] triangles, setup in parallel (collected in order),
/// bin by bounding box, then per group of targets with equal masks render every tile (tiles in
/// parallel, each into a private copy of its pixels per target, written back in tile order). A
/// masked group's tiles list only the triangles that cover a pixel of its mask there (the quad
/// loop's own coverage test), and a draw whose every target is masked uses tiles of
/// [`MASKED_TILE_SIZE`]: neither changes a pixel or a counter.
///
/// # Panics
/// If there are more than `u32::MAX` triangles (primitive ids are `u32`, as in Vulkan), more
/// than [`MAX_PASSES`] targets, or the targets differ in size.
pub fn draw_passes<const N: usize, S>(
    targets: &mut [&mut RenderTarget],
    shader: &S,
    triangles: &[Triangle<N>],
    state: &DrawState,
) -> Vec<DrawStats>
where
    S: PassShader<N> + ?Sized,
{
    assert!(
        u32::try_from(triangles.len()).is_ok(),
        "a draw holds at most u32::MAX triangles"
    );
    draw_passes_streamed(targets, shader, &mut SliceSource(triangles), state)
}

/// A triangle list handed to a draw a piece at a time ([`draw_passes_streamed`]), so that the
/// whole list never has to exist at once: the tree draw's vertex stage fills one piece while the
/// previous one is already drawn (issue 14, session 11: a `stress` frame's 10.7 M triangles
/// were 1.15 GB, and allocating, faulting in and copying them was a third of the frame).
pub trait TriangleSource<const N: usize> {
    /// The next triangles in submission order (any number, possibly none), or `None` when the
    /// list has ended. The slice lives until the next call.
    fn next_triangles(&mut self) -> Option<&[Triangle<N>]>;
}

/// A slice as a [`TriangleSource`], in pieces of [`SETUP_CHUNK`].
struct SliceSource<'a, const N: usize>(&'a [Triangle<N>]);

impl<const N: usize> TriangleSource<N> for SliceSource<'_, N> {
    fn next_triangles(&mut self) -> Option<&[Triangle<N>]> {
        if self.0.is_empty() {
            return None;
        }
        let (piece, rest) = self.0.split_at(self.0.len().min(SETUP_CHUNK));
        self.0 = rest;
        Some(piece)
    }
}

/// [`draw_passes`] of the triangles `source` hands out, in its order: the same buffers and
/// counters as [`draw_passes`] of their concatenation, whatever the pieces' sizes. Why: the
/// pieces are set up, binned and rendered one after the other, each tile rendering a piece's
/// triangles in order before the next piece's, so every pixel still merges its fragments in
/// submission order, and a triangle's primitive id is its index in the concatenation. Pieces
/// longer than [`SETUP_CHUNK`] are drawn in chunks of that size.
///
/// # Panics
/// As [`draw_passes`]; the `u32::MAX` limit is checked as the pieces arrive.
pub fn draw_passes_streamed<const N: usize, S>(
    targets: &mut [&mut RenderTarget],
    shader: &S,
    source: &mut dyn TriangleSource<N>,
    state: &DrawState,
) -> Vec<DrawStats>
where
    S: PassShader<N> + ?Sized,
{
    assert!(
        targets.len() <= MAX_PASSES,
        "a draw has at most {MAX_PASSES} passes"
    );
    let mut stats = vec![DrawStats::default(); targets.len()];
    let Some(first) = targets.first() else {
        return stats;
    };
    let (width, height) = (first.width, first.height);
    assert!(
        targets
            .iter()
            .all(|t| (t.width, t.height) == (width, height)),
        "draw_passes: targets differ in size"
    );
    let viewport = Viewport::new(width, height);
    // Draws whose every pass is masked use smaller tiles (issue 14): a masked tile's quad loop
    // still walks each listed triangle's whole box within the tile, so the tile bounds that walk
    // around the few masked pixels. Tiles are disjoint and keep submission order, so the tile
    // size changes no pixel and no counter.
    let tile_size = if targets.iter().all(|t| t.mask.is_some()) {
        MASKED_TILE_SIZE
    } else {
        TILE_SIZE
    };
    let tiles = first.tiles(tile_size);
    let tiles_x = width.div_ceil(tile_size) as usize;
    // The targets grouped by equal pixel masks, in pass order: a group walks its triangles'
    // quads once for all its targets (the coverage test, the only place a mask enters, is the
    // same for all of them). A masked group's triangles per tile are also filtered by its mask:
    // a triangle whose box meets no pixel of the mask inside a tile writes nothing and counts
    // nothing there (every pixel of the quad loop fails the mask), so it is left out of that
    // tile's list. The parity's six alternative frames, masked to ~1 % of the pixels, so skip
    // ~99 % of the tile work.
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for p in 0..targets.len() {
        match groups
            .iter_mut()
            .find(|g| targets[g[0]].mask == targets[p].mask)
        {
            Some(g) => g.push(p),
            None => groups.push(vec![p]),
        }
    }
    let mask_counts: Vec<Option<MaskCounts>> = groups
        .iter()
        .map(|g| {
            let mask = targets[g[0]].mask.as_ref()?;
            Some(MaskCounts::new(mask, width, height))
        })
        .collect();
    // Per group, per tile: whether the mask leaves it any pixel, and its targets' private copies
    // of its pixels, loaded when a triangle first reaches it and written back after the last
    // chunk (one copy each way per draw, not per chunk).
    let live: Vec<Vec<bool>> = groups
        .iter()
        .map(|g| {
            let target = &targets[g[0]];
            tiles.iter().map(|r| target.tile_has_pixels(*r)).collect()
        })
        .collect();
    let mut tile_buffers: Vec<Vec<Option<Vec<TileBuffers>>>> = groups
        .iter()
        .map(|_| tiles.iter().map(|_| None).collect())
        .collect();
    let reads: Vec<&RenderTarget> = targets.iter().map(|t| &**t).collect();
    // Triangles submitted before the current chunk (the first one's primitive id).
    let mut submitted = 0usize;
    while let Some(piece) = source.next_triangles() {
        for chunk in piece.chunks(SETUP_CHUNK) {
            let base = submitted;
            submitted += chunk.len();
            assert!(
                u32::try_from(submitted).is_ok(),
                "a draw holds at most u32::MAX triangles"
            );
            for s in &mut stats {
                s.triangles_in += chunk.len() as u64;
            }
            // Clip, project, snap and set up, in parallel over runs of triangles (one output vector
            // per run, not per triangle), concatenated in submission order.
            let runs: Vec<(SetupCounts, Vec<SetupTriangle<N>>)> = chunk
                .par_chunks(SETUP_RUN)
                .enumerate()
                .map(|(r, run)| {
                    let mut out = Vec::with_capacity(run.len());
                    let mut counts = SetupCounts::default();
                    for (i, tri) in run.iter().enumerate() {
                        let id = (base + r * SETUP_RUN + i) as u32;
                        let c = setup_primitive(id, tri, &viewport, state, &mut out);
                        counts.clipped += c.clipped;
                        counts.rasterized += c.rasterized;
                    }
                    (counts, out)
                })
                .collect();
            // The set-up triangles in submission order, as references into the runs' vectors
            // (session 12, issue 14: concatenating the runs copied 16 MB per chunk on one thread).
            let mut setup: Vec<&SetupTriangle<N>> =
                Vec::with_capacity(runs.iter().map(|(_, t)| t.len()).sum());
            let (mut clipped, mut rasterized) = (0, 0);
            for (counts, tris) in &runs {
                clipped += counts.clipped;
                rasterized += counts.rasterized;
                setup.extend(tris);
            }
            for s in &mut stats {
                s.triangles_clipped += clipped;
                s.triangles_rasterized += rasterized;
            }
            // Bin by bounding box; each bin lists setup indices in increasing, i.e. submission, order.
            let mut bins: Vec<Vec<u32>> = vec![Vec::new(); tiles.len()];
            for (i, tri) in setup.iter().enumerate() {
                let Some(b) = tri.bbox else { continue };
                for ty in (b.y0 / tile_size)..=((b.y1 - 1) / tile_size) {
                    for tx in (b.x0 / tile_size)..=((b.x1 - 1) / tile_size) {
                        bins[ty as usize * tiles_x + tx as usize].push(i as u32);
                    }
                }
            }
            for (((group, counts), live), buffers) in groups
                .iter()
                .zip(&mask_counts)
                .zip(&live)
                .zip(&mut tile_buffers)
            {
                // A masked group's triangles per tile that cover a pixel of the mask there: a box
                // meeting the mask (four lookups), then the same coverage test as the quad loop's at
                // each masked pixel of the box (`edges` equals the quad loop's stepped edge
                // functions bit for bit).
                // The masked pixels are visited from the tile's list of them where that is shorter
                // than the box (the same pixels; `any` does not depend on the order).
                let masked_bins: Option<Vec<Vec<u32>>> = counts.as_ref().map(|counts| {
                    let mask = reads[group[0]].mask.as_deref().expect("a masked group");
                    let covers_mask =
                        |tri: &SetupTriangle<N>, r: &PixelRect, list: &[(u32, u32)]| {
                            if list.len() < r.width() as usize * r.height() as usize {
                                return list.iter().any(|&(x, y)| {
                                    r.contains(x, y) && tri.covers(&tri.edges(x, y))
                                });
                            }
                            (r.y0..r.y1).any(|y| {
                                (r.x0..r.x1).any(|x| {
                                    mask[y as usize * width as usize + x as usize]
                                        && tri.covers(&tri.edges(x, y))
                                })
                            })
                        };
                    tiles
                        .par_iter()
                        .zip(bins.par_iter())
                        .with_max_len(1)
                        .map(|(rect, bin)| {
                            if bin.is_empty() || !counts.any(rect) {
                                return Vec::new();
                            }
                            let list = masked_pixels(*rect, mask, width);
                            bin.iter()
                                .copied()
                                .filter(|&i| {
                                    let tri = setup[i as usize];
                                    tri.bbox.and_then(|b| b.intersect(rect)).is_some_and(|r| {
                                        counts.any(&r) && covers_mask(tri, &r, &list)
                                    })
                                })
                                .collect()
                        })
                        .collect()
                });
                let bins = masked_bins.as_ref().unwrap_or(&bins);
                // Render tiles in parallel, each into its targets' private copies of its pixels.
                let counts: Vec<Vec<FragmentCounts>> = tiles
                    .par_iter()
                    .zip(bins.par_iter())
                    .zip(buffers.par_iter_mut())
                    .zip(live.par_iter())
                    .with_max_len(1)
                    .map(|(((rect, bin), buffers), &live)| {
                        if bin.is_empty() || !live {
                            return Vec::new();
                        }
                        let buffers = buffers.get_or_insert_with(|| {
                            group.iter().map(|&p| reads[p].load_tile(*rect)).collect()
                        });
                        // A group of one target takes a copy of the walk compiled for one (no
                        // loop over targets per pixel; part of undoing a 9-13 % regression of a
                        // plain frame in this function's first form, profile README session 9).
                        if group.len() == 1 {
                            render_tile::<N, S, true>(buffers, group, bin, &setup, shader, state)
                        } else {
                            render_tile::<N, S, false>(buffers, group, bin, &setup, shader, state)
                        }
                    })
                    .collect();
                for tile in counts {
                    for (c, &p) in tile.iter().zip(group) {
                        stats[p].fragments_covered += c.covered;
                        stats[p].fragments_shaded += c.shaded;
                        stats[p].fragments_written += c.written;
                    }
                }
            }
        }
    }
    drop(reads);
    // Write back (tiles are disjoint).
    for (group, buffers) in groups.iter().zip(tile_buffers) {
        for tile in buffers.into_iter().flatten() {
            for (&p, b) in group.iter().zip(&tile) {
                targets[p].store_tile(b);
            }
        }
    }
    stats
}

impl RenderTarget {
    /// Draws a triangle list (module docs for every step) and returns its work counters.
    ///
    /// # Panics
    /// If there are more than `u32::MAX` triangles (primitive ids are `u32`, as in Vulkan).
    pub fn draw<const N: usize, S>(
        &mut self,
        triangles: &[Triangle<N>],
        shader: &S,
        state: &DrawState,
    ) -> DrawStats
    where
        S: FragmentShader<N> + ?Sized,
    {
        draw_passes(&mut [self], &One(shader), triangles, state)[0]
    }
}

#[cfg(test)]
mod tests {
    use super::super::target::ClearValues;
    use super::super::test_util::unit_random;
    use super::super::types::Vertex;
    use super::*;

    /// `n` small triangles scattered over the viewport and a little beyond it, each at one
    /// depth, of side up to `size` in NDC, varying `varying(i)` for triangle `i` (xorshift from
    /// `seed`).
    fn scattered_triangles(
        n: usize,
        size: f32,
        seed: u64,
        varying: impl Fn(usize, f32) -> f32,
    ) -> Vec<Triangle<1>> {
        let mut seed = seed;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        (0..n)
            .map(|i| {
                let (cx, cy) = (next() * 2.2 - 1.1, next() * 2.2 - 1.1);
                let z = next();
                [0, 1, 2].map(|_| {
                    let p = [cx + next() * size, cy + next() * size, z, 1.0];
                    Vertex::new(p, [varying(i, next())])
                })
            })
            .collect()
    }

    /// Asserts that two targets hold the same colour, id and depth bits.
    fn assert_same_buffers(a: &RenderTarget, b: &RenderTarget) {
        assert_eq!(a.color(), b.color());
        assert_eq!(a.aux(), b.aux());
        let bits = |t: &RenderTarget| t.depth().iter().map(|d| d.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(a), bits(b));
    }

    /// One draw of more than two setup chunks equals the same triangles drawn as consecutive
    /// draws of one chunk each (the shader ignores the primitive id, which restarts per draw):
    /// the per-draw tile buffers carry every chunk's writes to the next, in submission order.
    #[test]
    fn a_draw_across_setup_chunks_equals_consecutive_draws() {
        let (w, h) = (72, 40);
        let n = 2 * SETUP_CHUNK + 1000;
        let tris = scattered_triangles(n, 0.15, 0x2545_f491_4f6c_dd1d, |i, _| {
            (i % 251) as f32 / 251.0
        });
        let shader = |f: &Fragment<1>| {
            (f.varyings[0] > 0.1).then_some(FragmentOutput {
                color: [f.varyings[0], 1.0 - f.varyings[0], 0.5, 0.6],
                id: (f.varyings[0] * 251.0) as u32,
                depth: None,
            })
        };
        let state = DrawState {
            depth_write: true,
            ..DrawState::TRANSPARENT
        };
        let mut one = RenderTarget::new(w, h, ClearValues::default());
        let s1 = one.draw(&tris, &shader, &state);
        let mut parts = RenderTarget::new(w, h, ClearValues::default());
        let mut s2 = DrawStats::default();
        for chunk in tris.chunks(SETUP_CHUNK) {
            s2 += parts.draw(chunk, &shader, &state);
        }
        assert_eq!(s1, s2);
        assert!(s1.fragments_written > 10_000, "{s1:?}");
        assert_same_buffers(&one, &parts);
    }

    /// A list handed out in uneven pieces (empty ones, one triangle, more than a setup chunk)
    /// draws exactly what one draw of the whole list draws, primitive ids included: a piece's
    /// first id continues the previous piece's count (issue 14, session 11).
    #[test]
    fn a_streamed_draw_in_uneven_pieces_equals_one_draw() {
        struct Pieces<'a> {
            rest: &'a [Triangle<1>],
            sizes: std::vec::IntoIter<usize>,
        }
        impl TriangleSource<1> for Pieces<'_> {
            fn next_triangles(&mut self) -> Option<&[Triangle<1>]> {
                let n = self.sizes.next().unwrap_or(self.rest.len());
                if n == 0 && self.rest.is_empty() {
                    return None;
                }
                let (piece, rest) = self.rest.split_at(n.min(self.rest.len()));
                self.rest = rest;
                Some(piece)
            }
        }
        let (w, h) = (64, 48);
        let n = SETUP_CHUNK + 3000;
        let tris = scattered_triangles(n, 0.2, 0x9e37_79b9_7f4a_7c15, |_, r| r);
        // The id is the primitive id: a piece restarting the count would show.
        let shader = |f: &Fragment<1>| {
            (f.varyings[0] > 0.2).then_some(FragmentOutput {
                color: [f.varyings[0], 0.3, 0.5, 0.7],
                id: f.primitive_id,
                depth: None,
            })
        };
        let state = DrawState {
            depth_write: true,
            ..DrawState::TRANSPARENT
        };
        let mut one = RenderTarget::new(w, h, ClearValues::default());
        let s1 = one.draw(&tris, &shader, &state);
        let mut streamed = RenderTarget::new(w, h, ClearValues::default());
        let mut source = Pieces {
            rest: &tris,
            sizes: vec![0, 1, 0, 7, SETUP_CHUNK + 5, 0, 1000].into_iter(),
        };
        let s2 = draw_passes_streamed(&mut [&mut streamed], &One(&shader), &mut source, &state)[0];
        assert_eq!(s1, s2);
        assert_eq!(s1.triangles_in, n as u64);
        assert!(s1.fragments_written > 10_000, "{s1:?}");
        assert!(
            one.aux().iter().any(|&id| id as usize > SETUP_CHUNK + 13),
            "ids from the last pieces are visible"
        );
        assert_same_buffers(&one, &streamed);
    }

    /// Passes that keep a fragment when its first varying reaches their cutoff; the output does
    /// not depend on the cutoff (as the tree shader's alpha test), so it is `shader(cut)`'s.
    struct Cutoffs<'a, F>(&'a [f32], F);

    impl<F: Fn(&Fragment<1>) -> FragmentOutput + Sync> PassShader<1> for Cutoffs<'_, F> {
        fn shade_passes(
            &self,
            f: &Fragment<1>,
            passes: PassSet,
        ) -> Option<(FragmentOutput, PassSet)> {
            let kept = (0..self.0.len())
                .filter(|&p| passes & (1 << p) != 0 && f.varyings[0] >= self.0[p])
                .fold(0, |set, p| set | (1 << p));
            (kept != 0).then(|| (self.1(f), kept))
        }
    }

    /// A masked draw writes exactly the unmasked draw's values inside the mask and nothing
    /// outside it; `draw_passes` gives each target what its own `draw` gives.
    #[test]
    fn masked_and_shared_draws_equal_plain_draws() {
        let (w, h) = (96, 80);
        let clear = ClearValues {
            color: [0.2, 0.3, 0.4, 1.0],
            depth: 1.0,
            aux: 0,
        };
        let mut next = unit_random(12345u64);
        let tris: Vec<Triangle<1>> = (0..300)
            .map(|i| {
                [0, 1, 2].map(|_| {
                    Vertex::new(
                        [next() * 2.2 - 1.1, next() * 2.2 - 1.1, next(), 1.0],
                        [i as f32 / 300.0],
                    )
                })
            })
            .collect();
        let shader = |cut: f32| {
            move |f: &Fragment<1>| {
                (f.varyings[0] >= cut).then_some(FragmentOutput {
                    color: [f.varyings[0], 0.5, 1.0 - f.varyings[0], 0.7],
                    id: f.primitive_id,
                    depth: None,
                })
            }
        };
        let state = DrawState::TRANSPARENT;
        let (s1, s2) = (shader(0.2), shader(0.6));
        let mut plain1 = RenderTarget::new(w, h, clear);
        let st1 = plain1.draw(&tris, &s1, &state);
        let mut plain2 = RenderTarget::new(w, h, clear);
        let st2 = plain2.draw(&tris, &s2, &state);
        let mask: Vec<bool> = (0..w * h).map(|i| (i * 7919) % 13 < 3).collect();
        let mut m1 = RenderTarget::new(w, h, clear).with_pixel_mask(mask.clone());
        let mut m2 = RenderTarget::new(w, h, clear).with_pixel_mask(mask.clone());
        let mut u1 = RenderTarget::new(w, h, clear);
        let mut u2 = RenderTarget::new(w, h, clear);
        let out = |f: &Fragment<1>| FragmentOutput {
            color: [f.varyings[0], 0.5, 1.0 - f.varyings[0], 0.7],
            id: f.primitive_id,
            depth: None,
        };
        let shared = draw_passes(
            &mut [&mut u1, &mut u2],
            &Cutoffs(&[0.2, 0.6], out),
            &tris,
            &state,
        );
        assert_eq!(shared, vec![st1, st2]);
        assert_eq!(
            (u1.color(), u1.depth(), u1.aux()),
            (plain1.color(), plain1.depth(), plain1.aux())
        );
        assert_eq!(
            (u2.color(), u2.depth(), u2.aux()),
            (plain2.color(), plain2.depth(), plain2.aux())
        );
        draw_passes(
            &mut [&mut m1, &mut m2],
            &Cutoffs(&[0.2, 0.6], out),
            &tris,
            &state,
        );
        let blank = RenderTarget::new(w, h, clear);
        for (masked, plain) in [(&m1, &plain1), (&m2, &plain2)] {
            let mut inside_written = 0;
            for (i, &inside) in mask.iter().enumerate() {
                let want = if inside { plain } else { &blank };
                assert_eq!(masked.color()[i], want.color()[i], "pixel {i}");
                assert_eq!(
                    masked.depth()[i].to_bits(),
                    want.depth()[i].to_bits(),
                    "pixel {i}"
                );
                assert_eq!(masked.aux()[i], want.aux()[i], "pixel {i}");
                inside_written += usize::from(inside && plain.aux()[i] != 0);
            }
            assert!(
                inside_written > 100,
                "the mask covers {inside_written} drawn pixels"
            );
        }
    }

    /// Small triangles and a sparse mask, so that most triangles meet no pixel of it (the masked
    /// bins leave them out): inside the mask every value is the plain draw's, two targets with
    /// the same mask share the lists, and the counters of complementary masks add up to the
    /// plain draw's (every fragment lies in exactly one of them).
    #[test]
    fn sparse_masks_keep_every_value_and_counter() {
        let (w, h) = (160, 96);
        let clear = ClearValues {
            color: [0.2, 0.3, 0.4, 1.0],
            depth: 1.0,
            aux: 0,
        };
        let mut next = unit_random(777u64);
        let tris: Vec<Triangle<1>> = (0..3000)
            .map(|i| {
                let (cx, cy) = (next() * 2.2 - 1.1, next() * 2.2 - 1.1);
                [0, 1, 2].map(|_| {
                    Vertex::new(
                        [cx + next() * 0.06, cy + next() * 0.06, next(), 1.0],
                        [i as f32 / 3000.0],
                    )
                })
            })
            .collect();
        let shader = |cut: f32| {
            move |f: &Fragment<1>| {
                (f.varyings[0] >= cut).then_some(FragmentOutput {
                    color: [f.varyings[0], 0.5, 1.0 - f.varyings[0], 0.7],
                    id: f.primitive_id + 1,
                    depth: None,
                })
            }
        };
        let state = DrawState {
            depth_write: true,
            ..DrawState::TRANSPARENT
        };
        let (s1, s2) = (shader(0.2), shader(0.6));
        let mut plain1 = RenderTarget::new(w, h, clear);
        let st1 = plain1.draw(&tris, &s1, &state);
        let mut plain2 = RenderTarget::new(w, h, clear);
        let st2 = plain2.draw(&tris, &s2, &state);
        let mask: Vec<bool> = (0..w * h).map(|i| (i * 7919) % 97 == 0).collect();
        let outside: Vec<bool> = mask.iter().map(|&m| !m).collect();
        let mut a1 = RenderTarget::new(w, h, clear).with_pixel_mask(mask.clone());
        let mut a2 = RenderTarget::new(w, h, clear).with_pixel_mask(mask.clone());
        let mut b1 = RenderTarget::new(w, h, clear).with_pixel_mask(outside);
        let out = |f: &Fragment<1>| FragmentOutput {
            color: [f.varyings[0], 0.5, 1.0 - f.varyings[0], 0.7],
            id: f.primitive_id + 1,
            depth: None,
        };
        let stats = draw_passes(
            &mut [&mut a1, &mut a2, &mut b1],
            &Cutoffs(&[0.2, 0.6, 0.2], out),
            &tris,
            &state,
        );
        let mut inside_written = 0;
        for (masked, plain) in [(&a1, &plain1), (&a2, &plain2)] {
            for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
                assert_eq!(masked.color()[i], plain.color()[i], "pixel {i}");
                assert_eq!(masked.depth()[i].to_bits(), plain.depth()[i].to_bits());
                assert_eq!(masked.aux()[i], plain.aux()[i], "pixel {i}");
                inside_written += usize::from(plain.aux()[i] != 0);
            }
        }
        assert!(
            inside_written > 20,
            "{inside_written} drawn pixels in the mask"
        );
        let sum = |a: &DrawStats, b: &DrawStats| {
            (
                a.fragments_covered + b.fragments_covered,
                a.fragments_shaded + b.fragments_shaded,
                a.fragments_written + b.fragments_written,
            )
        };
        let all = |s: &DrawStats| (s.fragments_covered, s.fragments_shaded, s.fragments_written);
        assert_eq!(sum(&stats[0], &stats[2]), all(&st1));
        assert!(stats[0].fragments_written > 0 && stats[1].fragments_written > 0);
        assert!(stats[1].fragments_covered == stats[0].fragments_covered);
        assert!(all(&stats[1]) <= all(&st2));
        for s in &stats {
            assert_eq!(
                (s.triangles_in, s.triangles_clipped, s.triangles_rasterized),
                (
                    st1.triangles_in,
                    st1.triangles_clipped,
                    st1.triangles_rasterized
                )
            );
        }
    }
}
