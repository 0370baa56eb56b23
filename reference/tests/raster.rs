//! The reference rasterizer and sampler against analytic expectations: exact coverage sets, the
//! top-left rule, watertight fans (property test), perspective-correct interpolation against the
//! ray-plane closed form, depth LESS, blending, derivatives, texturing and thread-count determinism.

use std::sync::atomic::{AtomicU32, Ordering};

use forestlod_reference::raster::{
    Blend, ClearValues, CullMode, DrawState, DrawStats, Fragment, FragmentOutput, FrontFace,
    RenderTarget, Triangle, Vertex,
};
use forestlod_reference::sampler::{Sampler, Texture};
use forestlod_reference::shared::Camera;
use forestlod_reference::texture::{Rgba8Image, linear_to_srgb, srgb_to_linear, unorm8};
use glam::{DMat4, DVec4, Vec4};
use proptest::prelude::*;

/// Clip coordinates (`w = 1`) of framebuffer point `(x, y)` (pixels, y down) on a `w` x `h` target.
/// For power-of-two sizes and coordinates that are multiples of 1/256 the round trip through the
/// viewport transform is exact, so the rasterizer sees exactly these snapped positions.
fn px(x: f32, y: f32, w: u32, h: u32) -> [f32; 4] {
    [2.0 * x / w as f32 - 1.0, 1.0 - 2.0 * y / h as f32, 0.5, 1.0]
}

fn tri(p: [[f32; 2]; 3], w: u32, h: u32) -> Triangle<0> {
    p.map(|q| Vertex::new(px(q[0], q[1], w, h), []))
}

/// State that counts every covered sample: no depth test, no depth write.
const COUNT: DrawState = DrawState {
    depth_test: false,
    depth_write: false,
    blend: Blend::Replace,
    cull: CullMode::None,
    front_face: FrontFace::Ccw,
};

/// How many times each pixel was covered by `triangles` (each drawn in the given order).
fn coverage(triangles: &[Triangle<0>], w: u32, h: u32) -> (Vec<u32>, DrawStats) {
    let counts: Vec<AtomicU32> = (0..w * h).map(|_| AtomicU32::new(0)).collect();
    let shader = |f: &Fragment<0>| {
        counts[(f.y * w + f.x) as usize].fetch_add(1, Ordering::Relaxed);
        Some(FragmentOutput {
            color: [1.0; 4],
            id: f.primitive_id,
            depth: None,
        })
    };
    let mut target = RenderTarget::new(w, h, ClearValues::default());
    let stats = target.draw(triangles, &shader, &COUNT);
    (counts.into_iter().map(|c| c.into_inner()).collect(), stats)
}

/// Asserts `counts` equals `expected(x, y)` at every pixel.
fn assert_coverage(counts: &[u32], w: u32, expected: impl Fn(i64, i64) -> u32, what: &str) {
    for (i, &c) in counts.iter().enumerate() {
        let (x, y) = ((i as u32 % w) as i64, (i as u32 / w) as i64);
        assert_eq!(c, expected(x, y), "{what}: pixel ({x}, {y})");
    }
}

#[test]
fn an_axis_aligned_right_triangle_covers_its_analytic_pixel_set() {
    let (w, h) = (32, 32);
    // Integer vertices: no centre lies on a leg; centres on the hypotenuse (x + y = 11) are on a
    // bottom-right edge and excluded.
    let (c, _) = coverage(&[tri([[2.0, 2.0], [10.0, 2.0], [2.0, 10.0]], w, h)], w, h);
    assert_coverage(
        &c,
        w,
        |x, y| (x >= 2 && y >= 2 && x + y <= 10) as u32,
        "integer",
    );
    // Vertices on pixel centres: the top leg (y = 2.5) and left leg (x = 2.5) are covered, the
    // hypotenuse (centres with x + y = 12) is not.
    let (c, _) = coverage(&[tri([[2.5, 2.5], [10.5, 2.5], [2.5, 10.5]], w, h)], w, h);
    assert_coverage(
        &c,
        w,
        |x, y| (x >= 2 && y >= 2 && x + y <= 11) as u32,
        "top-left",
    );
    // The mirror image: the bottom leg (y = 10.5) and right leg (x = 10.5) are not covered, the
    // hypotenuse is now a left edge and is.
    let (c, _) = coverage(&[tri([[10.5, 10.5], [2.5, 10.5], [10.5, 2.5]], w, h)], w, h);
    assert_coverage(
        &c,
        w,
        |x, y| (x <= 9 && y <= 9 && x + y >= 12) as u32,
        "bottom-right",
    );
}

