//! An oracle for the ground truth (issue 36, class 1; `reference/src/ground_truth.rs`): analytic
//! scenes whose images are known exactly, so that the truth's sample positions, its box filter and
//! its classification are judged by something other than themselves.
//!
//! ## The scenes
//! One "tree" whose mesh is a planar convex polygon in the plane `y = 0`, textured with one opaque
//! uniform colour (alpha 255, so the alpha test accepts every hit), seen head-on by a pinhole
//! camera at `(0, -D, EYE_Z)` looking along +Y (right +X, up +Z). The ground (flat, at `z = 0`)
//! lies below the far plane's reach (module constants), so every ray sees the polygon or the sky.
//! The projection is derived here, independently of `primary_ray`: a point `(x, 0, z)` lies at
//! view depth `D` and lands at
//! `fx = W/2 · (1 + x / (D tan(fovx/2)))`, `fy = H/2 · (1 - (z - EYE_Z) / (D tan(fovy/2)))`, with
//! `tan(fovx/2) = tan(fovy/2) · W/H` (square pixels). A plane parallel to the image plane maps
//! affinely, so the projected polygon is the polygon of the projected (`f32`) mesh vertices.
//! Shapes: a square aligned to the pixel grid, a square at subpixel positions, a regular 21-gon
//! (the disc: the oracle is the polygon itself), a half-plane whose edge is the pixel column line
//! `fx = 30.5`, and a slanted half-plane (each half-plane one big triangle whose other edges lie
//! far outside the frame, so no internal edge crosses the frame).
//!
//! ## What is checked, per pixel, for `s` = 3, 4 (the default) and 5 samples per side
//! - **Coverage within the ordered grid's sampling error.** The exact coverage `A` of the pixel by
//!   the projected polygon is its Sutherland–Hodgman clip against the pixel square (`f64`),
//!   measured by the shoelace formula. The truth's `tree_fraction` is exact in every `1/s x 1/s`
//!   sub-cell the polygon's boundary does not cross (its one sample, at the cell's centre, sees
//!   what the whole cell holds), so `|fraction - A| <= crossed / s²`, where a sub-cell is crossed
//!   when its clipped area lies strictly between 0 and the cell's area (same clipper; up to
//!   [`SLIVER`], see there).
//! - **Sample positions.** The truth's tree count equals the number of the definition's sample
//!   points `(x + (i + 0.5)/s, y + (j + 0.5)/s)` inside the polygon, except for points within
//!   [`AMBIGUOUS_PX`] of its **outer** boundary, which may fall either way (a genuine tie between
//!   the polygon and the sky; counted and reported: none here). Points on an edge that two of
//!   its triangles share are inside: they must hit (next section).
//! - **Colour**: the linear pixel is `fraction · c + (1 - fraction) · sky` ([`COLOUR_TOLERANCE`]).
//! - **Class**: tree when `2 · count >= s²`, else sky; never ground.
//!
//! ## Shared edges
//! The polygon is closed: a sample on an edge that two of its triangles share lies inside it and
//! must hit one of them. The truth's ray–triangle test is watertight (Woop, Benthin, Wald 2013;
//! `intersect_triangle`), so the oracle allows no slack there: such samples count as inside in
//! the sample-position check and nothing is added to the coverage bound for them. The
//! pixel-aligned square's diagonal runs through samples exactly (`27·s` of them, asserted), so it
//! is the case that would show a gap. The Möller–Trumbore test the truth used before leaked sky
//! there (9 of 81 diagonal samples at `s = 3`, 8 of 108 at 4, 6 of 135 at 5), which this oracle
//! now fails.
//!
//! Each test prints the largest `|fraction - A|` it saw beside the bound there.

use forestlod_reference::draw::SKY_SRGB;
use forestlod_reference::ground_truth::{
    DEFAULT_SAMPLES_PER_AXIS, GroundTruthImage, GroundTruthScene, PixelClass,
};
use forestlod_reference::scene::{Instance, Scene, Terrain, TreeMesh, footprint};
use forestlod_reference::texture::{Rgba8Image, srgb_to_linear};
use forestlod_shared::Camera;

