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
//!
//! ## Grids on given axes (issue 34)
//! A terrain from an elevation model is drawn on its own grid lines, not on the uniform
//! [`TERRAIN_CELLS`]² grid: [`GridAxes`] are the grid's `x` and `y` lines (increasing), and
//! [`axes_vertices`] / [`axes_triangles`] / [`axes_grid`] the same construction as above on them
//! (vertex `(i, j)` at index `j · xs.len() + i`, cells `(a, b, c), (a, c, d)`). [`uniform_axes`]
//! are the uniform grid's lines, so the uniform functions are the axes functions on them, bit for
//! bit (`uniform_axes_are_the_uniform_grid`). [`grid_surface_height`] is the height of the drawn
//! surface of a grid of heights (the triangle the point lies in, linearly), so that trees placed
//! on a grid terrain stand on what is drawn.

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
    axes_vertices(&uniform_axes(bounds), height)
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

/// The lines of a ground grid: `xs` and `y`s, each increasing, at least two each.
#[derive(Clone, Debug, PartialEq)]
pub struct GridAxes {
    /// The grid's `x` lines, metres relative to the scene origin, increasing.
    pub xs: Vec<f32>,
    /// The grid's `y` lines, increasing.
    pub ys: Vec<f32>,
}

/// The uniform grid's lines: [`TERRAIN_CELLS`] cells per side over the footprint `bounds` plus
/// [`TERRAIN_MARGIN`], each line computed as [`terrain_vertex`] computes it.
pub fn uniform_axes(bounds: [f32; 4]) -> GridAxes {
    let [x0, y0, x1, y1] = bounds;
    let (x0, y0, x1, y1) = (
        x0 - TERRAIN_MARGIN,
        y0 - TERRAIN_MARGIN,
        x1 + TERRAIN_MARGIN,
        y1 + TERRAIN_MARGIN,
    );
    let n = TERRAIN_CELLS;
    GridAxes {
        xs: (0..=n)
            .map(|i| x0 + (x1 - x0) * i as f32 / n as f32)
            .collect(),
        ys: (0..=n)
            .map(|j| y0 + (y1 - y0) * j as f32 / n as f32)
            .collect(),
    }
}

/// Every vertex of the grid on `axes` once, row by row (vertex `(i, j)` at `j · xs.len() + i`):
/// `(position, linear colour)` as [`terrain_vertex`] makes them.
pub fn axes_vertices(
    axes: &GridAxes,
    height: impl Fn(f32, f32) -> f32,
) -> Vec<([f32; 3], [f32; 3])> {
    let mut out = Vec::with_capacity(axes.xs.len() * axes.ys.len());
    for &y in &axes.ys {
        for &x in &axes.xs {
            let z = height(x, y) - TERRAIN_SINK;
            out.push(([x, y, z], ground_color(z)));
        }
    }
    out
}

/// The triangles of the grid on `axes` in draw order (module docs) as indices into
/// [`axes_vertices`].
pub fn axes_triangles(axes: &GridAxes) -> impl Iterator<Item = [u32; 3]> + use<> {
    let nx = axes.xs.len().saturating_sub(1) as u32;
    let ny = axes.ys.len().saturating_sub(1) as u32;
    let at = move |i: u32, j: u32| j * (nx + 1) + i;
    (0..ny).flat_map(move |j| {
        (0..nx).flat_map(move |i| {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            [[a, b, c], [a, c, d]]
        })
    })
}

/// The grid on `axes` as a triangle list in draw order: [`axes_triangles`] over [`axes_vertices`].
pub fn axes_grid(
    axes: &GridAxes,
    height: impl Fn(f32, f32) -> f32,
) -> Vec<[([f32; 3], [f32; 3]); 3]> {
    let grid = axes_vertices(axes, height);
    axes_triangles(axes)
        .map(|t| t.map(|k| grid[k as usize]))
        .collect()
}

