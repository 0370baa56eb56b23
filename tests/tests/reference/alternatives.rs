//! The parity's alternative frames drawn only where the frames disagree
//! (`image_compare::alternative_pixels`, `backend::alpha_test_alternatives_at`, issue 14) give the
//! same classified report as whole alternative frames: the main job and the parity tests may use
//! the cheap ones without changing a verdict, a count or a class image.

use forestlod_harness::alternatives::{alpha_test_alternatives, alpha_test_alternatives_at};
use forestlod_harness::image_compare::{alternative_pixels, compare_images};
use forestlod_harness::stage::images_of;
use forestlod_reference::cameras::named_camera;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::builtin;
use forestlod_shared::Params;

#[test]
fn masked_alternatives_give_the_same_report() {
    let params = Params::default();
    let scene = builtin::tiny();
    let camera = named_camera("close", &scene, 30.0, 192, 108).expect("camera");
    let prepared = prepare(scene, &params).expect("prepare");
    let reference = images_of(
        &prepared
            .render(&camera, &params)
            .expect("render")
            .drawn
            .target,
    );
    // A stand-in for a GPU frame that disagrees the way a GPU does: its alpha test rounds
    // differently (cutoff moved by a little less than the 0.03 shift, so nearly every pixel it
    // flips is forgiven by some alternative), plus a few depth and LOD-id outliers that must
    // stay mismatches (they read the alternatives at the pixel only).
    let shifted = Params {
        alpha_cutoff: params.alpha_cutoff + 0.029,
        ..params
    };
    let mut gpu = images_of(
        &prepared
            .render(&camera, &shifted)
            .expect("render")
            .drawn
            .target,
    );
    let n = gpu.depth.len();
    for i in (0..n).step_by(997) {
        gpu.depth[i] = (gpu.depth[i] * 0.5).max(0.0);
        gpu.lod_id[(i + 13) % n] = 7;
    }
    let full = alpha_test_alternatives(&prepared, &camera, &params);
    let pixels = alternative_pixels(&gpu, &reference);
    let mut masked = alpha_test_alternatives_at(&prepared, &camera, &params, &pixels);
    assert_eq!(masked.len(), full.len());
    // Outside the pixels it names, poison the masked alternatives with the GPU's own values (which
    // would forgive anything): the report must not change, i.e. the comparison reads nothing
    // outside `alternative_pixels`.
    for a in &mut masked {
        for i in (0..n).filter(|&i| !pixels[i]) {
            a.color[i] = gpu.color[i];
            a.depth[i] = gpu.depth[i];
            a.lod_id[i] = gpu.lod_id[i];
        }
    }
    let want = compare_images("full", &gpu, &reference, &full, &camera);
    let got = compare_images("full", &gpu, &reference, &masked, &camera);
    let read = pixels.iter().filter(|&&p| p).count();
    println!(
        "alternatives read at {read} of {} pixels; colour {:?}",
        pixels.len(),
        want.color
    );
    assert!(
        want.color.threshold_ambiguous > 20,
        "the case must exercise the alternatives: {:?}",
        want.color
    );
    assert!(
        want.depth.mismatches > 0 && want.lod_id.mismatches > 0,
        "{want}"
    );
    assert!(read < pixels.len() / 4, "{read} of {} pixels", pixels.len());
    assert_eq!(format!("{got:?}"), format!("{want:?}"));
}

/// `alternative_pixels` names exactly what the comparison reads: a colour pixel beyond the
/// tolerance through its whole ±1 px window reads its 3x3 neighbourhood, a depth or LOD-id
/// outlier reads only itself, and agreeing pixels read nothing.
#[test]
fn alternative_pixels_are_the_pixels_read() {
    use forestlod_harness::image_compare::Images;
    let (w, h) = (7u32, 5u32);
    let n = (w * h) as usize;
    let reference = Images {
        width: w,
        height: h,
        color: vec![[10, 20, 30, 255]; n],
        depth: vec![0.5; n],
        lod_id: vec![1; n],
    };
    let mut gpu = reference.clone();
    gpu.color[(2 * w + 3) as usize] = [200, 20, 30, 255]; // colour outlier at (3, 2)
    gpu.color[(4 * w + 6) as usize] = [10, 24, 30, 255]; // within tolerance at (6, 4)
    gpu.depth[1] = 0.25; // depth outlier at (1, 0)
    gpu.lod_id[(4 * w) as usize] = 2; // LOD-id outlier at (0, 4)
    let pixels = alternative_pixels(&gpu, &reference);
    let mut want = vec![false; n];
    for y in 1..=3 {
        for x in 2..=4 {
            want[(y * w + x) as usize] = true;
        }
    }
    want[1] = true;
    want[(4 * w) as usize] = true;
    assert_eq!(pixels, want);
}