#[test]
fn a_full_screen_quad_covers_every_pixel_exactly_once() {
    // Not a power of two and not a multiple of the tile size.
    let (w, h) = (100, 70);
    let v = |x: f32, y: f32| Vertex::new([x, y, 0.5, 1.0], []);
    let quad = [
        [v(-1.0, -1.0), v(1.0, -1.0), v(1.0, 1.0)],
        [v(-1.0, -1.0), v(1.0, 1.0), v(-1.0, 1.0)],
    ];
    let (c, stats) = coverage(&quad, w, h);
    assert_coverage(&c, w, |_, _| 1, "full-screen quad");
    assert_eq!(
        stats,
        DrawStats {
            triangles_in: 2,
            triangles_clipped: 2,
            triangles_rasterized: 2,
            fragments_covered: 7000,
            fragments_shaded: 7000,
            fragments_written: 7000,
        }
    );
}

#[test]
fn a_quad_far_beyond_the_guard_band_is_clipped_and_still_covers_once() {
    let (w, h) = (100, 70);
    let s = 3.0e6f32; // NDC: ~1.5e8 pixels out, far past the 2^20-pixel guard band
    let v = |x: f32, y: f32, wc: f32| Vertex::new([x * wc, y * wc, 0.5 * wc, wc], []);
    let quad = [
        [v(-s, -s, 1.0), v(s, -s, 2.0), v(s, s, 0.5)],
        [v(-s, -s, 1.0), v(s, s, 0.5), v(-s, s, 3.0)],
    ];
    let (c, stats) = coverage(&quad, w, h);
    assert_coverage(&c, w, |_, _| 1, "guard-band quad");
    assert!(stats.triangles_clipped > 2, "{stats:?}");
}

#[test]
fn triangles_behind_the_near_plane_or_beyond_the_far_plane_cover_nothing() {
    let (w, h) = (64, 64);
    let v = |z: f32| Vertex::new([0.0, 0.0, z, 1.0], []);
    let at = |x: f32, y: f32, z: f32| Vertex::new([x, y, z, 1.0], []);
    let behind = [at(-1.0, -1.0, -0.1), at(1.0, -1.0, -0.2), v(-0.01)];
    let beyond = [at(-1.0, -1.0, 1.1), at(1.0, -1.0, 1.2), v(1.01)];
    let (c, stats) = coverage(&[behind, beyond], w, h);
    assert_coverage(&c, w, |_, _| 0, "outside depth range");
    assert_eq!(stats.triangles_clipped, 0);
}

/// Twice the signed area of `(a, b, p)` in integer units.
fn edge(a: [i64; 2], b: [i64; 2], p: [i64; 2]) -> i64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// Whether pixel `(x, y)`'s centre lies strictly inside the convex polygon `poly` (1/256 units,
/// either winding).
fn strictly_inside(poly: &[[i64; 2]], x: i64, y: i64) -> bool {
    let p = [x * 256 + 128, y * 256 + 128];
    let e: Vec<i64> = (0..poly.len())
        .map(|i| edge(poly[i], poly[(i + 1) % poly.len()], p))
        .collect();
    e.iter().all(|&v| v > 0) || e.iter().all(|&v| v < 0)
}

fn fixed(p: [f32; 2]) -> [i64; 2] {
    p.map(|c| (c * 256.0) as i64)
}

/// Draws the two triangles `(a, b, c)` and `(b, a, d)` in both orders and with both windings and
/// checks: no pixel twice, every centre strictly inside the quad `a c b d` once, every centre on
/// the open segment `ab` once.
fn check_shared_edge(a: [f32; 2], b: [f32; 2], c: [f32; 2], d: [f32; 2], on_edge: &[(i64, i64)]) {
    let (w, h) = (64, 64);
    let quad = [a, c, b, d].map(fixed);
    // Bits of `order`: 1 flips the first triangle's winding, 2 the second's, 4 draws it first.
    for order in 0..8 {
        let mut t1 = tri([a, b, c], w, h);
        let mut t2 = tri([b, a, d], w, h);
        if order & 1 != 0 {
            t1.swap(1, 2);
        }
        if order & 2 != 0 {
            t2.swap(1, 2);
        }
        let tris = if order & 4 != 0 { [t2, t1] } else { [t1, t2] };
        let (counts, _) = coverage(&tris, w, h);
        for (i, &n) in counts.iter().enumerate() {
            let (x, y) = ((i as u32 % w) as i64, (i as u32 / w) as i64);
            assert!(n <= 1, "order {order}: pixel ({x}, {y}) covered {n} times");
            if strictly_inside(&quad, x, y) {
                assert_eq!(n, 1, "order {order}: pixel ({x}, {y}) inside the quad");
            }
        }
        for &(x, y) in on_edge {
            assert_eq!(
                counts[(y * w as i64 + x) as usize],
                1,
                "order {order}: ({x}, {y})"
            );
        }
    }
}

#[test]
fn two_triangles_sharing_a_quad_diagonal_cover_it_once_in_any_order() {
    // The diagonal (0.5, 0.5) -> (40.5, 20.5) passes through the centres (0.5 + 2k, 0.5 + k).
    let on_edge: Vec<(i64, i64)> = (1..20).map(|k| (2 * k, k)).collect();
    check_shared_edge(
        [0.5, 0.5],
        [40.5, 20.5],
        [30.25, 3.75],
        [6.0, 28.5],
        &on_edge,
    );
}

