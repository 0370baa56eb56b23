//! Issue 30's billboard azimuth views (E§7, `forestlod_shared::azimuth`) on the reference:
//! - one azimuth draws today's frame under either azimuth rule (the goldens hold today's frame
//!   itself: `goldens::reference_matches_goldens`);
//! - the layer the draw picks for a billboard holds the view baked nearest the eye (elevation and
//!   azimuth decided here in `f64` from the scene, independently of the pipeline's `f32` index),
//!   and under the blend the second layer is the next view with the eye's fraction as weight;
//! - rotating a tree by `2π/J` and the camera about it by the same angle gives identical
//!   billboard pixels (colour, depth, LOD id; exact, at quarter and half turns, whose rotations
//!   `f32` carries out exactly);
//! - too many layers (`m·K·J`) is a parameter error naming `azimuth_count`, never a panic.
//!
//! Decisions within `AZIMUTH_BIN_EPSILON` (`forestlod_tests::azimuth`) of a rounding boundary (the two views tie, or the
//! blend weight's quantisation step) are classified ambiguous, counted and printed, and held
//! under a budget; they are not compared.

use std::collections::BTreeMap;

use forestlod_harness::stage::images_of;
use forestlod_reference::bake::bake_view;
use forestlod_reference::draw::{DrawUniform, LOD_ID_BILLBOARD, tree_stage};
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::{Scene, builtin};
use forestlod_reference::texture::Rgba8Image;
use forestlod_shared::{
    AZIMUTH_WEIGHT_STEPS, AzimuthMode, BillboardViews, Camera, FadeMode, Params, azimuth_unpack,
    bake_azimuth, bake_elevation,
};
use forestlod_tests::azimuth::{AZIMUTH_BIN_EPSILON, azimuth_near_boundary, to_half, true_view};
use forestlod_tests::differing_pixels;

/// Largest fraction of the billboard decisions (or of the rotation poses) that may be ambiguous:
/// with decisions spread evenly, a band of ±ε around one boundary per bin is 2ε of them (0.2 %);
/// the blend has two boundaries (the view pair and the weight's step). 2 % leaves room for few
/// samples and fails a rule that puts many decisions on a boundary.
const AMBIGUOUS_BUDGET: f64 = 0.02;

/// Views of `p`.
fn views(p: &Params) -> BillboardViews {
    BillboardViews::of(p)
}

/// `tiny`'s frame with billboards from 60 m on (small bands so that trees near the camera are
/// billboards from many directions).
fn base() -> Params {
    Params {
        lod1_transition: 60.0,
        fade_width: 20.0,
        grid_size: 50.0,
        texture_size: 32,
        ..Params::default()
    }
}

/// Cameras over `tiny` looking at several points from several heights.
fn cameras(scene: &Scene) -> Vec<Camera> {
    let [x0, y0, x1, y1] = scene.bounds;
    let (cx, cy) = ((x0 + x1) * 0.5, (y0 + y1) * 0.5);
    let mut out = Vec::new();
    for (i, (dx, dy, z)) in [(0.0, 0.0, 30.0), (0.3, -0.2, 80.0), (-0.35, 0.3, 12.0)]
        .into_iter()
        .enumerate()
    {
        let eye = [cx + dx * (x1 - x0), cy + dy * (y1 - y0), z];
        let target = [
            cx - dy * (x1 - x0),
            cy + dx * (y1 - y0) + 10.0 * (i + 1) as f32,
            0.0,
        ];
        out.push(Camera::look_at(eye, target, 60.0, 160, 90));
    }
    out
}