/// A masked draw (`Prepared::render_cutoffs` with a pixel mask) leaves out the trees whose screen
/// footprint misses the mask before the vertex stage (`draw::tree_footprint_radius`, issue 14);
/// at every masked pixel its colour, depth and LOD id must still be an unmasked draw's, bit for
/// bit, and the draw-distance discards the same. Random sparse masks and cameras on `tiny`: half
/// the eyes stand among the trees (within a few metres of one, so footprints cross the near
/// plane and reach behind the eye), half look from far (billboards, small footprints). The run
/// must have left trees out, met trees around the eye and drawn billboards, or it proves nothing.
#[test]
fn masked_draws_equal_unmasked_draws_at_the_mask() {
    use forestlod_reference::draw::tree_footprint_radius;
    use forestlod_shared::Camera;
    use forestlod_tests::run_cases;
    use glam::Vec3;
    use proptest::prelude::*;
    use std::cell::Cell;

    let base = Params {
        lod1_transition: 40.0,
        fade_width: 15.0,
        texture_size: 32,
        ..Params::default()
    };
    let prepared = prepare(builtin::tiny(), &base).expect("prepare");
    let trees = prepared.scene.instances.len();
    let metas = prepared.scene.mesh_metas();
    let (skipped_cases, near_cases, billboard_cases) = (Cell::new(0), Cell::new(0), Cell::new(0));
    let strategy = (
        (
            0..trees,
            -6.0f32..6.0,
            -6.0f32..6.0,
            0.3f32..25.0,
            any::<bool>(),
        ),
        (
            0.0f32..360.0,
            -70.0f32..25.0,
            25.0f32..100.0,
            40u32..112,
            40u32..112,
        ),
        (
            prop_oneof![Just(0.002f64), Just(0.02), Just(0.2)],
            any::<u64>(),
        ),
    );
    run_cases(
        "masked draws equal unmasked draws at the mask",
        96,
        strategy,
        |((tree, dx, dy, dz, far), (yaw, pitch, fov, w, h), (density, seed))| {
            let t = &prepared.scene.instances[tree];
            // A far eye: 60..200 m back along the view direction, 40..150 m up.
            let (yaw, pitch) = (yaw.to_radians(), pitch.to_radians());
            let forward = Vec3::new(
                yaw.cos() * pitch.cos(),
                yaw.sin() * pitch.cos(),
                pitch.sin(),
            );
            let eye = if far {
                Vec3::from(t.position) - forward * (60.0 + 7.0 * dz) + Vec3::Z * (40.0 + 4.0 * dz)
            } else {
                Vec3::from(t.position) + Vec3::new(dx, dy, dz)
            };
            let mut camera = Camera::look_at(eye.to_array(), (eye + forward).to_array(), fov, w, h);
            camera.forward = forward.to_array();
            if camera.validate().is_err() {
                return Ok(());
            }
            // A sparse pseudo-random mask (splitmix64 of the pixel index).
            let mask: Vec<bool> = (0..(w * h) as u64)
                .map(|i| {
                    let mut z = seed.wrapping_add(i.wrapping_mul(0x9E37_79B9_7F4A_7C15));
                    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
                    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
                    (((z ^ (z >> 31)) >> 11) as f64) < density * (1u64 << 53) as f64
                })
                .collect();
            let plain = prepared.render(&camera, &base).expect("render");
            let masked = prepared
                .render_cutoffs(&camera, &base, &[base.alpha_cutoff], Some(mask.clone()))
                .expect("render")
                .pop()
                .expect("one frame");
            let (a, b) = (&plain.drawn.target, &masked.target);
            for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
                let same = a.color()[i] == b.color()[i]
                    && a.depth()[i].to_bits() == b.depth()[i].to_bits()
                    && a.aux()[i] == b.aux()[i];
                if !same {
                    return Err(format!(
                        "pixel ({}, {}) of {w}x{h}: plain {:?} {} {}, masked {:?} {} {} (eye {eye}, far {far})",
                        i as u32 % w,
                        i as u32 / w,
                        a.color()[i],
                        a.depth()[i],
                        a.aux()[i],
                        b.color()[i],
                        b.depth()[i],
                        b.aux()[i],
                    ));
                }
            }
            if plain.drawn.trees_discarded != masked.trees_discarded {
                return Err(format!(
                    "trees discarded: plain {}, masked {}",
                    plain.drawn.trees_discarded, masked.trees_discarded
                ));
            }
            let (t0, t1) = (
                plain.drawn.tree_stats.triangles_in,
                masked.tree_stats.triangles_in,
            );
            if t1 > t0 {
                return Err(format!("masked draw took more triangles: {t1} > {t0}"));
            }
            skipped_cases.set(skipped_cases.get() + u32::from(t1 < t0));
            let around_eye = prepared.scene.instances.iter().any(|t| {
                let r = tree_footprint_radius(t, &metas[t.mesh as usize], false);
                (Vec3::from(t.position) - eye).dot(forward) < r + camera.near
                    && (Vec3::from(t.position) - eye).length() < r + 1.0
            });
            near_cases.set(near_cases.get() + u32::from(around_eye));
            let billboards = plain
                .selection
                .commands
                .iter()
                .zip(&plain.selection.data)
                .any(|(c, d)| d.billboard != 0 && c.instance_count > 0);
            billboard_cases.set(billboard_cases.get() + u32::from(billboards));
            Ok(())
        },
    );
    let (s, n, b) = (skipped_cases.get(), near_cases.get(), billboard_cases.get());
    println!(
        "of 96 cases: triangles left out in {s}, a tree around the eye in {n}, billboards in {b}"
    );
    assert!(
        s >= 20 && n >= 10 && b >= 20,
        "the cases missed what they must exercise"
    );
}