#[test]
fn two_triangles_sharing_an_arbitrary_edge_cover_it_once_in_any_order() {
    // Direction (3, -2) from (2.5, 40.5): centres (2.5 + 3k, 40.5 - 2k), k = 1..19.
    let on_edge: Vec<(i64, i64)> = (1..20).map(|k| (2 + 3 * k, 40 - 2 * k)).collect();
    check_shared_edge(
        [2.5, 40.5],
        [62.5, 0.5],
        [50.0, 45.75],
        [5.25, 3.0],
        &on_edge,
    );
    // A steep edge through no centre at all, with subpixel endpoints.
    check_shared_edge(
        [10.0 + 3.0 / 256.0, 1.0 + 77.0 / 256.0],
        [13.0 + 250.0 / 256.0, 60.0 + 1.0 / 256.0],
        [40.0, 30.0],
        [1.0, 50.0 + 5.0 / 256.0],
        &[],
    );
}

#[test]
fn top_left_ties_on_pixel_centres_cover_top_and_left_but_not_bottom_and_right() {
    let (w, h) = (32, 32);
    let (a, b, c, d) = ([2.5, 2.5], [10.5, 2.5], [10.5, 10.5], [2.5, 10.5]);
    // Both diagonals, both windings.
    for tris in [
        [tri([a, b, c], w, h), tri([a, c, d], w, h)],
        [tri([a, c, b], w, h), tri([a, d, c], w, h)],
        [tri([b, d, a], w, h), tri([b, c, d], w, h)],
    ] {
        let (counts, _) = coverage(&tris, w, h);
        // Centres on the top row (y = 2) and left column (x = 2) are in; on the bottom row
        // (y = 10) and right column (x = 10) out.
        assert_coverage(
            &counts,
            w,
            |x, y| ((2..10).contains(&x) && (2..10).contains(&y)) as u32,
            "square on centres",
        );
    }
}

#[test]
fn degenerate_triangles_cover_nothing() {
    let (w, h) = (32, 32);
    let e = 1.0 / 1024.0; // snaps away: under half a subpixel
    let tris = [
        tri([[1.0, 1.0], [20.0, 20.0], [10.5, 10.5]], w, h), // collinear
        tri([[3.0, 3.0], [3.0, 3.0], [20.0, 5.0]], w, h),    // repeated vertex
        tri([[5.5, 5.5], [5.5 + e, 5.5], [5.5, 5.5 + e]], w, h), // collapses when snapped
    ];
    let (c, stats) = coverage(&tris, w, h);
    assert_coverage(&c, w, |_, _| 0, "degenerate");
    assert_eq!(
        (stats.triangles_clipped, stats.triangles_rasterized),
        (3, 0)
    );
}

/// A random fan tiling an axis-aligned rectangle, in 1/256 pixel units.
#[derive(Clone, Debug)]
struct Fan {
    /// `[x0, y0, x1, y1]`, half-open in the expectation.
    rect: [i64; 4],
    centre: [i64; 2],
    /// Boundary points in perimeter order, corners included.
    rim: Vec<[i64; 2]>,
    /// Bit `i` set: triangle `i` is drawn clockwise instead of counter-clockwise.
    flips: u64,
}

