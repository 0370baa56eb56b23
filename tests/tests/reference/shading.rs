//! Issue 30's sun-depth shading (G§5, Figs. 7-9; `forestlod_shared::light`) on whole frames of
//! the reference, one tree of each built-in species alone on flat ground:
//! - **the seed's defect, reproduced and fixed**: sun at +X, the tree's billboard seen from +X
//!   is brighter than seen from −X by at least a quarter of the lit range `(1 − a)/4` with
//!   `sun-depth-plane`, and by about nothing with `sun-depth` (Fig. 8: the billboard sits at the
//!   crown centre's depth along the sun, so it shows medium lightness from every side);
//! - **meshes are lit where they stand**: seen from either side they differ by at most
//!   [`MESH_SAME_SIDES`] (crossed cards show their central card to both);
//! - **the billboard agrees with its mesh**, loosely on card trees: with `sun-depth-plane`, a
//!   billboard's mean lightness is within [`MESH_AGREEMENT`] of its mesh's, seen from the same
//!   direction;
//! - **symmetry**: rotating the sun, the camera and the tree together about the vertical axis
//!   through the tree leaves the image unchanged, to rounding ([`ROTATION_BUDGET`]).
//!
//! A frame's mean lightness is measured, not read from the shader: each tree pixel's linear
//! colour over the unlit frame's (the same frame with `shading = unlit`), averaged over the
//! pixels both frames draw as the same LOD; the green channel, the brightest of foliage, so the
//! 8-bit quantisation costs least.

use forestlod_harness::image_compare::Images;
use forestlod_harness::stage::images_of;
use forestlod_reference::draw::{LOD_ID_BILLBOARD, LOD_ID_MESH};
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::{Instance, Scene, Terrain, builtin};
use forestlod_shared::{Camera, Params, Shading, srgb_to_linear};

/// The ambient level of these tests (the default): the lit range is `1 − a` = 0.65.
const AMBIENT: f32 = 0.35;

/// How far a billboard's mean lightness may lie from its mesh's, seen from the same direction
/// (`sun-depth-plane`). The seed's plane (G§5 Fig. 9) assumes a volumetric crown, whose visible
/// leaves lie on average half a radius towards the eye. Our built-in species are crossed alpha
/// cards: from any side the card facing the eye stands through the crown centre, so the mesh's
/// mean lightness hardly depends on the view (0.62-0.78 over the species, suns and views
/// measured), while the plane swings the billboard's by half the lit range
/// between the sun side and the far side. Measured on the five species from four sides at sun
/// elevations 15° and 45°: at most 0.148 (species 1, sun 15°, seen from the far side; the
/// printout of `billboard_mean_lightness_is_near_its_meshs`), at most 0.065 at 45°. 0.17 allows
/// the rounding of the measurement, and stays under a quarter of the lit range (0.1625 + 0.01):
/// the plane's error on card trees is a finding of issue 30, not a tolerance to hide.
const MESH_AGREEMENT: f32 = 0.17;

/// How much a *mesh*'s mean lightness may differ between the sun side and the far side (sun at
/// +X, level view, `sun-depth-plane`): meshes are lit where they stand, and a crossed-card
/// tree shows its central card to both sides, so only the cards' own offsets from the crown
/// centre and their texture separate them (measured at most 0.079, species 2). 0.12, under a
/// fifth of the lit range: lighting a mesh on the billboard's plane (the plane applied to LOD0
/// too) moves the difference to about half the lit range (0.32).
const MESH_SAME_SIDES: f32 = 0.12;

/// With `sun-depth` (the seed's defect), the billboard's mean lightness from +X and from −X,
/// sun at +X, may differ by this much at most: the billboard's vertices stand on the tree's
/// vertical plane through its base, whose sun depth is the same from either side, so only the
/// 8-bit rounding of the two frames separates them.
const DEFECT_SAME_SIDES: f32 = 0.01;

/// Pixels allowed to differ by more than one sRGB level between a frame and its rotated twin
/// (sun, camera and tree rotated together by 90°): `cos(π/2)` is not 0 in `f32`, so vertices
/// move by ulps and a few edge pixels change coverage. A fraction of the tree pixels.
const ROTATION_BUDGET: f64 = 0.01;

/// One tree of species `mesh` at the origin, unrotated, on flat ground.
fn lone_tree(mesh: u32, yaw: f32) -> Scene {
    let tiny = builtin::tiny();
    Scene {
        name: format!("lone-{mesh}"),
        origin: [0.0; 3],
        meshes: tiny.meshes,
        instances: vec![Instance {
            position: [0.0, 0.0, 0.0],
            yaw,
            scale: 1.0,
            mesh,
        }],
        terrain: Terrain::Flat { z: 0.0 },
        bounds: [-20.0, -20.0, 20.0, 20.0],
    }
}

