//! Per-tile rasterization (module docs, steps 5-9 within one tile): the walk over a tile's bin
//! of set-up triangles, in submission order, by 2x2 quads: coverage, the early depth test with
//! the depth bound, interpolation and coarse derivatives, shading, the late depth test and the
//! merge into the tile's private buffers, for every target of a group with equal masks at once.
//!
//! Invariants:
//! - a tile reads and writes only its own pixels (and, for a masked target, only masked ones),
//!   so tiles can run in parallel;
//! - each pixel receives its fragments in submission order, every pass's in full before the
//!   next fragment;
//! - the masked-quad list and the covered spans skip only quads that would cover, count and
//!   write nothing.
//!
//! Depends on `types`, `color` (the merge), `target` (the tile buffers) and `setup`.

use super::color::merge;
use super::setup::{QUAD, SetupTriangle, add3, covered_quad_span, mul3, quad_edges};
use super::target::TileBuffers;
use super::types::{DrawState, Fragment, PassSet, PassShader, PixelRect};

#[derive(Clone, Copy, Default)]
pub(super) struct FragmentCounts {
    pub(super) covered: u64,
    pub(super) shaded: u64,
    pub(super) written: u64,
}

/// Rasterizes the triangles of `bin` (indices into `setup`, in submission order) into one tile
/// of the targets of `group` (pass indices; `buffers[i]` is pass `group[i]`'s copy of the tile,
/// all with the same mask). Returns each pass's counts, in `group` order.
pub(super) fn render_tile<const N: usize, S, const ONE: bool>(
    buffers: &mut [TileBuffers],
    group: &[usize],
    bin: &[u32],
    setup: &[&SetupTriangle<N>],
    shader: &S,
    state: &DrawState,
) -> Vec<FragmentCounts>
where
    S: PassShader<N> + ?Sized,
{
    let tile = buffers[0].rect;
    // One target's counts live on the stack, where the compiler keeps them in registers.
    let (mut one, mut many) = ([FragmentCounts::default()], Vec::new());
    let counts: &mut [FragmentCounts] = if ONE {
        &mut one
    } else {
        many.resize(group.len(), FragmentCounts::default());
        &mut many
    };
    // Speed-up (issue 14, masked draws): the quads of a masked tile with at least one masked
    // pixel, in row-major order. A quad with none covers nothing (the coverage test below
    // requires the mask), so a triangle may visit only these quads of its box, in the same
    // order, with the edge functions evaluated at each (exact integers, equal to the stepped
    // ones): every value and counter is the full walk's. Used where it is the shorter walk.
    let masked_quads = buffers[0]
        .mask
        .as_ref()
        .map(|mask| masked_quads(tile, mask));
    for tri in bin.iter().map(|&i| setup[i as usize]) {
        let Some(r) = tri.bbox.and_then(|b| b.intersect(&tile)) else {
            continue;
        };
        // Quads are aligned to even coordinates; tiles start at even coordinates too. The edge
        // functions walk the quads by exact integer steps (two pixels per quad) from those of
        // the first quad's top-left pixel.
        let (qx0, qy0) = (r.x0 & !1, r.y0 & !1);
        let steps = tri.edge_steps();
        let box_quads = (r.x1 - qx0).div_ceil(2) as usize * (r.y1 - qy0).div_ceil(2) as usize;
        if let Some(list) = masked_quads.as_ref().filter(|l| l.len() < box_quads) {
            for &(qx, qy) in list {
                if qx < qx0 || qx >= r.x1 || qy < qy0 || qy >= r.y1 {
                    continue;
                }
                let edges = quad_edges(tri.edges(qx, qy), &steps);
                shade_quad::<N, S, ONE>(
                    buffers,
                    group,
                    tri,
                    &r,
                    (qx, qy),
                    &edges,
                    shader,
                    state,
                    counts,
                );
            }
            continue;
        }
        let [two_sx, two_sy] = steps.map(|s| add3(s, s));
        let row_quads = (r.x1 - qx0).div_ceil(2);
        let mut row_edges = tri.edges(qx0, qy0);
        for qy in (qy0..r.y1).step_by(2) {
            let row_start = row_edges;
            row_edges = add3(row_edges, two_sy);
            // Only the quads of this row that can hold a covered pixel (exact, see
            // `covered_quad_span`): the others would cover, count and write nothing.
            let Some((m0, m1)) = covered_quad_span(tri, row_start, &steps, row_quads) else {
                continue;
            };
            let mut quad_e = add3(row_start, mul3(two_sx, m0 as i64));
            for qx in (qx0 + 2 * m0..qx0 + 2 * m1).step_by(2) {
                let edges = quad_edges(quad_e, &steps);
                quad_e = add3(quad_e, two_sx);
                shade_quad::<N, S, ONE>(
                    buffers,
                    group,
                    tri,
                    &r,
                    (qx, qy),
                    &edges,
                    shader,
                    state,
                    counts,
                );
            }
        }
    }
    counts.to_vec()
}