fn fan() -> impl Strategy<Value = Fan> {
    (
        (-1024i64..15360, -1024i64..15360, 2i64..20000, 2i64..20000),
        (any::<u64>(), any::<u64>()),
        prop::collection::vec(any::<u64>(), 0..12),
        any::<u64>(),
    )
        .prop_map(|((x0, y0, w, h), (cx, cy), seeds, flips)| {
            let (x1, y1) = (x0 + w, y0 + h);
            let perimeter = 2 * (w + h) as u64;
            let mut ts: Vec<u64> = seeds.iter().map(|s| s % perimeter).collect();
            ts.extend([0, w as u64, (w + h) as u64, (2 * w + h) as u64]);
            ts.sort_unstable();
            ts.dedup();
            let point = |t: u64| {
                let t = t as i64;
                if t < w {
                    [x0 + t, y0]
                } else if t < w + h {
                    [x1, y0 + (t - w)]
                } else if t < 2 * w + h {
                    [x1 - (t - w - h), y1]
                } else {
                    [x0, y1 - (t - 2 * w - h)]
                }
            };
            Fan {
                rect: [x0, y0, x1, y1],
                centre: [
                    x0 + 1 + (cx % (w as u64 - 1)) as i64,
                    y0 + 1 + (cy % (h as u64 - 1)) as i64,
                ],
                rim: ts.into_iter().map(point).collect(),
                flips,
            }
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// A fan around an interior point tiles a rectangle; under the top-left rule the rectangle's
    /// covered samples are exactly the half-open `[x0, x1) x [y0, y1)` (its top and left sides in,
    /// bottom and right out), each exactly once. This implies "every centre strictly inside once,
    /// every centre outside never".
    #[test]
    fn a_fan_tiling_a_rectangle_covers_each_pixel_exactly_once(fan in fan()) {
        let (w, h) = (128, 128);
        let to_px = |p: [i64; 2]| [p[0] as f32 / 256.0, p[1] as f32 / 256.0];
        let n = fan.rim.len();
        let tris: Vec<Triangle<0>> = (0..n)
            .map(|i| {
                let (a, b) = (to_px(fan.rim[i]), to_px(fan.rim[(i + 1) % n]));
                let c = to_px(fan.centre);
                if fan.flips >> (i % 64) & 1 == 1 { tri([c, b, a], w, h) } else { tri([c, a, b], w, h) }
            })
            .collect();
        let (counts, _) = coverage(&tris, w, h);
        let [x0, y0, x1, y1] = fan.rect;
        for (i, &c) in counts.iter().enumerate() {
            let (x, y) = ((i as u32 % w) as i64, (i as u32 / w) as i64);
            let (sx, sy) = (x * 256 + 128, y * 256 + 128);
            let want = (x0 <= sx && sx < x1 && y0 <= sy && sy < y1) as u32;
            prop_assert_eq!(c, want, "pixel ({}, {})", x, y);
        }
    }
}

/// The perspective test scene: a camera 2 m above a ground quad `x in [x_near, 41]`,
/// `y in [-20, 20]` on `z = 0`, looking 11° down, with `u = (x - 1) / 40` as varying 0.
fn ground_scene(x_near: f32) -> (Camera, Vec<Triangle<2>>) {
    let camera = Camera::look_at([0.0, 0.0, 2.0], [10.0, 0.0, 0.0], 60.0, 128, 96);
    let vp = camera.view_projection();
    let v = |x: f32, y: f32| {
        let clip = vp * Vec4::new(x, y, 0.0, 1.0);
        Vertex::new(clip.to_array(), [(x - 1.0) / 40.0, (y + 20.0) / 40.0])
    };
    let (a, b, c, d) = (
        v(x_near, -20.0),
        v(41.0, -20.0),
        v(41.0, 20.0),
        v(x_near, 20.0),
    );
    (camera, vec![[a, b, c], [a, c, d]])
}

/// `u` where the ray through the centre of pixel `(x, y)` meets the ground (the closed form).
fn exact_u(camera: &Camera, x: f64, y: f64) -> f64 {
    let inv = DMat4::from_cols_array(&camera.view_projection().to_cols_array().map(|c| c as f64))
        .inverse();
    let (w, h) = (camera.width as f64, camera.height as f64);
    let ndc = [2.0 * (x + 0.5) / w - 1.0, 1.0 - 2.0 * (y + 0.5) / h];
    let unproject = |z: f64| {
        let p = inv * DVec4::new(ndc[0], ndc[1], z, 1.0);
        p.truncate() / p.w
    };
    let (p0, p1) = (unproject(0.0), unproject(1.0));
    let t = -p0.z / (p1.z - p0.z);
    (p0.x + t * (p1.x - p0.x) - 1.0) / 40.0
}

/// How far, in pixels, the rasterizer's interpolant may be displaced from the exact one: snapping
/// moves each vertex by at most 1/512 px per axis (≤ 0.0028 px), and the `f32` view-projection and
/// viewport transform add ~1e-4 px; 1/256 px covers both with margin.
const POSITION_TOLERANCE_PX: f64 = 1.0 / 256.0;
/// Absolute slack for `f32` rounding of `u` itself (`u <= 1`: a few ulps).
const VALUE_TOLERANCE: f64 = 1e-5;

fn check_perspective(x_near: f32) {
    let (camera, tris) = ground_scene(x_near);
    let (w, h) = (camera.width, camera.height);
    let shader = |f: &Fragment<2>| {
        Some(FragmentOutput {
            color: [f.ddx[0], f.ddy[0], 0.0, 1.0],
            id: f.varyings[0].to_bits(),
            depth: None,
        })
    };
    let clear = ClearValues {
        aux: u32::MAX,
        ..ClearValues::default()
    };
    let mut target = RenderTarget::new(w, h, clear);
    let stats = target.draw(&tris, &shader, &DrawState::OPAQUE);
    let mut checked = 0;
    let mut worst = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            let (xf, yf) = (x as f64, y as f64);
            let want = exact_u(&camera, xf, yf);
            let id = target.aux()[(y * w + x) as usize];
            if !(0.0..=1.0).contains(&want) || id == u32::MAX {
                // Off the quad or above the horizon; the quad's edges are checked for coverage
                // elsewhere.
                continue;
            }
            let got = f32::from_bits(id) as f64;
            let gx = (exact_u(&camera, xf + 1.0, yf) - exact_u(&camera, xf - 1.0, yf)) / 2.0;
            let gy = (exact_u(&camera, xf, yf + 1.0) - exact_u(&camera, xf, yf - 1.0)) / 2.0;
            let tol = POSITION_TOLERANCE_PX * (gx.abs() + gy.abs()) + VALUE_TOLERANCE;
            assert!(
                (got - want).abs() <= tol,
                "pixel ({x}, {y}): u = {got}, exact {want}, tolerance {tol}"
            );
            worst = worst.max((got - want).abs() / tol);
            checked += 1;
        }
    }
    // The ground fills the lower part of the screen up to the horizon.
    assert!(
        checked > (w * h / 3) as usize,
        "only {checked} pixels checked"
    );
    assert!(stats.fragments_written as usize >= checked);
    assert!(worst <= 1.0);
}