/// Frame size, pixels.
const W: u32 = 64;
const H: u32 = 48;
/// Vertical field of view, degrees.
const FOV_Y_DEGREES: f32 = 60.0;
/// The polygon's view depth, metres.
const D: f64 = 10.0;
/// Eye height, metres: the lowest ray of the frame falls `tan(30°) ≈ 0.58` m per metre of depth,
/// so within [`FAR`] it stays above `EYE_Z - 0.58 · FAR ≈ 71` m, far over the ground at 0.
const EYE_Z: f64 = 100.0;
/// The far plane, metres: beyond the polygon, short of the ground.
const FAR: f32 = 50.0;
/// The polygon's texture colour (sRGB8, opaque).
const COLOUR: [u8; 4] = [200, 60, 30, 255];
/// Samples per pixel side exercised: the default and one odd count either side of it.
const SAMPLE_COUNTS: [u32; 3] = [3, DEFAULT_SAMPLES_PER_AXIS, 5];

/// A sub-cell piece (or the complement of one) smaller than `SLIVER` of the cell's area does not
/// count as crossing it, and the coverage bound allows `SLIVER` on top per pixel (at most `s²`
/// such pieces of `SLIVER / s²` each). Such a piece cannot hold the cell's centre sample: a piece
/// of these convex shapes (corners of 90° or more, edges straight across a cell) that holds the
/// centre holds at least a quarter of the cell. What it absorbs: the `f32` rounding of the mesh
/// vertices, which moves an edge placed on a pixel or sub-cell line by ~1e-6 px (1e-6 · s of a
/// cell's area at most), and the shoelace formula's `f64` rounding.
const SLIVER: f64 = 1e-4;

/// Sample points this close to the polygon's outer boundary (pixels) may fall on either side (an
/// edge two of its triangles share gets no such slack: the surface is closed): the truth sets up
/// its rays in `f32` (tan, basis, NDC) and intersects in `f32`, which places an edge within
/// ~1e-5 px of where this file's `f64` projection puts it at this resolution. 1e-3 px leaves a
/// margin of 100, and is far below the distance `1/(2s) >= 0.1` px from a sample to its sub-cell's
/// border.
const AMBIGUOUS_PX: f64 = 1e-3;

/// Linear colour tolerance: the texture's bilinear weights sum to 1 only up to `f32` rounding (a
/// few ulps of the colour), and the `f64` mean is rounded once to `f32` (half an ulp); 1e-6 is
/// about 8 ulps of 1.0. A wrong filter weight is off by at least `1/(s² + 1)` of the colour
/// difference between the polygon and the sky (> 0.01 here).
const COLOUR_TOLERANCE: f64 = 1e-6;

type P = [f64; 2];

/// The camera of the module docs.
fn camera() -> Camera {
    Camera {
        eye: [0.0, -D as f32, EYE_Z as f32],
        fov_y: FOV_Y_DEGREES.to_radians(),
        forward: [0.0, 1.0, 0.0],
        near: 0.5,
        up: [0.0, 0.0, 1.0],
        far: FAR,
        width: W,
        height: H,
        tile: [0, 0],
    }
}

/// `(tan(fovx/2), tan(fovy/2))` of the camera, in `f64`.
fn tangents(camera: &Camera) -> (f64, f64) {
    let ty = (camera.fov_y as f64 * 0.5).tan();
    (ty * W as f64 / H as f64, ty)
}

/// Framebuffer position of the world point `(x, 0, z)` (module docs).
fn to_pixel(camera: &Camera, x: f64, z: f64) -> P {
    let (tx, ty) = tangents(camera);
    [
        W as f64 / 2.0 * (1.0 + x / (D * tx)),
        H as f64 / 2.0 * (1.0 - (z - EYE_Z) / (D * ty)),
    ]
}

/// The world point `(x, 0, z)` that lands at framebuffer position `p`: the inverse of
/// [`to_pixel`].
fn to_world(camera: &Camera, p: P) -> (f64, f64) {
    let (tx, ty) = tangents(camera);
    (
        (2.0 * p[0] / W as f64 - 1.0) * D * tx,
        EYE_Z - (2.0 * p[1] / H as f64 - 1.0) * D * ty,
    )
}