/// The pixels of `tile` set in `mask` (the whole target's row-major pixel mask, `width` wide),
/// in row-major order.
pub(super) fn masked_pixels(tile: PixelRect, mask: &[bool], width: u32) -> Vec<(u32, u32)> {
    let mut pixels = Vec::new();
    for y in tile.y0..tile.y1 {
        for x in tile.x0..tile.x1 {
            if mask[y as usize * width as usize + x as usize] {
                pixels.push((x, y));
            }
        }
    }
    pixels
}

/// The quads (top-left pixel, even coordinates) of `tile` with at least one pixel set in
/// `mask` (the tile's row-major pixel mask), in row-major order.
fn masked_quads(tile: PixelRect, mask: &[bool]) -> Vec<(u32, u32)> {
    let tile_w = tile.width();
    let mut quads = Vec::new();
    for qy in (tile.y0..tile.y1).step_by(2) {
        for qx in (tile.x0..tile.x1).step_by(2) {
            let any = QUAD.iter().any(|&(dx, dy)| {
                let (x, y) = (qx + dx, qy + dy);
                x < tile.x1
                    && y < tile.y1
                    && mask[((y - tile.y0) * tile_w + (x - tile.x0)) as usize]
            });
            if any {
                quads.push((qx, qy));
            }
        }
    }
    quads
}