#[test]
fn perspective_correct_interpolation_matches_the_ray_plane_closed_form() {
    check_perspective(1.0);
}

#[test]
fn interpolation_stays_exact_after_near_plane_clipping() {
    // The quad starts behind the camera: the near plane cuts it and the fan pieces carry
    // clip-space-interpolated varyings.
    let (_, tris) = ground_scene(-5.0);
    let mut target = RenderTarget::new(128, 96, ClearValues::default());
    let none = |_: &Fragment<2>| None;
    let stats = target.draw(&tris, &none, &DrawState::OPAQUE);
    assert!(stats.triangles_clipped > 2, "{stats:?}");
    check_perspective(-5.0);
}

#[test]
fn coarse_derivatives_are_quad_differences() {
    let (w, h) = (64, 32);
    // Varyings equal to NDC x and y: affine on screen, so ddx = 2/w, ddy = -2/h (y down).
    let v = |x: f32, y: f32| Vertex::new([x, y, 0.5, 1.0], [x, y]);
    let quad = [
        [v(-1.0, -1.0), v(1.0, -1.0), v(1.0, 1.0)],
        [v(-1.0, -1.0), v(1.0, 1.0), v(-1.0, 1.0)],
    ];
    let seen = AtomicU32::new(0);
    let shader = |f: &Fragment<2>| {
        assert!((f.ddx[0] - 2.0 / w as f32).abs() < 1e-6, "{f:?}");
        assert!(f.ddx[1].abs() < 1e-6, "{f:?}");
        assert!(f.ddy[0].abs() < 1e-6, "{f:?}");
        assert!((f.ddy[1] + 2.0 / h as f32).abs() < 1e-6, "{f:?}");
        let want_x = 2.0 * (f.x as f32 + 0.5) / w as f32 - 1.0;
        assert!((f.varyings[0] - want_x).abs() < 1e-6, "{f:?}");
        seen.fetch_add(1, Ordering::Relaxed);
        None
    };
    RenderTarget::new(w, h, ClearValues::default()).draw(&quad, &shader, &DrawState::OPAQUE);
    assert_eq!(seen.into_inner(), w * h);
}

#[test]
fn derivatives_are_shared_by_the_quad_and_taken_at_its_top_left_pixel() {
    // u = x² along the screen would need per-pixel derivatives; coarse ones are the top row's
    // difference for all four pixels. Use a perspective plane where ddx varies per row.
    let (camera, tris) = ground_scene(1.0);
    let out = std::sync::Mutex::new(Vec::new());
    let shader = |f: &Fragment<2>| {
        out.lock()
            .unwrap()
            .push((f.x, f.y, f.varyings[0], f.ddx[0], f.ddy[0]));
        None
    };
    RenderTarget::new(camera.width, camera.height, ClearValues::default()).draw(
        &tris,
        &shader,
        &DrawState::OPAQUE,
    );
    let frags = out.into_inner().unwrap();
    let mut by_pixel = std::collections::HashMap::new();
    for &(x, y, u, dx, dy) in &frags {
        by_pixel.insert((x, y), (u, dx, dy));
    }
    let mut full_quads = 0;
    for &(x, y, _, dx, dy) in &frags {
        let (x0, y0) = (x & !1, y & !1);
        // Where the whole quad is covered, its own values give the expected differences.
        if let (Some(tl), Some(tr), Some(bl)) = (
            by_pixel.get(&(x0, y0)),
            by_pixel.get(&(x0 + 1, y0)),
            by_pixel.get(&(x0, y0 + 1)),
        ) {
            assert_eq!(dx, tr.0 - tl.0, "ddx at ({x}, {y})");
            assert_eq!(dy, bl.0 - tl.0, "ddy at ({x}, {y})");
            full_quads += 1;
        }
    }
    assert!(full_quads > 1000);
}

/// A full-screen quad at depth `z` whose fragments output `color` and id `id`.
fn flat_quad(z: f32) -> [Triangle<0>; 2] {
    let v = |x: f32, y: f32| Vertex::new([x, y, z, 1.0], []);
    [
        [v(-1.0, -1.0), v(1.0, -1.0), v(1.0, 1.0)],
        [v(-1.0, -1.0), v(1.0, 1.0), v(-1.0, 1.0)],
    ]
}

