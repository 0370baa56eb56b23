//! The ground both renderers draw (and the ray-traced ground truth intersects): a
//! [`TERRAIN_CELLS`]² grid over the scene's footprint plus [`TERRAIN_MARGIN`], following the
//! terrain height, sunk [`TERRAIN_SINK`] so tree bases do not z-fight it, coloured by
//! [`ground_color`] (linear RGB vertex colours).
//!
//! ## Contract
//! [`terrain_vertex`] is grid vertex `(i, j)`, `0 <= i, j <= TERRAIN_CELLS`; [`terrain_grid`] the
//! triangle list every side draws, cell by cell (row `j` outer, column `i` inner), each cell
//! `(a, b, c), (a, c, d)` with `a = (i, j)`, `b = (i + 1, j)`, `c = (i + 1, j + 1)`,
//! `d = (i, j + 1)`. [`terrain_grid_vertices`] and [`terrain_grid_triangles`] are the same grid as
//! shared vertices and the triangles' indices into them. The reference projects it on the CPU
//! (`reference::draw::terrain_triangles`, each shared vertex once), the GPU uploads it in world
//! space (`gpu::draw::terrain_vertices`).

use crate::color::srgb_to_linear;

/// Cells per side of the ground grid.
pub const TERRAIN_CELLS: u32 = 64;
/// How far the ground extends beyond the scene's footprint, metres.
pub const TERRAIN_MARGIN: f32 = 2000.0;
/// How far the ground is sunk below the terrain height, metres.
pub const TERRAIN_SINK: f32 = 0.05;

/// Ground colour at a height, a muted green-brown ramp between two sRGB8 colours, returned in
/// linear light (the ground's vertex colour).
pub fn ground_color(z: f32) -> [f32; 3] {
    let t = ((z + 30.0) / 60.0).clamp(0.0, 1.0);
    let lo = [96u8, 110, 70];
    let hi = [140u8, 132, 96];
    core::array::from_fn(|c| srgb_to_linear(lo[c]) * (1.0 - t) + srgb_to_linear(hi[c]) * t)
}

/// Grid vertex `(i, j)` over the footprint `bounds = [min_x, min_y, max_x, max_y]` (plus the
/// margin), on the terrain `height(x, y)`: `(position, linear colour)`.
pub fn terrain_vertex(
    bounds: [f32; 4],
    height: &impl Fn(f32, f32) -> f32,
    i: u32,
    j: u32,
) -> ([f32; 3], [f32; 3]) {
    let [x0, y0, x1, y1] = bounds;
    let (x0, y0, x1, y1) = (
        x0 - TERRAIN_MARGIN,
        y0 - TERRAIN_MARGIN,
        x1 + TERRAIN_MARGIN,
        y1 + TERRAIN_MARGIN,
    );
    let n = TERRAIN_CELLS;
    let x = x0 + (x1 - x0) * i as f32 / n as f32;
    let y = y0 + (y1 - y0) * j as f32 / n as f32;
    let z = height(x, y) - TERRAIN_SINK;
    ([x, y, z], ground_color(z))
}

/// Every grid vertex once ([`terrain_vertex`]), row by row: vertex `(i, j)` at index
/// `j · (TERRAIN_CELLS + 1) + i`. A vertex is shared by up to six triangles; `terrain_vertex` is
/// a pure function, so computing it once gives each of them the same values (issue 14, session
/// 11: evaluating each vertex per cell corner was a tenth of a frame without trees).
pub fn terrain_grid_vertices(
    bounds: [f32; 4],
    height: impl Fn(f32, f32) -> f32,
) -> Vec<([f32; 3], [f32; 3])> {
    let n = TERRAIN_CELLS;
    (0..=n)
        .flat_map(|j| (0..=n).map(move |i| (i, j)))
        .map(|(i, j)| terrain_vertex(bounds, &height, i, j))
        .collect()
}

/// The grid's triangles in draw order (module docs) as indices into [`terrain_grid_vertices`].
pub fn terrain_grid_triangles() -> impl Iterator<Item = [u32; 3]> {
    let n = TERRAIN_CELLS;
    let at = move |i: u32, j: u32| j * (n + 1) + i;
    (0..n).flat_map(move |j| {
        (0..n).flat_map(move |i| {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            [[a, b, c], [a, c, d]]
        })
    })
}

/// The ground's triangles in draw order (module docs), each vertex `(position, linear colour)`:
/// [`terrain_grid_triangles`] over [`terrain_grid_vertices`].
pub fn terrain_grid(
    bounds: [f32; 4],
    height: impl Fn(f32, f32) -> f32,
) -> Vec<[([f32; 3], [f32; 3]); 3]> {
    let grid = terrain_grid_vertices(bounds, height);
    terrain_grid_triangles()
        .map(|t| t.map(|k| grid[k as usize]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_covers_the_footprint_plus_margin() {
        let g = terrain_grid([0.0, 0.0, 100.0, 100.0], |_, _| 1.0);
        assert_eq!(g.len(), (TERRAIN_CELLS * TERRAIN_CELLS * 2) as usize);
        assert_eq!(g[0][0].0, [-TERRAIN_MARGIN, -TERRAIN_MARGIN, 0.95]);
        let last = g.last().unwrap()[1].0;
        assert_eq!(last[0], 100.0 + TERRAIN_MARGIN);
        assert_eq!(last[1], 100.0 + TERRAIN_MARGIN);
    }

    /// Every corner of every cell is `terrain_vertex` at that grid point, bit for bit: the grid's
    /// vertices are computed once and shared, not per corner.
    #[test]
    fn grid_corners_are_the_terrain_vertices() {
        let bounds = [-350.0, 20.0, 900.0, 1700.0];
        let height = |x: f32, y: f32| (x * 0.013).sin() * 12.0 + (y * 0.007).cos() * 20.0;
        let g = terrain_grid(bounds, height);
        let n = TERRAIN_CELLS;
        let bits = |v: ([f32; 3], [f32; 3])| (v.0.map(f32::to_bits), v.1.map(f32::to_bits));
        for j in 0..n {
            for i in 0..n {
                let corner = |a, b| bits(terrain_vertex(bounds, &height, a, b));
                let [t0, t1] = [
                    g[(2 * (j * n + i)) as usize],
                    g[(2 * (j * n + i) + 1) as usize],
                ];
                assert_eq!(
                    t0.map(bits),
                    [corner(i, j), corner(i + 1, j), corner(i + 1, j + 1)]
                );
                assert_eq!(
                    t1.map(bits),
                    [corner(i, j), corner(i + 1, j + 1), corner(i, j + 1)]
                );
            }
        }
    }
}