/// A scene of one tree at the origin whose mesh is the convex polygon `pixels` (framebuffer
/// positions, either orientation) placed in the plane `y = 0`, fan-triangulated from its first
/// vertex; and that polygon as the truth will see it: its `f32` vertices projected back, counter-
/// clockwise in framebuffer coordinates, with the fan's shared (interior) edges.
fn polygon_scene(name: &str, camera: &Camera, pixels: &[P]) -> (Scene, Vec<P>, Vec<[P; 2]>) {
    let positions: Vec<[f32; 3]> = pixels
        .iter()
        .map(|&p| {
            let (x, z) = to_world(camera, p);
            [x as f32, 0.0, z as f32]
        })
        .collect();
    let n = positions.len() as u32;
    let indices = (1..n - 1).flat_map(|k| [0, k, k + 1]).collect();
    let mesh = TreeMesh {
        name: name.into(),
        uvs: vec![[0.5, 0.5]; positions.len()],
        positions: positions.clone(),
        indices,
        texture: Rgba8Image::new(4, 4, COLOUR),
    };
    let tree = Instance {
        position: [0.0; 3],
        yaw: 0.0,
        scale: 1.0,
        mesh: 0,
    };
    let scene = Scene {
        name: name.into(),
        origin: [0.0; 3],
        meshes: vec![mesh],
        instances: vec![tree],
        terrain: Terrain::Flat { z: 0.0 },
        bounds: footprint([tree.position]),
    };
    scene.validate(name).expect("the analytic scene is valid");
    let mut poly: Vec<P> = positions
        .iter()
        .map(|p| to_pixel(camera, p[0] as f64, p[2] as f64))
        .collect();
    let shared = (2..poly.len() - 1).map(|k| [poly[0], poly[k]]).collect();
    if signed_area(&poly) < 0.0 {
        poly.reverse();
    }
    (scene, poly, shared)
}

/// Distance (pixels) of `p` from the segment `[a, b]`.
fn segment_distance([a, b]: [P; 2], p: P) -> f64 {
    let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
    let t = (((p[0] - a[0]) * ex + (p[1] - a[1]) * ey) / (ex * ex + ey * ey)).clamp(0.0, 1.0);
    ((p[0] - a[0] - t * ex).powi(2) + (p[1] - a[1] - t * ey).powi(2)).sqrt()
}