fn solid(color: [f32; 4], id: u32) -> impl Fn(&Fragment<0>) -> Option<FragmentOutput> + Sync {
    move |_| {
        Some(FragmentOutput {
            color,
            id,
            depth: None,
        })
    }
}

#[test]
fn depth_less_keeps_the_nearest_whatever_the_order_and_the_first_on_ties() {
    let (w, h) = (40, 24);
    let (red, green) = ([1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0]);
    for near_first in [true, false] {
        let mut t = RenderTarget::new(w, h, ClearValues::default());
        let near = (flat_quad(0.3), solid(red, 1));
        let far = (flat_quad(0.6), solid(green, 2));
        let (first, second) = if near_first {
            (&near, &far)
        } else {
            (&far, &near)
        };
        t.draw(&first.0, &first.1, &DrawState::OPAQUE);
        let stats = t.draw(&second.0, &second.1, &DrawState::OPAQUE);
        assert!(t.color().iter().all(|&c| c == [255, 0, 0, 255]));
        assert!(t.aux().iter().all(|&id| id == 1));
        assert!(t.depth().iter().all(|&d| d == 0.3));
        // The far quad drawn second is rejected before shading.
        let expect_shaded = if near_first { 0 } else { (w * h) as u64 };
        assert_eq!(stats.fragments_shaded, expect_shaded);
        assert_eq!(stats.fragments_covered, (w * h) as u64);
    }
    // Equal depth: LESS is strict, the first drawn stays, in separate draws and within one draw.
    let mut t = RenderTarget::new(w, h, ClearValues::default());
    t.draw(&flat_quad(0.5), &solid(red, 1), &DrawState::OPAQUE);
    t.draw(&flat_quad(0.5), &solid(green, 2), &DrawState::OPAQUE);
    assert!(t.aux().iter().all(|&id| id == 1));
    let mut t = RenderTarget::new(w, h, ClearValues::default());
    let both = [flat_quad(0.5), flat_quad(0.5)].concat();
    let by_primitive = |f: &Fragment<0>| {
        Some(FragmentOutput {
            color: [1.0; 4],
            id: f.primitive_id,
            depth: None,
        })
    };
    t.draw(&both, &by_primitive, &DrawState::OPAQUE);
    assert!(
        t.aux().iter().all(|&id| id < 2),
        "the first quad (primitives 0, 1) wins"
    );
}

#[test]
fn depth_write_off_and_discard_leave_depth_alone() {
    let (w, h) = (16, 16);
    let mut t = RenderTarget::new(w, h, ClearValues::default());
    let no_write = DrawState {
        depth_write: false,
        ..DrawState::OPAQUE
    };
    t.draw(&flat_quad(0.2), &solid([1.0; 4], 1), &no_write);
    assert!(t.depth().iter().all(|&d| d == 1.0));
    // Discard the left half: those pixels keep id 1 and depth 1.0.
    let half = |f: &Fragment<0>| {
        (f.x >= w / 2).then_some(FragmentOutput {
            color: [0.0, 0.0, 0.0, 1.0],
            id: 2,
            depth: None,
        })
    };
    let stats = t.draw(&flat_quad(0.7), &half, &DrawState::OPAQUE);
    assert_eq!(stats.fragments_shaded, (w * h) as u64);
    assert_eq!(stats.fragments_written, (w * h / 2) as u64);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let (id, d) = if x >= w / 2 { (2, 0.7) } else { (1, 1.0) };
            assert_eq!((t.aux()[i], t.depth()[i]), (id, d), "({x}, {y})");
        }
    }
    // Without the depth test (compare Always) a farther quad still lands, and writes its depth.
    let always = DrawState {
        depth_test: false,
        ..DrawState::OPAQUE
    };
    t.draw(&flat_quad(0.9), &solid([1.0; 4], 3), &always);
    assert!(t.aux().iter().all(|&id| id == 3));
    assert!(t.depth().iter().all(|&d| d == 0.9));
}

#[test]
fn alpha_blending_is_source_over_in_linear_light_quantized_per_fragment() {
    let blue = ClearValues {
        color: [0.0, 0.0, 1.0, 1.0],
        ..ClearValues::default()
    };
    let mut t = RenderTarget::new(8, 8, blue);
    let state = DrawState::TRANSPARENT;
    t.draw(&flat_quad(0.5), &solid([1.0, 0.0, 0.0, 0.5], 7), &state);
    let once = [linear_to_srgb(0.5), 0, linear_to_srgb(0.5), 255];
    assert!(t.color().iter().all(|&c| c == once), "{:?}", t.color()[0]);
    // A second layer blends with the *stored* (sRGB8-quantized) destination.
    t.draw(&flat_quad(0.5), &solid([1.0, 0.0, 0.0, 0.5], 7), &state);
    let d = srgb_to_linear(once[0]);
    let twice = [
        linear_to_srgb(0.5 + d * 0.5),
        0,
        linear_to_srgb(srgb_to_linear(once[2]) * 0.5),
        255,
    ];
    assert!(t.color().iter().all(|&c| c == twice), "{:?}", t.color()[0]);
    // Over transparent black, alpha accumulates as a + d.a (1 - a).
    let mut t = RenderTarget::new(8, 8, ClearValues::default());
    t.draw(&flat_quad(0.5), &solid([1.0, 1.0, 1.0, 0.5], 7), &state);
    assert_eq!(t.color()[0][3], unorm8(0.5));
    assert!(
        t.depth().iter().all(|&d| d == 1.0),
        "TRANSPARENT writes no depth"
    );
}

