//! Issue 32's octahedral impostors (`forestlod_shared::octahedral`) on the reference:
//! - the default (elevation views) is untouched: the goldens hold today's frame
//!   (`goldens::reference_matches_goldens`), and a frame drawn with octahedral parameters set but
//!   elevation views is bit-identical to the default's;
//! - **a freshly baked frame seen from its own direction reproduces the direct render of the
//!   tree**: one tree, turned by a yaw, seen from far away along a frame's direction, drawn as
//!   meshes and as impostors; the tree's silhouettes must agree (pixels covered by one and not the
//!   other, over the pixels covered by either, at most [`SILHOUETTE_XOR_MAX`]) and so must its
//!   colours where both cover (mean absolute sRGB difference at most [`COLOR_MEAN_MAX`]);
//! - under the blend, an eye between frames still reproduces the tree (the re-projection puts each
//!   frame's content where the nearest frame's is), within the same bounds widened by the
//!   in-between view's parallax ([`BLEND_XOR_MAX`]);
//! - a grid whose layers pass the array limit is a parameter error naming `octahedral_grid`.

use forestlod_harness::stage::images_of;
use forestlod_reference::draw::{LOD_ID_BILLBOARD, LOD_ID_MESH};
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::{Scene, builtin, tree_sphere};
use forestlod_shared::{AzimuthMode, Camera, Params, ViewSphere, frame_direction};
use forestlod_tests::differing_pixels;

/// Largest share of silhouette pixels (covered by the mesh or the impostor, not both) over the
/// pixels either covers, for an eye on a frame's direction. The impostor is the mesh resampled
/// twice (baked at `r = 128` texels over the sphere's diameter, then drawn with trilinear mips and
/// the alpha test at 0.5), and the mesh's leaf cards are alpha-tested at their own texture's
/// resolution: the silhouettes differ along every leaf edge by up to a texel. Measured 0.06-0.20
/// over 70 poses of the five species (printed).
const SILHOUETTE_XOR_MAX: f64 = 0.25;

/// Largest mean absolute difference of the sRGB channels (0-255) where both cover. Measured
/// 0.9-5.4 on frames and 2.2-7.1 between them (printed: the bilinear bake and trilinear mips
/// average leaf texels).
const COLOR_MEAN_MAX: f64 = 12.0;

/// [`SILHOUETTE_XOR_MAX`] for an eye between frames under the blend: the plane re-projection puts
/// content at the sphere centre's depth, so a leaf a crown radius off that plane moves by about
/// `radius · angle` between frames (an 8×8 hemi grid's cells span about 13-26°). Measured
/// 0.15-0.34 over 24 poses (printed; the blend 0.02-0.07 below the nearest frame at each).
const BLEND_XOR_MAX: f64 = 0.42;

/// The grid of the in-between poses: 8×8 over the hemisphere.
const BETWEEN_GRID: u32 = 8;

/// The in-between poses' trees: species and yaw.
const BETWEEN_TREES: [(u32, f32); 3] = [(0, 0.3), (2, 1.1), (4, -0.6)];

/// The in-between poses' eyes (mesh-local directions): inside cells of the hemi grid, away from
/// the frames.
const BETWEEN_EYES: [[f32; 3]; 4] = [
    [0.6, 0.3, 0.5],
    [-0.4, 0.7, 0.35],
    [0.2, -0.8, 0.6],
    [0.9, 0.1, 0.2],
];

/// `single`'s spruce changed to species `mesh`, turned by `yaw`.
fn one_tree(mesh: u32, yaw: f32) -> Scene {
    let mut s = builtin::single();
    s.instances[0].mesh = mesh;
    s.instances[0].yaw = yaw;
    s
}

/// Every tree a mesh (`lod_levels = 1`), or every tree an octahedral impostor (the billboard band
/// ends at 2 m), with a draw distance beyond the camera.
fn params(impostor: bool, sphere: ViewSphere, grid: u32, blend: AzimuthMode) -> Params {
    with_depth(impostor, sphere, grid, blend, false)
}

/// [`params`] with the depth channel (issue 32) on or off.
fn with_depth(
    impostor: bool,
    sphere: ViewSphere,
    grid: u32,
    blend: AzimuthMode,
    depth: bool,
) -> Params {
    let p = Params {
        draw_distance: 100_000.0,
        texture_size: 128,
        billboard_views: sphere as u32,
        octahedral_grid: grid,
        octahedral_blend: blend as u32,
        octahedral_depth: u32::from(depth),
        ..Params::default()
    };
    if impostor {
        Params {
            lod1_transition: 2.0,
            fade_width: 1.0,
            ..p
        }
    } else {
        Params { lod_levels: 1, ..p }
    }
}