#[test]
fn one_azimuth_draws_todays_frame_under_either_rule() {
    let mut frames = 0;
    for fade in [FadeMode::DitherSequential, FadeMode::Alpha] {
        let nearest = Params {
            fade_mode: fade as u32,
            ..base()
        };
        let blend = Params {
            azimuth_mode: AzimuthMode::Blend as u32,
            ..nearest
        };
        let a = prepare(builtin::tiny(), &nearest).expect("prepare");
        let b = prepare(builtin::tiny(), &blend).expect("prepare");
        assert_eq!(a.billboards.layers.len(), 5 * nearest.angle_count as usize);
        for (la, lb) in a.billboards.layers.iter().zip(&b.billboards.layers) {
            assert_eq!(la.texels, lb.texels);
        }
        for camera in cameras(&a.scene) {
            let x = images_of(&a.render(&camera, &nearest).unwrap().drawn.target);
            let y = images_of(&b.render(&camera, &blend).unwrap().drawn.target);
            assert_eq!(differing_pixels(&x, &y), (0, 0, 0), "{}", fade.name());
            frames += 1;
        }
    }
    println!("one azimuth, nearest vs blend: {frames} frames bit-identical");
}

/// Level 0 of view `(k, j)` of `mesh`, baked alone (not read from the prepared array).
fn baked(
    prepared: &Prepared,
    v: BillboardViews,
    mesh: usize,
    k: u32,
    j: u32,
    r: u32,
) -> Rgba8Image {
    let m = &prepared.scene.meshes[mesh];
    bake_view(
        m,
        &prepared.geometry.meshes[mesh],
        &prepared.mesh_textures[mesh],
        v,
        k,
        j,
        r,
    )
}

/// Tallies of [`the_drawn_layers_hold_the_views_nearest_the_eye`].
#[derive(Default)]
struct Tally {
    checked: u64,
    ambiguous: u64,
    /// Billboards whose second view carries weight (blend).
    blended: u64,
}

#[test]
fn the_drawn_layers_hold_the_views_nearest_the_eye() {
    let mut tally = Tally::default();
    for (k_count, j_count) in [(1, 4), (2, 3), (5, 8), (3, 2)] {
        for mode in AzimuthMode::ALL {
            let params = Params {
                angle_count: k_count,
                azimuth_count: j_count,
                azimuth_mode: mode as u32,
                ..base()
            };
            let v = views(&params);
            let prepared = prepare(builtin::tiny(), &params).expect("prepare");
            assert_eq!(
                prepared.billboards.layers.len() as u64,
                v.layers(prepared.scene.meshes.len())
            );
            // Each layer that a billboard draws, checked against its own bake once.
            let mut layer_checked: BTreeMap<u32, ()> = BTreeMap::new();
            let mut check_layer = |layer: u32, mesh: usize, k: u32, j: u32| {
                if layer_checked.insert(layer, ()).is_none() {
                    let want = baked(&prepared, v, mesh, k, j, params.texture_size);
                    assert!(
                        prepared.billboards.layers[layer as usize].texels == want.texels,
                        "K={k_count} J={j_count}: layer {layer} does not hold mesh {mesh}'s view ({k}, {j})"
                    );
                }
            };
            for camera in cameras(&prepared.scene) {
                let selection = prepared.select(&camera, &params);
                let res = prepared.resources();
                let uniform = DrawUniform::new(&camera, &params);
                for (c, (cmd, data)) in selection.commands.iter().zip(&selection.data).enumerate() {
                    if data.billboard == 0 {
                        continue;
                    }
                    for i in cmd.first_instance..cmd.first_instance + cmd.instance_count {
                        let Some(stage) = tree_stage(&res, &selection, &uniform, c as u32, i)
                        else {
                            continue;
                        };
                        let tree = prepared.batches.indirection[i as usize] as usize;
                        let t = prepared.scene.instances[tree];
                        let Some((k_true, t_true)) = true_view(t.position, t.yaw, camera.eye, v)
                        else {
                            continue;
                        };
                        let word = stage.vertex(&res, &uniform, 0).varyings[3];
                        let (layer, code) = azimuth_unpack(word as u32);
                        let per_mesh = v.per_mesh();
                        let (mesh, k, j) = (
                            (layer / per_mesh) as usize,
                            layer / j_count % k_count,
                            layer % j_count,
                        );
                        assert_eq!(mesh, t.mesh as usize, "layer {layer} of another mesh");
                        let j_of = |x: f64| (x as u32) % j_count;
                        let blend = mode == AzimuthMode::Blend && j_count > 1;
                        let frac = t_true - t_true.floor();
                        let ambiguous = (k_count > 1 && to_half(k_true) < AZIMUTH_BIN_EPSILON)
                            || azimuth_near_boundary(t_true, mode, j_count);
                        if ambiguous {
                            tally.ambiguous += 1;
                            continue;
                        }
                        let k_want = (k_true.round() as u32).min(k_count - 1);
                        let (j_want, code_want) = if blend {
                            let code = (frac * f64::from(AZIMUTH_WEIGHT_STEPS)).round() as u32;
                            (j_of(t_true.floor()), code)
                        } else {
                            (j_of(t_true.round()), 0)
                        };
                        assert_eq!(
                            (k, j, code),
                            (k_want, j_want, code_want),
                            "K={k_count} J={j_count} {}: tree {tree} at elevation index {k_true:.4}, \
                             azimuth position {t_true:.4}",
                            mode.name()
                        );
                        check_layer(layer, mesh, k, j);
                        if code > 0 {
                            tally.blended += 1;
                            let second = forestlod_shared::azimuth_second_layer(layer, j_count);
                            check_layer(second, mesh, k, (j + 1) % j_count);
                        }
                        tally.checked += 1;
                    }
                }
            }
        }
    }
    let share = tally.ambiguous as f64 / (tally.checked + tally.ambiguous) as f64;
    println!(
        "billboards checked: {}, blended: {}, ambiguous (within {AZIMUTH_BIN_EPSILON} of a \
         rounding boundary): {} ({:.3} %, budget {:.1} %)",
        tally.checked,
        tally.blended,
        tally.ambiguous,
        100.0 * share,
        100.0 * AMBIGUOUS_BUDGET
    );
    assert!(
        tally.checked >= 200,
        "only {} billboards checked",
        tally.checked
    );
    assert!(
        tally.blended >= 50,
        "only {} blended billboards",
        tally.blended
    );
    assert!(
        share <= AMBIGUOUS_BUDGET,
        "{share} of the decisions ambiguous"
    );
}