/// One 2x2 quad of one triangle in a tile of the targets of `group` (module docs, steps 7-9):
/// coverage (once for all), the early depth test (per target), interpolation with the quad's
/// derivatives (once, for the pixels some target shades), shading (once per pixel, for the
/// passes whose test it passed: [`PassShader`]), the late depth test and the merge (per target).
/// `r`: the triangle's box within the tile; `edges`: the edge functions at the quad's four
/// pixels; `buffers`, `counts`: per target, in `group` order.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn shade_quad<const N: usize, S, const ONE: bool>(
    buffers: &mut [TileBuffers],
    group: &[usize],
    tri: &SetupTriangle<N>,
    r: &PixelRect,
    (qx, qy): (u32, u32),
    edges: &[[i64; 3]; 4],
    shader: &S,
    state: &DrawState,
    counts: &mut [FragmentCounts],
) where
    S: PassShader<N> + ?Sized,
{
    // With `ONE` (a group of one target) the loops over targets below run once, and the
    // compiler knows it.
    let n = if ONE { 1 } else { buffers.len() };
    let (buffers, counts, group) = (&mut buffers[..n], &mut counts[..n], &group[..n]);
    let tile = buffers[0].rect;
    let tile_w = tile.width();
    // Covered pixels: inside the triangle, and pixels this tile may write (inside the
    // triangle's box and the tile, and inside the targets' pixel mask if they have one). `at`:
    // each pixel's index in the tile buffers.
    let first = ((qy - tile.y0) * tile_w + (qx - tile.x0)) as usize;
    let at = [
        first,
        first + 1,
        first + tile_w as usize,
        first + tile_w as usize + 1,
    ];
    let mut covered = [false; 4];
    {
        let mask = buffers[0].mask.as_ref();
        for k in 0..4 {
            covered[k] = tri.covers(&edges[k])
                && r.contains(qx + QUAD[k].0, qy + QUAD[k].1)
                && mask.is_none_or(|m| m[at[k]]);
        }
    }
    if covered == [false; 4] {
        return;
    }
    // The early depth test of the covered pixels (module docs, step 8), per target: `passed[k]`
    // holds the passes whose test pixel `k` passed.
    // Barycentrics are computed once per pixel and shared by depth and varyings.
    let mut bary = [[0.0f64; 3]; 4];
    let mut have_bary = [false; 4];
    let mut depth = [0.0f32; 4];
    let mut passed: [PassSet; 4] = [0; 4];
    for k in (0..4).filter(|&k| covered[k]) {
        // Depth bound (module docs): the passes whose stored depth is at most the triangle's
        // lower bound fail the test whatever the interpolated depth; the others may pass.
        // `at[k]` may lie outside the tile only for uncovered pixels.
        let mut may_pass: PassSet = 0;
        for ((b, c), &p) in buffers.iter().zip(counts.iter_mut()).zip(group) {
            c.covered += 1;
            if !state.depth_test || tri.min_depth < b.depth[at[k]] {
                may_pass |= 1 << p;
            }
        }
        if may_pass == 0 {
            continue;
        }
        bary[k] = tri.barycentrics(&edges[k]);
        have_bary[k] = true;
        depth[k] = tri.depth(&bary[k]);
        for (b, &p) in buffers.iter().zip(group) {
            if may_pass & (1 << p) != 0 && (!state.depth_test || depth[k] < b.depth[at[k]]) {
                passed[k] |= 1 << p;
            }
        }
    }
    if passed == [0; 4] {
        return;
    }
    // The derivatives need the top three pixels, covered or not (helpers); the bottom-right
    // one is interpolated only if it is shaded.
    for k in (0..3).filter(|&k| !have_bary[k]) {
        bary[k] = tri.barycentrics(&edges[k]);
    }
    let mut values = [[0.0f32; N]; 4];
    for k in (0..4).filter(|&k| k < 3 || passed[k] != 0) {
        values[k] = tri.varyings(&bary[k]);
    }
    let ddx = std::array::from_fn(|j| values[1][j] - values[0][j]);
    let ddy = std::array::from_fn(|j| values[2][j] - values[0][j]);
    for k in (0..4).filter(|&k| passed[k] != 0) {
        for (c, &p) in counts.iter_mut().zip(group) {
            c.shaded += u64::from(passed[k] & (1 << p) != 0);
        }
        let fragment = Fragment {
            x: qx + QUAD[k].0,
            y: qy + QUAD[k].1,
            depth: depth[k],
            varyings: values[k],
            ddx,
            ddy,
            front_facing: tri.front_facing,
            primitive_id: tri.primitive_id,
        };
        let Some((out, kept)) = shader.shade_passes(&fragment, passed[k]) else {
            continue; // discarded by every pass
        };
        let at = at[k];
        for ((b, c), &p) in buffers.iter_mut().zip(counts.iter_mut()).zip(group) {
            if kept & (1 << p) == 0 {
                continue;
            }
            // Shader-written depth (module docs, step 8): clamped, then the late test.
            let z = match out.depth {
                None => depth[k],
                Some(d) if d.is_nan() => continue,
                Some(d) => {
                    let d = d.clamp(0.0, 1.0);
                    if state.depth_test && d >= b.depth[at] {
                        continue;
                    }
                    d
                }
            };
            c.written += 1;
            if state.depth_write {
                b.depth[at] = z;
            }
            b.color[at] = merge(b.color[at], out.color, state.blend);
            b.aux[at] = out.id;
        }
    }
}