/// A camera 400 sphere radii from the tree's sphere centre along the world direction `dir`,
/// looking at the centre, with a field of view that makes the sphere's diameter about 128 pixels
/// (one bake texel a pixel).
fn camera_along(prepared: &Prepared, dir: [f32; 3]) -> Camera {
    let t = &prepared.scene.instances[0];
    let (c, r) = tree_sphere(t, &prepared.geometry.meshes[t.mesh as usize]);
    let dist = 400.0 * r;
    let eye = [
        c[0] + dir[0] * dist,
        c[1] + dir[1] * dist,
        c[2] + dir[2] * dist,
    ];
    // 2r over 128 of 160 pixels: tan(fov/2) = (r·160/128) / dist.
    let fov = 2.0 * ((r * 160.0 / 128.0) / dist).atan().to_degrees();
    Camera {
        far: 2.0 * dist,
        near: dist * 0.5,
        ..Camera::look_at(eye, c, fov, 160, 160)
    }
}

/// Silhouette XOR share and mean colour difference between the mesh and impostor frames.
/// The eye is along the world direction `dir` from the tree ([`camera_along`]).
fn compare(
    scene: &Scene,
    dir: [f32; 3],
    sphere: ViewSphere,
    grid: u32,
    blend: AzimuthMode,
) -> (f64, f64) {
    compare_depth(scene, dir, sphere, grid, blend, false)
}

/// [`compare`] with the depth channel (issue 32) on or off.
fn compare_depth(
    scene: &Scene,
    dir: [f32; 3],
    sphere: ViewSphere,
    grid: u32,
    blend: AzimuthMode,
    depth: bool,
) -> (f64, f64) {
    let mesh_p = params(false, sphere, grid, blend);
    let imp_p = with_depth(true, sphere, grid, blend, depth);
    let a = prepare(scene.clone(), &mesh_p).expect("prepare meshes");
    let b = prepare(scene.clone(), &imp_p).expect("prepare impostors");
    let camera = camera_along(&a, dir);
    let x = images_of(&a.render(&camera, &mesh_p).unwrap().drawn.target);
    let y = images_of(&b.render(&camera, &imp_p).unwrap().drawn.target);
    let (mut either, mut one, mut both, mut diff) = (0u64, 0u64, 0u64, 0u64);
    for i in 0..x.lod_id.len() {
        let m = x.lod_id[i] == LOD_ID_MESH;
        let b = y.lod_id[i] == LOD_ID_BILLBOARD;
        either += u64::from(m || b);
        one += u64::from(m != b);
        if m && b {
            both += 1;
            diff += (0..3)
                .map(|c| u64::from(x.color[i][c].abs_diff(y.color[i][c])))
                .sum::<u64>();
        }
    }
    assert!(
        either > 500,
        "the tree covers {either} pixels: the camera missed it"
    );
    assert!(
        y.lod_id.iter().all(|&l| l != LOD_ID_MESH),
        "the impostor frame drew a mesh"
    );
    (
        one as f64 / either as f64,
        diff as f64 / (3 * both.max(1)) as f64,
    )
}

/// `d` (mesh-local) turned by `yaw` about Z.
fn turned(d: [f32; 3], yaw: f32) -> [f32; 3] {
    let (s, c) = yaw.sin_cos();
    [c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]]
}

#[test]
fn a_frame_seen_from_its_own_direction_reproduces_the_mesh() {
    let (mut worst_xor, mut worst_col, mut n) = (0.0f64, 0.0f64, 0);
    for (mesh, yaw) in [(0, 0.0), (1, 0.7), (2, -2.1), (3, 1.3), (4, 2.9)] {
        let scene = one_tree(mesh, yaw);
        for (sphere, grid, frames) in [
            (ViewSphere::HemiOctahedral, 4, &[1u32, 5, 6, 9][..]),
            (ViewSphere::Octahedral, 5, &[7, 11, 13][..]),
        ] {
            for &f in frames {
                let d = frame_direction(f, grid, sphere == ViewSphere::HemiOctahedral);
                // Straight down, `look_at`'s up vector is degenerate: not a pose we test.
                if d[2].abs() > 0.95 {
                    continue;
                }
                for blend in [AzimuthMode::Nearest, AzimuthMode::Blend] {
                    let (xor, col) = compare(&scene, turned(d, yaw), sphere, grid, blend);
                    println!(
                        "mesh {mesh} yaw {yaw} {} N={grid} frame {f} {}: silhouette xor {xor:.3}, colour {col:.1}",
                        sphere.name(),
                        blend.name()
                    );
                    assert!(
                        xor <= SILHOUETTE_XOR_MAX && col <= COLOR_MEAN_MAX,
                        "mesh {mesh} frame {f} ({}): xor {xor:.3} colour {col:.1}",
                        blend.name()
                    );
                    worst_xor = worst_xor.max(xor);
                    worst_col = worst_col.max(col);
                    n += 1;
                }
            }
        }
    }
    println!("{n} poses: worst silhouette xor {worst_xor:.3}, worst colour {worst_col:.1}");
    assert!(n >= 30, "{n} poses");
}