/// Parameters drawing every tree as a billboard (`billboard`) or as its mesh, shaded `shading`,
/// sun at azimuth `sun_az` and elevation `sun_el`.
fn params(billboard: bool, shading: Shading, sun_az: f32, sun_el: f32) -> Params {
    Params {
        lod_levels: if billboard { 2 } else { 1 },
        lod1_transition: 1.0,
        fade_width: 0.0,
        texture_size: 128,
        shading: shading as u32,
        sun_azimuth: sun_az,
        sun_elevation: sun_el,
        ambient: AMBIENT,
        ..Params::default()
    }
}

/// A camera `distance` m from the crown centre `centre` in the horizontal direction
/// `angle_deg` (counter-clockwise from +X), at height `z` (the crown centre's when `None`),
/// looking at the centre.
fn camera_at(centre: [f32; 3], angle_deg: f32, distance: f32, z: Option<f32>) -> Camera {
    let (s, c) = angle_deg.to_radians().sin_cos();
    let eye = [
        centre[0] + distance * c,
        centre[1] + distance * s,
        z.unwrap_or(centre[2]),
    ];
    Camera::look_at(eye, centre, 40.0, 160, 160)
}

/// The frame of `scene` under `params` from `camera`.
fn frame(scene: &Scene, params: &Params, camera: &Camera) -> Images {
    let prepared = prepare(scene.clone(), params).expect("prepare");
    images_of(
        &prepared
            .render(camera, params)
            .expect("render")
            .drawn
            .target,
    )
}

/// The mean lightness of `lit` against `unlit` (module docs) over pixels of LOD id `id` in both,
/// and how many pixels it averaged.
fn mean_lightness(lit: &Images, unlit: &Images, id: u32) -> (f32, usize) {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for i in 0..lit.color.len() {
        if lit.lod_id[i] != id || unlit.lod_id[i] != id {
            continue;
        }
        let g0 = srgb_to_linear(unlit.color[i][1]);
        if g0 < 0.02 {
            continue;
        }
        sum += f64::from(srgb_to_linear(lit.color[i][1]) / g0);
        n += 1;
    }
    assert!(
        n > 200,
        "only {n} pixels of LOD id {id}: the tree is not on screen"
    );
    ((sum / n as f64) as f32, n)
}

/// The crown centre of the lone tree of `mesh` (its bounding-box centre).
fn crown_centre(scene: &Scene) -> [f32; 3] {
    let meta = scene.meshes[scene.instances[0].mesh as usize].bounds_meta();
    [0, 1, 2].map(|i| (meta.bbox_min[i] + meta.bbox_max[i]) * 0.5)
}

/// The mean lightness of the lone tree of `mesh` drawn as a billboard (or its mesh) from the
/// horizontal direction `angle_deg` at height `z` (module docs of [`camera_at`]), sun at
/// `(sun_az, sun_el)`.
fn tree_lightness(
    mesh: u32,
    billboard: bool,
    shading: Shading,
    (angle_deg, z): (f32, Option<f32>),
    (sun_az, sun_el): (f32, f32),
) -> f32 {
    let scene = lone_tree(mesh, 0.0);
    let camera = camera_at(crown_centre(&scene), angle_deg, 60.0, z);
    let p = params(billboard, shading, sun_az, sun_el);
    let lit = frame(&scene, &p, &camera);
    let unlit = frame(
        &scene,
        &Params {
            shading: Shading::Unlit as u32,
            ..p
        },
        &camera,
    );
    let id = if billboard {
        LOD_ID_BILLBOARD
    } else {
        LOD_ID_MESH
    };
    mean_lightness(&lit, &unlit, id).0
}

