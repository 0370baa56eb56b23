//! Issue 29's degenerate case on whole frames (C§4.6.3): with every tree of one mesh at unit
//! scale and a scaled metric's threshold matched to the distance mode's transition, the reference
//! draws the distance mode's frame **bit for bit** (colour, depth, LOD id), for both scaled
//! metrics; and the frame is not trivially equal: it has transition pixels, and a threshold one
//! step off changes it. The selection-level property is
//! `properties::select_properties::metric::unit_scales_and_a_matched_threshold_select_as_the_distance_mode`.

use forestlod_harness::stage::images_of;
use forestlod_reference::cameras::named_camera;
use forestlod_reference::draw::LOD_ID_TRANSITION;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::builtin;
use forestlod_reference::select::SelectUniform;
use forestlod_shared::{Camera, FadeMode, Hierarchy, LodMetric, Params};
use forestlod_tests::{differing_pixels, tiny_hierarchy_params};

/// The threshold of `metric` (its `Params` field set by `set`) nearest `guess` whose band for
/// `mesh` at unit scale is exactly `want`, searching 256 `f32` steps either side; `None` when no
/// step lands on it.
fn matched(
    base: &Params,
    camera: &Camera,
    mesh: &forestlod_shared::MeshMeta,
    guess: f32,
    set: fn(&mut Params, f32),
    want: [f32; 2],
) -> Option<Params> {
    (0..512u32).find_map(|k| {
        let step = if k % 2 == 0 {
            k / 2
        } else {
            0u32.wrapping_sub(k.div_ceil(2))
        };
        let thr = f32::from_bits(guess.to_bits().wrapping_add(step));
        let mut p = *base;
        set(&mut p, thr);
        (SelectUniform::new(camera, &p).mesh_band(mesh) == want).then_some(p)
    })
}

#[test]
fn a_matched_threshold_draws_the_distance_mode_bit_for_bit() {
    // A band ratio of 3/4, exact in f32: the scaled metric's start `end · ratio` is the
    // distance mode's `fade_start` bit for bit.
    let distance = Params {
        lod1_transition: 120.0,
        fade_width: 30.0,
        ..tiny_hierarchy_params(Hierarchy::Grid)
    };
    let mut checked = 0;
    // The default fade and the cross-fade, whose weights move with every fragment's place in
    // its band (a band off by a little changes colours, not only dithered pixel sets).
    for fade in [FadeMode::DitherSequential, FadeMode::Alpha] {
        checked += matched_frames(Params {
            fade_mode: fade as u32,
            ..distance
        });
    }
    println!("matched-threshold frames equal to the distance mode: {checked}");
    assert!(
        checked >= 6,
        "only {checked} of 8 fade x metric x camera triples had a matching threshold"
    );
}

/// Frames of `tiny` (one mesh, unit scales) at two cameras under both scaled metrics matched to
/// `distance`'s band, each asserted equal to `distance`'s frame; returns how many were checked.
fn matched_frames(distance: Params) -> usize {
    let mut scene = builtin::tiny();
    for t in &mut scene.instances {
        t.mesh = 0;
        t.scale = 1.0;
    }
    let want = [distance.fade_start(), distance.lod1_transition];
    let prepared = prepare(scene, &distance).expect("prepare");
    let mesh = prepared.geometry.meshes[0];
    let mut checked = 0;
    let fade = distance.fade().expect("a fade mode").name();
    for (name, yaw) in [("close", 0.0), ("close", 90.0)] {
        let camera = named_camera(name, &prepared.scene, yaw, 192, 108).expect("camera");
        let f = forestlod_shared::focal_px(&camera);
        let base = Params {
            lod_metric: LodMetric::PixelArea as u32,
            ..distance
        };
        let area = f64::from(mesh.area_size).powi(2);
        let pixel_area = matched(
            &base,
            &camera,
            &mesh,
            (area * (f / 120.0).powi(2)) as f32,
            |p, t| p.lod_pixel_area = t,
            want,
        );
        let base = Params {
            lod_metric: LodMetric::ScreenError as u32,
            ..distance
        };
        let screen_error = matched(
            &base,
            &camera,
            &mesh,
            (f64::from(mesh.error_size) * f / 120.0) as f32,
            |p, t| p.lod_screen_error = t,
            want,
        );
        let want_frame = images_of(
            &prepared
                .render(&camera, &distance)
                .expect("render")
                .drawn
                .target,
        );
        let transition = want_frame
            .lod_id
            .iter()
            .filter(|&&id| id == LOD_ID_TRANSITION)
            .count();
        assert!(
            transition > 20,
            "{name} {yaw}: {transition} transition pixels: the band is not on screen"
        );
        for q in [pixel_area, screen_error].into_iter().flatten() {
            let got = images_of(&prepared.render(&camera, &q).expect("render").drawn.target);
            let metric = q.lod_metric_mode().unwrap().name();
            assert_eq!(
                differing_pixels(&got, &want_frame),
                (0, 0, 0),
                "{name} yaw {yaw}, {fade}: {metric} matched to the distance mode differs (colour, depth, LOD-id pixels)"
            );
            // Not trivially equal: halving the threshold's transition changes the frame.
            let mut off = q;
            off.lod_pixel_area *= 4.0;
            off.lod_screen_error *= 2.0;
            let moved = images_of(&prepared.render(&camera, &off).expect("render").drawn.target);
            assert!(
                differing_pixels(&moved, &want_frame).2 > 0,
                "{name} yaw {yaw}, {fade}: {metric} with half the transition draws the same LOD ids"
            );
            checked += 1;
        }
    }
    checked
}