#[test]
fn between_frames_the_blend_still_reproduces_the_mesh() {
    let (mut worst, mut n) = (0.0f64, 0);
    for (mesh, yaw) in BETWEEN_TREES {
        let scene = one_tree(mesh, yaw);
        for d in BETWEEN_EYES {
            for blend in [AzimuthMode::Nearest, AzimuthMode::Blend] {
                let (xor, col) = compare(
                    &scene,
                    turned(d, yaw),
                    ViewSphere::HemiOctahedral,
                    BETWEEN_GRID,
                    blend,
                );
                println!(
                    "mesh {mesh} eye {d:?} {}: silhouette xor {xor:.3}, colour {col:.1}",
                    blend.name()
                );
                assert!(
                    xor <= BLEND_XOR_MAX && col <= COLOR_MEAN_MAX,
                    "mesh {mesh} {d:?}: {xor:.3} {col:.1}"
                );
                worst = worst.max(xor);
                n += 1;
            }
        }
    }
    println!("{n} in-between poses: worst silhouette xor {worst:.3}");
}

/// The depth channel (issue 32, `forestlod_shared::octahedral` module docs) at the in-between
/// eyes of [`between_frames_the_blend_still_reproduces_the_mesh`] on a coarse 4×4 hemi grid
/// (frames far apart, where re-projecting through the plane ghosts most): the means of the
/// silhouette XOR and of the colour difference against the mesh no worse than the plane's.
/// Printed per pose and as means. Measured: XOR 0.380 → 0.370, colour 5.1 → 3.5 (lower at every
/// pose). The rejected first design (the nearest frame's surface point re-projected onto the
/// other two) failed this test: XOR 0.397, colour higher at every pose.
#[test]
fn the_depth_channel_keeps_the_blend_on_the_mesh() {
    let (mut plane, mut depth, mut n) = (0.0f64, 0.0f64, 0);
    let (mut plane_colour, mut depth_colour) = (0.0f64, 0.0f64);
    for (mesh, yaw) in BETWEEN_TREES {
        let scene = one_tree(mesh, yaw);
        for d in BETWEEN_EYES {
            let run = |on| {
                compare_depth(
                    &scene,
                    turned(d, yaw),
                    ViewSphere::HemiOctahedral,
                    4,
                    AzimuthMode::Blend,
                    on,
                )
            };
            let ((x0, c0), (x1, c1)) = (run(false), run(true));
            println!(
                "mesh {mesh} eye {d:?}: silhouette xor plane {x0:.3} depth {x1:.3}, colour plane {c0:.1} depth {c1:.1}"
            );
            plane += x0;
            depth += x1;
            plane_colour += c0;
            depth_colour += c1;
            n += 1;
        }
    }
    let (plane, depth) = (plane / n as f64, depth / n as f64);
    let (plane_colour, depth_colour) = (plane_colour / n as f64, depth_colour / n as f64);
    println!(
        "{n} poses, 4x4 hemi grid: mean silhouette xor plane {plane:.4}, depth {depth:.4}; \
         mean colour plane {plane_colour:.2}, depth {depth_colour:.2}"
    );
    assert!(
        depth <= plane && depth_colour <= plane_colour,
        "the depth channel (xor {depth:.4}, colour {depth_colour:.2}) is worse than the plane \
         (xor {plane:.4}, colour {plane_colour:.2})"
    );
}

#[test]
fn octahedral_parameters_under_elevation_views_draw_todays_frame() {
    let scene = builtin::tiny();
    let today = Params {
        lod1_transition: 60.0,
        fade_width: 20.0,
        grid_size: 50.0,
        texture_size: 32,
        ..Params::default()
    };
    let other = Params {
        octahedral_grid: 7,
        octahedral_blend: AzimuthMode::Nearest as u32,
        ..today
    };
    let a = prepare(scene.clone(), &today).unwrap();
    let b = prepare(scene, &other).unwrap();
    let [x0, y0, x1, y1] = a.scene.bounds;
    let camera = Camera::look_at(
        [x0, y0, 40.0],
        [(x0 + x1) * 0.5, (y0 + y1) * 0.5, 0.0],
        60.0,
        160,
        90,
    );
    let x = images_of(&a.render(&camera, &today).unwrap().drawn.target);
    let y = images_of(&b.render(&camera, &other).unwrap().drawn.target);
    assert!(x.lod_id.contains(&LOD_ID_BILLBOARD));
    assert_eq!(differing_pixels(&x, &y), (0, 0, 0));
}

#[test]
fn too_many_frames_is_a_parameter_error_naming_the_grid() {
    let p = Params {
        billboard_views: ViewSphere::Octahedral as u32,
        octahedral_grid: 32,
        ..Params::default()
    };
    // `tiny` carries five species: 5 x 1024 layers.
    let e = prepare(builtin::tiny(), &p)
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(e.contains("octahedral_grid") && e.contains("5120"), "{e}");
}