#[test]
fn the_seeds_defect_is_reproduced_and_the_lighting_plane_fixes_it() {
    let species = builtin::tiny().meshes.len() as u32;
    let range = 1.0 - AMBIENT;
    let mut report = Vec::new();
    for mesh in 0..species {
        let sun = (0.0, 0.0);
        // Eyes 1 m above the ground: the level view, layer 0, whose billboard stands upright
        // through the tree's base, as the seed's do (module docs of `forestlod_shared::light`:
        // a tilted layer leans away and makes the defect worse, not absent).
        let side = |shading| {
            let front = tree_lightness(mesh, true, shading, (0.0, Some(1.0)), sun);
            let back = tree_lightness(mesh, true, shading, (180.0, Some(1.0)), sun);
            (front, back)
        };
        let (pf, pb) = side(Shading::SunDepthPlane);
        let (df, db) = side(Shading::SunDepth);
        // From the crown's height (9° above the base: the 10° layer, tilted away from the eye)
        // the plane must fix it too: it projects, so the tilt does not matter.
        let tf = tree_lightness(mesh, true, Shading::SunDepthPlane, (0.0, None), sun);
        let tb = tree_lightness(mesh, true, Shading::SunDepthPlane, (180.0, None), sun);
        let mf = tree_lightness(mesh, false, Shading::SunDepthPlane, (0.0, Some(1.0)), sun);
        let mb = tree_lightness(mesh, false, Shading::SunDepthPlane, (180.0, Some(1.0)), sun);
        report.push(format!(
            "species {mesh}: plane +X {pf:.3} −X {pb:.3} (difference {:.3}); \
             sun-depth +X {df:.3} −X {db:.3} (difference {:.3}); mesh +X {mf:.3} −X {mb:.3}; \
             plane from the crown's height +X {tf:.3} −X {tb:.3}",
            pf - pb,
            df - db
        ));
        assert!(
            tf - tb >= range / 4.0,
            "species {mesh}: seen from the crown's height (a tilted layer) the lighting plane \
             leaves the sunlit side only {:.3} brighter (at least {:.3} expected)\n{}",
            tf - tb,
            range / 4.0,
            report.join("\n")
        );
        assert!(
            (mf - mb).abs() <= MESH_SAME_SIDES,
            "species {mesh}: the mesh differs by {:.3} between the sides (meshes are lit where \
             they stand, within {MESH_SAME_SIDES})\n{}",
            mf - mb,
            report.join("\n")
        );
        assert!(
            pf - pb >= range / 4.0,
            "species {mesh}: with the lighting plane the sunlit side is only {:.3} brighter \
             (at least (1 − a)/4 = {:.3} expected)\n{}",
            pf - pb,
            range / 4.0,
            report.join("\n")
        );
        assert!(
            (df - db).abs() <= DEFECT_SAME_SIDES,
            "species {mesh}: without the plane the two sides differ by {:.3} (the seed's \
             defect is equal lightness, within {DEFECT_SAME_SIDES})\n{}",
            df - db,
            report.join("\n")
        );
    }
    println!("{}", report.join("\n"));
}

#[test]
fn billboard_mean_lightness_is_near_its_meshs() {
    let species = builtin::tiny().meshes.len() as u32;
    let mut worst = 0.0f32;
    let mut report = Vec::new();
    for mesh in 0..species {
        for sun in [(0.0, 15.0), (0.0, 45.0)] {
            for angle in [0.0, 90.0, 180.0, 270.0] {
                let b = tree_lightness(mesh, true, Shading::SunDepthPlane, (angle, None), sun);
                let m = tree_lightness(mesh, false, Shading::SunDepthPlane, (angle, None), sun);
                worst = worst.max((b - m).abs());
                report.push(format!(
                    "species {mesh} sun elevation {} view {angle}°: billboard {b:.3} mesh {m:.3}",
                    sun.1
                ));
            }
        }
    }
    println!(
        "{}\nlargest |billboard − mesh| = {worst:.3} (allowed {MESH_AGREEMENT})",
        report.join("\n")
    );
    assert!(
        worst <= MESH_AGREEMENT,
        "a billboard's mean lightness is {worst:.3} from its mesh's (allowed {MESH_AGREEMENT})\n{}",
        report.join("\n")
    );
}

#[test]
fn rotating_sun_camera_and_tree_together_leaves_the_image_unchanged() {
    let mut report = Vec::new();
    for billboard in [false, true] {
        for shading in [Shading::SunDepth, Shading::SunDepthPlane] {
            let turn = 90.0f32;
            let base = lone_tree(1, 0.0);
            let turned = lone_tree(1, turn.to_radians());
            // The crown centre of the unrotated tree, rotated: the tree turns about its base.
            let c = crown_centre(&base);
            let (s, co) = turn.to_radians().sin_cos();
            let c_turned = [co * c[0] - s * c[1], s * c[0] + co * c[1], c[2]];
            let a = frame(
                &base,
                &params(billboard, shading, 20.0, 30.0),
                &camera_at(c, 200.0, 60.0, None),
            );
            let b = frame(
                &turned,
                &params(billboard, shading, 20.0 + turn, 30.0),
                &camera_at(c_turned, 200.0 + turn, 60.0, None),
            );
            let trees = a
                .lod_id
                .iter()
                .filter(|&&id| id == LOD_ID_MESH || id == LOD_ID_BILLBOARD);
            let tree_pixels = trees.count();
            let differing = a
                .color
                .iter()
                .zip(&b.color)
                .filter(|(x, y)| (0..3).any(|k| x[k].abs_diff(y[k]) > 1))
                .count();
            report.push(format!(
                "{} {}: {differing} of {tree_pixels} tree pixels differ by more than 1",
                if billboard { "billboard" } else { "mesh" },
                shading.name()
            ));
            assert!(tree_pixels > 200, "{}", report.join("\n"));
            assert!(
                differing as f64 <= ROTATION_BUDGET * tree_pixels as f64,
                "rotating everything together changed the image:\n{}",
                report.join("\n")
            );
        }
    }
    println!("{}", report.join("\n"));
}