/// Height of the drawn surface of a grid of heights at `(x, y)`: `heights[j · nx + i]` at
/// `(x0 + i · dx, y0 + j · dy)`, `nx, ny >= 2`, split into the triangles the grid is drawn with
/// (module docs: `(a, b, c)` where the cell fraction `fx >= fy`, else `(a, c, d)`) and
/// interpolated linearly on the triangle; outside the grid, the nearest edge point's height.
/// At a grid point whose `(x - x0) / dx` and `(y - y0) / dy` are whole numbers it is that
/// point's height, exactly.
pub fn grid_surface_height(
    heights: &[f32],
    nx: usize,
    ny: usize,
    origin: [f32; 2],
    step: [f32; 2],
    x: f32,
    y: f32,
) -> f32 {
    let locate = |v: f32, o: f32, d: f32, n: usize| -> (usize, f32) {
        let t = ((v - o) / d).clamp(0.0, (n - 1) as f32);
        let i = (t.floor() as usize).min(n - 2);
        (i, (t - i as f32).clamp(0.0, 1.0))
    };
    let (i, fx) = locate(x, origin[0], step[0], nx);
    let (j, fy) = locate(y, origin[1], step[1], ny);
    let h = |i: usize, j: usize| heights[j * nx + i];
    let (a, b, c, d) = (h(i, j), h(i + 1, j), h(i + 1, j + 1), h(i, j + 1));
    if fx == 0.0 && fy == 0.0 {
        return a;
    }
    if fx >= fy {
        a + fx * (b - a) + fy * (c - b)
    } else {
        a + fx * (c - d) + fy * (d - a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The uniform grid is the axes grid on [`uniform_axes`], bit for bit.
    #[test]
    fn uniform_axes_are_the_uniform_grid() {
        let bounds = [-350.0, 20.0, 900.0, 1700.0];
        let height = |x: f32, y: f32| (x * 0.013).sin() * 12.0 + (y * 0.007).cos() * 20.0;
        let bits = |v: &([f32; 3], [f32; 3])| (v.0.map(f32::to_bits), v.1.map(f32::to_bits));
        let a: Vec<_> = terrain_grid_vertices(bounds, height)
            .iter()
            .map(bits)
            .collect();
        let b: Vec<_> = axes_vertices(&uniform_axes(bounds), height)
            .iter()
            .map(bits)
            .collect();
        assert_eq!(a, b);
        let ta: Vec<_> = terrain_grid_triangles().collect();
        let tb: Vec<_> = axes_triangles(&uniform_axes(bounds)).collect();
        assert_eq!(ta, tb);
    }

    /// The surface height is the grid height at grid points and linear along the cell's
    /// triangles (a plane through three grid points is reproduced within rounding).
    #[test]
    fn grid_surface_height_is_exact_at_points_and_linear_on_triangles() {
        let (nx, ny) = (5, 4);
        let heights: Vec<f32> = (0..nx * ny).map(|k| ((k * 37) % 11) as f32 - 3.5).collect();
        let (o, d) = ([10.0, -20.0], [2.0, 3.0]);
        for j in 0..ny {
            for i in 0..nx {
                let (x, y) = (o[0] + i as f32 * d[0], o[1] + j as f32 * d[1]);
                assert_eq!(
                    grid_surface_height(&heights, nx, ny, o, d, x, y),
                    heights[j * nx + i]
                );
            }
        }
        // A plane z = 0.5 x - 0.25 y + 3 is reproduced everywhere (triangles are planar pieces).
        let plane = |x: f32, y: f32| 0.5 * x - 0.25 * y + 3.0;
        let mut hp = vec![0.0; nx * ny];
        for j in 0..ny {
            for i in 0..nx {
                hp[j * nx + i] = plane(o[0] + i as f32 * d[0], o[1] + j as f32 * d[1]);
            }
        }
        for k in 0..50 {
            let (x, y) = (10.0 + k as f32 * 0.159, -20.0 + k as f32 * 0.18);
            let z = grid_surface_height(&hp, nx, ny, o, d, x, y);
            assert!(
                (z - plane(x, y)).abs() < 1e-4,
                "{x} {y}: {z} vs {}",
                plane(x, y)
            );
        }
        // The drawn surface: inside every cell, the height is the drawn triangle's (the grid's
        // triangles on these lines, interpolated by barycentric weights), on a non-planar grid.
        let axes = GridAxes {
            xs: (0..nx).map(|i| o[0] + i as f32 * d[0]).collect(),
            ys: (0..ny).map(|j| o[1] + j as f32 * d[1]).collect(),
        };
        let tris = axes_grid(&axes, |x, y| {
            grid_surface_height(&heights, nx, ny, o, d, x, y)
        });
        for k in 0..400 {
            let (x, y) = (
                o[0] + (k as f32 * 0.0371) % (d[0] * (nx - 1) as f32),
                o[1] + (k as f32 * 0.0533) % (d[1] * (ny - 1) as f32),
            );
            let z = grid_surface_height(&heights, nx, ny, o, d, x, y);
            let inside = tris.iter().find_map(|t| {
                let [a, b, c] = t.map(|v| v.0);
                let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
                let u = ((x - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (y - a[1])) / det;
                let v = ((b[0] - a[0]) * (y - a[1]) - (x - a[0]) * (b[1] - a[1])) / det;
                (u >= -1e-6 && v >= -1e-6 && u + v <= 1.0 + 1e-6)
                    .then(|| a[2] + u * (b[2] - a[2]) + v * (c[2] - a[2]) + TERRAIN_SINK)
            });
            let drawn = inside.expect("every point inside the grid is in a drawn triangle");
            assert!(
                (z - drawn).abs() < 1e-3,
                "({x}, {y}): height {z}, drawn {drawn}"
            );
        }
        // Outside: the nearest edge point.
        assert_eq!(
            grid_surface_height(&heights, nx, ny, o, d, -1e6, -1e6),
            heights[0]
        );
    }

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