/// The signed area of a polygon (shoelace): positive when its vertices run counter-clockwise in
/// framebuffer coordinates read as a plain x/y plane.
fn signed_area(poly: &[P]) -> f64 {
    let n = poly.len();
    (0..n)
        .map(|k| {
            let (a, b) = (poly[k], poly[(k + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        * 0.5
}

/// Sutherland–Hodgman: the part of the convex polygon `poly` inside the rectangle
/// `[x0, y0, x1, y1]`.
fn clip(poly: &[P], [x0, y0, x1, y1]: [f64; 4]) -> Vec<P> {
    let mut out = poly.to_vec();
    for (axis, bound, keep_above) in [(0, x0, true), (0, x1, false), (1, y0, true), (1, y1, false)]
    {
        let input = std::mem::take(&mut out);
        let inside = |p: &P| {
            if keep_above {
                p[axis] >= bound
            } else {
                p[axis] <= bound
            }
        };
        for k in 0..input.len() {
            let (prev, cur) = (input[(k + input.len() - 1) % input.len()], input[k]);
            if inside(&cur) != inside(&prev) {
                let t = (bound - prev[axis]) / (cur[axis] - prev[axis]);
                let mut q = [
                    prev[0] + t * (cur[0] - prev[0]),
                    prev[1] + t * (cur[1] - prev[1]),
                ];
                q[axis] = bound;
                out.push(q);
            }
            if inside(&cur) {
                out.push(cur);
            }
        }
    }
    out
}

/// Area of the part of `poly` inside the rectangle.
fn covered(poly: &[P], rect: [f64; 4]) -> f64 {
    let c = clip(poly, rect);
    if c.len() < 3 {
        0.0
    } else {
        signed_area(&c).abs()
    }
}

/// Signed distance (pixels) of `p` from the counter-clockwise convex polygon's boundary: the least
/// over its edges, positive inside.
fn inside_distance(poly: &[P], p: P) -> f64 {
    let n = poly.len();
    (0..n)
        .map(|k| {
            let (a, b) = (poly[k], poly[(k + 1) % n]);
            let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
            // Counter-clockwise with y down read as a plain plane: the interior is to the left.
            (ex * (p[1] - a[1]) - ey * (p[0] - a[0])) / (ex * ex + ey * ey).sqrt()
        })
        .fold(f64::INFINITY, f64::min)
}

/// What one scene's check measured.
#[derive(Debug, Default)]
struct Measured {
    /// Largest `|fraction - exact coverage|` over the pixels, and the bound at that pixel.
    worst: (f64, f64),
    /// Largest per-pixel bound.
    largest_bound: f64,
    /// Pixels the boundary crosses (0 < coverage < 1).
    edge_pixels: usize,
    /// Sample points within `AMBIGUOUS_PX` of the polygon's boundary.
    ambiguous: usize,
    /// Sample points inside, within `AMBIGUOUS_PX` of an edge two of its triangles share (they
    /// must hit, like every point inside).
    on_shared: usize,
    /// Pixels classed tree.
    tree_pixels: usize,
}

/// Renders the polygon scene with `s` samples per side and checks every pixel (module docs).
fn check(name: &str, pixels: &[P], s: u32) -> (Measured, GroundTruthImage) {
    let camera = camera();
    camera.validate().expect("valid camera");
    let (scene, poly, shared) = polygon_scene(name, &camera, pixels);
    let truth = GroundTruthScene::build(&scene, 0.5).expect("the truth builds");
    let image = truth.render(&camera, s);
    assert_eq!(
        (image.width, image.height, image.samples_per_axis),
        (W, H, s)
    );
    let c = COLOUR.map(|v| srgb_to_linear(v) as f64);
    let sky = SKY_SRGB.map(|v| srgb_to_linear(v) as f64);
    let n = (s * s) as f64;
    let cell = 1.0 / s as f64;
    let mut m = Measured::default();
    for y in 0..H {
        for x in 0..W {
            let at = (y * W + x) as usize;
            let (xf, yf) = (x as f64, y as f64);
            let exact = covered(&poly, [xf, yf, xf + 1.0, yf + 1.0]);
            let fraction = image.tree_fraction[at] as f64;
            // The fraction is a whole number of samples over s², divided in f32.
            let count = (fraction * n).round() as u32;
            assert_eq!(
                image.tree_fraction[at],
                count as f32 / (s * s) as f32,
                "{name} s={s} ({x}, {y}): fraction {fraction} is no count of samples"
            );

            // Coverage within the ordered grid's sampling error.
            let mut crossed = 0u32;
            if exact > 0.0 && exact < 1.0 {
                m.edge_pixels += 1;
                for j in 0..s {
                    for i in 0..s {
                        let (cx, cy) = (xf + i as f64 * cell, yf + j as f64 * cell);
                        let a = covered(&poly, [cx, cy, cx + cell, cy + cell]) / (cell * cell);
                        crossed += (a > SLIVER && a < 1.0 - SLIVER) as u32;
                    }
                }
            }
            // The definition's sample points inside the polygon.
            let (mut inside, mut ambiguous, mut on_shared) = (0u32, 0u32, 0u32);
            for j in 0..s {
                for i in 0..s {
                    let p = [
                        xf + (i as f64 + 0.5) / s as f64,
                        yf + (j as f64 + 0.5) / s as f64,
                    ];
                    let d = inside_distance(&poly, p);
                    if d.abs() <= AMBIGUOUS_PX {
                        ambiguous += 1;
                    } else if d > 0.0 {
                        // Inside, shared edges included: the surface is closed (module docs).
                        inside += 1;
                        on_shared += shared
                            .iter()
                            .any(|&e| segment_distance(e, p) <= AMBIGUOUS_PX)
                            as u32;
                    }
                }
            }
            m.ambiguous += ambiguous as usize;
            m.on_shared += on_shared as usize;
            assert!(
                count >= inside && count <= inside + ambiguous,
                "{name} s={s} pixel ({x}, {y}): {count} samples hit the polygon, but {inside} \
                 of the pattern's points lie inside it ({on_shared} of them on an edge shared by \
                 two of its triangles, which must hit) and {ambiguous} on its outer boundary"
            );

            // Coverage within the ordered grid's sampling error (no slack for shared edges).
            let bound = crossed as f64 / n + SLIVER;
            let err = (fraction - exact).abs();
            assert!(
                err <= bound,
                "{name} s={s} pixel ({x}, {y}): tree fraction {fraction} vs exact coverage \
                 {exact:.6}: off by {err:.6} > the bound {bound:.6} ({crossed} crossed sub-cells, \
                 {on_shared} samples on a shared edge)"
            );
            if err > m.worst.0 {
                m.worst = (err, bound);
            }
            m.largest_bound = m.largest_bound.max(bound);

            // Colour: the box filter of `count` polygon samples and the rest sky.
            let linear = image.linear[at];
            for k in 0..3 {
                let want = fraction * c[k] + (1.0 - fraction) * sky[k];
                assert!(
                    (linear[k] as f64 - want).abs() <= COLOUR_TOLERANCE,
                    "{name} s={s} pixel ({x}, {y}) channel {k}: linear {} vs {want} for \
                     fraction {fraction} (difference {:e})",
                    linear[k],
                    (linear[k] as f64 - want).abs()
                );
            }

            // Class: tree from half the samples on; the rest is sky.
            let want = if 2 * count >= s * s {
                PixelClass::Tree
            } else {
                PixelClass::Sky
            };
            assert_eq!(
                image.class[at],
                want,
                "{name} s={s} pixel ({x}, {y}): {count} of {} samples on the polygon",
                s * s
            );
            m.tree_pixels += (want == PixelClass::Tree) as usize;
        }
    }
    println!(
        "{name} s={s}: largest |fraction - exact| {:.6} (bound there {:.6}), largest bound {:.6}, \
         {} edge pixels, {} tree pixels, {} samples on the outer boundary, {} on a shared edge \
         (all hit)",
        m.worst.0,
        m.worst.1,
        m.largest_bound,
        m.edge_pixels,
        m.tree_pixels,
        m.ambiguous,
        m.on_shared
    );
    assert!(
        m.tree_pixels > 0 && m.edge_pixels > 0,
        "{name}: nothing seen"
    );
    (m, image)
}

/// An axis-aligned rectangle `[x0, y0, x1, y1]` in framebuffer positions.
fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<P> {
    vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
}

/// A half-plane as one big triangle: the points to the left of the line through `p` along the
/// angle `theta` (radians, framebuffer axes), out to `L` pixels, so its other edges pass at
/// `L/√2` from `p`, far outside the frame.
fn half_plane(p: P, theta: f64) -> Vec<P> {
    const L: f64 = 400.0;
    let (dx, dy) = (theta.cos(), theta.sin());
    vec![
        [p[0] - L * dx, p[1] - L * dy],
        [p[0] + L * dx, p[1] + L * dy],
        [p[0] - L * dy, p[1] + L * dx],
    ]
}

/// A square aligned with the pixel grid: every pixel is wholly in or out, so the truth's image is
/// exactly 0 or 1 everywhere (no crossed sub-cells, the bound is `SLIVER`), the samples on the
/// diagonal its two triangles share included: none may leak (module docs, *Shared edges*).
/// Mutation-checked: the truth's old Möller–Trumbore leaf test fails it (see the report in
/// `reference/src/ground_truth.rs`'s `intersect_triangle`).
#[test]
fn a_pixel_aligned_square_is_exact() {
    for s in SAMPLE_COUNTS {
        let (m, _) = check("aligned-square", &rect(10.0, 7.0, 37.0, 34.0), s);
        // Its diagonal (the edge its two triangles share) runs through the samples with i = j.
        assert_eq!(m.on_shared, 27 * s as usize, "{m:?}");
    }
}

/// A square whose edges lie at subpixel positions, off the sample rows and columns of every `s`.
#[test]
fn a_subpixel_square_is_its_coverage_within_the_sampling_error() {
    for s in SAMPLE_COUNTS {
        let (m, _) = check("subpixel-square", &rect(17.37, 9.61, 40.79, 33.03), s);
        assert_eq!((m.ambiguous, m.on_shared), (0, 0), "{m:?}");
    }
}

/// A disc: the regular 21-gon (the most sides a tree mesh's 19 triangles allow), radius 14.2 px.
#[test]
fn a_disc_is_its_coverage_within_the_sampling_error() {
    let disc: Vec<P> = (0..21)
        .map(|k| {
            let a = 0.3 + k as f64 * std::f64::consts::TAU / 21.0;
            [31.7 + 14.2 * a.cos(), 23.4 + 14.2 * a.sin()]
        })
        .collect();
    for s in SAMPLE_COUNTS {
        check("disc", &disc, s);
    }
}

/// A half-plane whose edge is the line `fx = 30.5`: column 30's pixels are half covered, and for
/// even `s` exactly half their samples lie on the polygon, so they are tree pixels (the rule's
/// boundary, in a rendered image). For odd `s` the middle sample column lies on the edge itself
/// and may fall either way.
#[test]
fn a_half_plane_at_a_half_pixel_is_half_covered() {
    // Pointing up the frame (-y): the polygon is to the left in a plain x/y plane, +x here.
    let plane = half_plane([30.5, 24.0], -std::f64::consts::FRAC_PI_2);
    for s in SAMPLE_COUNTS {
        let (m, image) = check("half-plane", &plane, s);
        for y in 0..H {
            let at = (y * W + 30) as usize;
            if s % 2 == 0 {
                assert_eq!(image.tree_fraction[at], 0.5, "s={s} row {y}");
                assert_eq!(image.class[at], PixelClass::Tree, "s={s} row {y}");
            }
        }
        assert_eq!(m.edge_pixels, H as usize, "{m:?}");
    }
}

/// A half-plane with a slanted edge (17° off the x axis) through a subpixel point.
#[test]
fn a_slanted_half_plane_is_its_coverage_within_the_sampling_error() {
    let plane = half_plane([29.37, 21.81], 17f64.to_radians());
    for s in SAMPLE_COUNTS {
        check("slanted-half-plane", &plane, s);
    }
}

/// The oracle's own geometry: the projection round-trips, the clipper measures a known pixel of a
/// triangle, and a polygon's coverage summed over all pixels is its area.
#[test]
fn the_oracle_geometry_is_right() {
    let camera = camera();
    for p in [[0.0, 0.0], [64.0, 48.0], [17.3, 40.1]] {
        let (x, z) = to_world(&camera, p);
        let q = to_pixel(&camera, x, z);
        assert!(
            (q[0] - p[0]).abs() < 1e-9 && (q[1] - p[1]).abs() < 1e-9,
            "{p:?} -> {q:?}"
        );
    }
    // The frame centre is straight ahead; the top edge is tan(fovy/2)·D above the eye.
    let (x, z) = to_world(&camera, [32.0, 0.0]);
    assert!(x.abs() < 1e-12);
    // (fov_y is stored in f32: its tangent differs from tan(30°) by ~1e-8.)
    assert!((z - EYE_Z - D * (30f64).to_radians().tan()).abs() < 1e-6);
    // The triangle x, y >= 0, x + y <= 2 holds the pixel [0,1]² wholly, half of [1,2]x[0,1], and
    // only the corner (1, 1) of [1,2]².
    let tri = vec![[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]];
    assert!((covered(&tri, [0.0, 0.0, 1.0, 1.0]) - 1.0).abs() < 1e-15);
    assert!((covered(&tri, [1.0, 0.0, 2.0, 1.0]) - 0.5).abs() < 1e-15);
    assert_eq!(covered(&tri, [1.0, 1.0, 2.0, 2.0]), 0.0);
    let disc: Vec<P> = (0..21)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 21.0;
            [31.7 + 14.2 * a.cos(), 23.4 + 14.2 * a.sin()]
        })
        .collect();
    let total: f64 = (0..H)
        .flat_map(|y| (0..W).map(move |x| (x as f64, y as f64)))
        .map(|(x, y)| covered(&disc, [x, y, x + 1.0, y + 1.0]))
        .sum();
    assert!((total - signed_area(&disc).abs()).abs() < 1e-9, "{total}");
}