/// `v` turned a quarter turn about +Z, `n` times: `(x, y) -> (-y, x)`, exact in `f32`.
fn quarter_turns(v: [f32; 3], n: u32) -> [f32; 3] {
    (0..n).fold(v, |[x, y, z], _| [-y, x, z])
}

#[test]
fn rotating_the_tree_and_the_camera_by_a_view_step_keeps_the_billboard_pixels() {
    // One oak at yaw 0.3 on a 10 m pedestal above the ground (so that no billboard pixel meets the
    // ground, whose grid does not turn with the tree), seen from 40 m past its transition.
    let mut scene = builtin::single();
    scene.instances[0].mesh = builtin::Species::Oak as u32;
    scene.instances[0].yaw = 0.3;
    scene.instances[0].position = [0.0, 0.0, 10.0];
    let (mut compared, mut ambiguous, mut billboard_pixels) = (0u64, 0u64, 0u64);
    for j_count in [2u32, 4] {
        for mode in AzimuthMode::ALL {
            let params = Params {
                angle_count: 3,
                azimuth_count: j_count,
                azimuth_mode: mode as u32,
                lod1_transition: 5.0,
                fade_width: 1.0,
                texture_size: 64,
                ..Params::default()
            };
            let v = views(&params);
            let here = prepare(scene.clone(), &params).expect("prepare");
            for azimuth_deg in [17.0f32, 62.0, 100.0, 151.0, 200.0, 244.0, 290.0, 333.0] {
                for elevation_deg in [4.0f32, 28.0] {
                    let (a, e) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
                    let eye = [
                        40.0 * e.cos() * a.cos(),
                        40.0 * e.cos() * a.sin(),
                        10.0 + 40.0 * e.sin(),
                    ];
                    let camera = Camera::look_at(eye, [0.0, 0.0, 18.0], 40.0, 96, 96);
                    let want = images_of(&here.render(&camera, &params).unwrap().drawn.target);
                    // Quarter turns per view step: J = 4 one, J = 2 two.
                    let step = 4 / j_count;
                    for n in 1..j_count {
                        let turns = n * step;
                        let (_, t_true) = true_view([0.0, 0.0, 10.0], 0.3, eye, v).unwrap();
                        if azimuth_near_boundary(t_true, mode, j_count) {
                            ambiguous += 1;
                            continue;
                        }
                        let mut turned = scene.clone();
                        turned.instances[0].yaw =
                            0.3 + n as f32 * (std::f32::consts::TAU / j_count as f32);
                        let there = prepare(turned, &params).expect("prepare");
                        let camera = Camera {
                            eye: quarter_turns(camera.eye, turns),
                            forward: quarter_turns(camera.forward, turns),
                            ..camera
                        };
                        let got = images_of(&there.render(&camera, &params).unwrap().drawn.target);
                        let mut differ = 0;
                        for p in 0..want.lod_id.len() {
                            let billboard = want.lod_id[p] == LOD_ID_BILLBOARD
                                || got.lod_id[p] == LOD_ID_BILLBOARD;
                            if !billboard {
                                continue;
                            }
                            billboard_pixels += 1;
                            if want.color[p] != got.color[p]
                                || want.depth[p].to_bits() != got.depth[p].to_bits()
                                || want.lod_id[p] != got.lod_id[p]
                            {
                                differ += 1;
                            }
                        }
                        assert_eq!(
                            differ,
                            0,
                            "J={j_count} {}: eye at {azimuth_deg}°/{elevation_deg}°, turned by \
                             {n}/{j_count}: {differ} billboard pixels differ",
                            mode.name()
                        );
                        compared += 1;
                    }
                }
            }
        }
    }
    let share = ambiguous as f64 / (compared + ambiguous) as f64;
    println!(
        "rotations compared: {compared} ({billboard_pixels} billboard pixels, all identical), \
         ambiguous poses: {ambiguous} ({:.1} %, budget {:.1} %)",
        100.0 * share,
        100.0 * AMBIGUOUS_BUDGET
    );
    assert!(
        compared >= 60 && billboard_pixels > 10_000,
        "{compared} poses, {billboard_pixels} px"
    );
    assert!(share <= AMBIGUOUS_BUDGET, "{share} of the poses ambiguous");
}