#[test]
fn facing_and_culling_follow_wgpu_conventions() {
    let (w, h) = (16, 16);
    let v = |x: f32, y: f32| Vertex::new([x, y, 0.5, 1.0], []);
    // Counter-clockwise in NDC with y up.
    let ccw = [v(-1.0, -1.0), v(1.0, -1.0), v(-1.0, 1.0)];
    let cw = [ccw[0], ccw[2], ccw[1]];
    let facing = |tri: Triangle<0>, state: DrawState| {
        let mut t = RenderTarget::new(w, h, ClearValues::default());
        let shader = |f: &Fragment<0>| {
            Some(FragmentOutput {
                color: [1.0; 4],
                id: 1 + f.front_facing as u32,
                depth: None,
            })
        };
        t.draw(&[tri], &shader, &state);
        t.aux()[(h - 1) as usize * w as usize] // bottom-left pixel: inside both
    };
    let s = DrawState::OPAQUE;
    assert_eq!(facing(ccw, s), 2, "CCW is front-facing");
    assert_eq!(facing(cw, s), 1, "CW is back-facing");
    let back = DrawState {
        cull: CullMode::Back,
        ..s
    };
    assert_eq!((facing(ccw, back), facing(cw, back)), (2, 0));
    let front = DrawState {
        cull: CullMode::Front,
        ..s
    };
    assert_eq!((facing(ccw, front), facing(cw, front)), (0, 1));
    let cw_front = DrawState {
        front_face: FrontFace::Cw,
        ..s
    };
    assert_eq!((facing(ccw, cw_front), facing(cw, cw_front)), (1, 2));
}

/// A 32x32 chain whose every texel is distinct.
fn distinct_chain() -> Vec<Rgba8Image> {
    let mut levels = Vec::new();
    let mut size = 32;
    for level in 0u32.. {
        let mut img = Rgba8Image::new(size, size, [0; 4]);
        for (i, t) in img.texels.iter_mut().enumerate() {
            let i = i as u32;
            *t = [
                (i * 7 % 256) as u8,
                (i / 4 * 9 % 256) as u8,
                (level * 40) as u8,
                255,
            ];
        }
        levels.push(img);
        if size == 1 {
            return levels;
        }
        size /= 2;
    }
    unreachable!()
}

/// A screen-aligned quad covering pixels `[0, size)²`, with `uv` from 0 to 1 (perspective: w = 2).
fn textured_quad(size: f32, w: u32, h: u32) -> Vec<Triangle<2>> {
    let v = |x: f32, y: f32, u: f32, t: f32| {
        let c = px(x, y, w, h);
        Vertex::new([2.0 * c[0], 2.0 * c[1], 2.0 * c[2], 2.0], [u, t])
    };
    let (a, b, c, d) = (
        v(0.0, 0.0, 0.0, 0.0),
        v(size, 0.0, 1.0, 0.0),
        v(size, size, 1.0, 1.0),
        v(0.0, size, 0.0, 1.0),
    );
    vec![[a, b, c], [a, c, d]]
}

#[test]
fn a_textured_triangle_list_reproduces_the_texture_at_one_and_two_texels_per_pixel() {
    let tex = Texture::new(distinct_chain()).unwrap();
    for (size, level) in [(32u32, 0usize), (16, 1), (8, 2)] {
        let (w, h) = (64, 64);
        let shader = |f: &Fragment<2>| {
            let uv = [f.varyings[0], f.varyings[1]];
            let lod = tex.lod([f.ddx[0], f.ddx[1]], [f.ddy[0], f.ddy[1]]);
            let color = tex.sample(
                &Sampler::NEAREST,
                0,
                uv,
                [f.ddx[0], f.ddx[1]],
                [f.ddy[0], f.ddy[1]],
            );
            Some(FragmentOutput {
                color,
                id: lod.lambda.to_bits(),
                depth: None,
            })
        };
        let mut t = RenderTarget::new(w, h, ClearValues::default());
        t.draw(
            &textured_quad(size as f32, w, h),
            &shader,
            &DrawState::OPAQUE,
        );
        let want = tex.level(0, level);
        let img = t.color_image();
        for y in 0..h {
            for x in 0..w {
                let got = img.get(x, y);
                if x < size && y < size {
                    assert_eq!(got, want.get(x, y), "size {size}: ({x}, {y})");
                    let lambda = f32::from_bits(t.aux()[(y * w + x) as usize]);
                    assert!((lambda - level as f32).abs() < 1e-5, "λ = {lambda}");
                } else {
                    assert_eq!(got, [0; 4], "size {size}: ({x}, {y}) outside");
                }
            }
        }
    }
}