/// The alternative frames share one walk and one texture sample per fragment for all their
/// cutoffs (`draw_frame_cutoffs`: `raster::draw_passes` with the tree shader's one pass per
/// cutoff, issue 14): each frame must still be its own plain draw's, every buffer bit for bit
/// and every counter equal, unmasked as well as masked. Cameras close to the trees of `tiny`,
/// where the alpha test decides many pixels; the cutoffs must give frames that differ, or the
/// passes could have been mixed up unseen.
#[test]
fn shared_cutoff_passes_equal_their_own_draws() {
    use forestlod_shared::Camera;

    let params = Params::default();
    let scene = builtin::tiny();
    let cutoffs = [0.1, params.alpha_cutoff, 0.45, 0.8];
    let prepared = prepare(scene, &params).expect("prepare");
    let cameras: Vec<Camera> = ["close", "medium"]
        .iter()
        .map(|name| named_camera(name, &prepared.scene, 30.0, 160, 96).expect("camera"))
        .collect();
    let mut differing = 0;
    for camera in &cameras {
        let n = (camera.width * camera.height) as usize;
        let mask: Vec<bool> = (0..n).map(|i| (i * 7919) % 11 < 4).collect();
        let shared = prepared
            .render_cutoffs(camera, &params, &cutoffs, None)
            .expect("render");
        let masked = prepared
            .render_cutoffs(camera, &params, &cutoffs, Some(mask.clone()))
            .expect("render");
        assert_eq!((shared.len(), masked.len()), (cutoffs.len(), cutoffs.len()));
        let own: Vec<_> = cutoffs
            .iter()
            .map(|&alpha_cutoff| {
                let p = Params {
                    alpha_cutoff,
                    ..params
                };
                prepared.render(camera, &p).expect("render").drawn
            })
            .collect();
        for (k, ((s, m), o)) in shared.iter().zip(&masked).zip(&own).enumerate() {
            let what = format!("camera {:?}, cutoff {}", camera.eye, cutoffs[k]);
            let depth_bits = |d: &[f32]| d.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert!(s.target.color() == o.target.color(), "{what}: colour");
            assert_eq!(
                depth_bits(s.target.depth()),
                depth_bits(o.target.depth()),
                "{what}"
            );
            assert!(s.target.aux() == o.target.aux(), "{what}: LOD id");
            assert_eq!(
                (s.terrain_stats, s.tree_stats, s.trees_discarded),
                (o.terrain_stats, o.tree_stats, o.trees_discarded),
                "{what}: counters"
            );
            for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
                assert!(
                    m.target.color()[i] == o.target.color()[i]
                        && m.target.depth()[i].to_bits() == o.target.depth()[i].to_bits()
                        && m.target.aux()[i] == o.target.aux()[i],
                    "{what}: masked pixel {i}"
                );
            }
            if k > 0 {
                differing += own[k - 1]
                    .target
                    .color()
                    .iter()
                    .zip(o.target.color())
                    .filter(|(a, b)| a != b)
                    .count();
            }
        }
    }
    assert!(
        differing > 200,
        "the cutoffs must change the frames: {differing} pixels differ"
    );
}