#[test]
fn too_many_layers_is_a_parameter_error_naming_the_azimuths() {
    // One mesh's views alone: 91 elevations x 64 azimuths.
    let p = Params {
        angle_count: 91,
        azimuth_count: 64,
        ..Params::default()
    };
    let e = p.validate().unwrap_err();
    assert_eq!((e.field, e.value.as_str()), ("azimuth_count", "64"), "{e}");
    // The scene's: five species x 10 x 64 = 3200 layers (one mesh's 640 fit).
    let p = Params {
        azimuth_count: 64,
        ..Params::default()
    };
    p.validate().unwrap();
    let e = match prepare(builtin::tiny(), &p) {
        Ok(_) => panic!("3200 layers accepted"),
        Err(e) => e.to_string(),
    };
    assert!(
        e.contains("azimuth_count") && e.contains("3200 billboard layers") && e.contains("2048"),
        "{e}"
    );
    // The memory beside E Eq. 4.1 grows by J (four azimuths: four times the billboards).
    let one = prepare(builtin::single(), &base()).unwrap().memory;
    let four = Params {
        azimuth_count: 4,
        ..base()
    };
    let four = prepare(builtin::single(), &four).unwrap().memory;
    assert_eq!((one.j, four.j), (1, 4));
    assert_eq!(four.billboards, 4 * one.billboards);
    assert_eq!(four.eq41 - one.eq41, 3 * 16 * one.a * one.m * one.r * one.r);
    // Each view's bake angle is where its layer was baked from.
    assert_eq!(bake_azimuth(1, 4), std::f32::consts::FRAC_PI_2);
    assert_eq!(bake_elevation(0, 1), 0.0);
}