/// A random scene: triangles anywhere around the view (some clipped by the near and far planes),
/// blended and alpha-tested so the result depends on order.
fn scene() -> impl Strategy<Value = Vec<Triangle<3>>> {
    let vertex = (
        -1.5f32..1.5,
        -1.5f32..1.5,
        -0.3f32..1.2,
        0.2f32..3.0,
        (0.0f32..1.0, 0.0f32..1.0, 0.0f32..1.0),
    )
        .prop_map(|(x, y, z, w, (r, g, a))| Vertex::new([x * w, y * w, z * w, w], [r, g, a]));
    prop::collection::vec([vertex.clone(), vertex.clone(), vertex], 300..400)
}

fn render_scene(tris: &[Triangle<3>], threads: usize) -> (RenderTarget, DrawStats) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut t = RenderTarget::new(200, 150, ClearValues::default());
        let shader = |f: &Fragment<3>| {
            let [r, g, a] = f.varyings;
            (a > 0.15).then_some(FragmentOutput {
                color: [r, g, (f.ddx[0] * 50.0).abs(), a],
                id: f.primitive_id,
                depth: None,
            })
        };
        let mut stats = t.draw(&tris[..tris.len() / 2], &shader, &DrawState::OPAQUE);
        stats += t.draw(&tris[tris.len() / 2..], &shader, &DrawState::TRANSPARENT);
        (t, stats)
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(6))]

    /// Screen tiles own their pixels and process triangles in submission order, so the thread
    /// count cannot change a single bit.
    #[test]
    fn output_is_bit_identical_for_any_thread_count(tris in scene()) {
        let (one, s1) = render_scene(&tris, 1);
        let (two, s2) = render_scene(&tris, 2);
        let (three, s3) = render_scene(&tris, 3);
        prop_assert!(s1.fragments_written > 0);
        prop_assert_eq!(s1, s2);
        prop_assert_eq!(s1, s3);
        prop_assert!(one.color() == two.color() && one.color() == three.color());
        prop_assert!(one.aux() == two.aux() && one.aux() == three.aux());
        let bits = |t: &RenderTarget| t.depth().iter().map(|d| d.to_bits()).collect::<Vec<_>>();
        prop_assert!(bits(&one) == bits(&two) && bits(&one) == bits(&three));
    }
}

/// A shader-written depth (`FragmentOutput::depth`, SPIR-V `FragDepth` under `DepthGreater`)
/// replaces the interpolated one: it is clamped to `[0, 1]`, tested again with LESS and written;
/// NaN discards. This is what the *Primitive* baseline's ray-cast quads rely on (E§5).
#[test]
fn shader_written_depth_is_clamped_tested_and_written() {
    let (w, h) = (8, 8);
    let mut t = RenderTarget::new(w, h, ClearValues::default());
    // A wall at depth 0.5 on the right half only.
    let right = |f: &Fragment<0>| {
        (f.x >= w / 2).then_some(FragmentOutput {
            color: [1.0; 4],
            id: 1,
            depth: None,
        })
    };
    t.draw(&flat_quad(0.5), &right, &DrawState::OPAQUE);
    // A quad interpolated at 0.1 whose shader pushes depth back: rows 0-1 to 0.3 (in front of the
    // wall), rows 2-3 to 0.8 (behind it), rows 4-5 to 2.0 (clamped to 1.0: behind the wall, and
    // not below the cleared 1.0 on the left, so not written there either), rows 6-7 NaN
    // (discarded).
    let pushed = |f: &Fragment<0>| {
        let depth = match f.y / 2 {
            0 => 0.3,
            1 => 0.8,
            2 => 2.0,
            _ => f32::NAN,
        };
        Some(FragmentOutput {
            color: [0.0, 0.0, 0.0, 1.0],
            id: 2,
            depth: Some(depth),
        })
    };
    let stats = t.draw(&flat_quad(0.1), &pushed, &DrawState::OPAQUE);
    assert_eq!(stats.fragments_shaded, (w * h) as u64);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let wall = x >= w / 2;
            let expected = match y / 2 {
                0 => (2, 0.3),
                1 if !wall => (2, 0.8),
                _ if wall => (1, 0.5),
                _ => (0, 1.0),
            };
            assert_eq!((t.aux()[i], t.depth()[i]), expected, "({x}, {y})");
        }
    }
    // Written: all of rows 0-1, the left half of rows 2-3.
    assert_eq!(stats.fragments_written, (2 * w + w / 2 * 2) as u64);
}
