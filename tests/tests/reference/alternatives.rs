//! The parity's alternative frames drawn only where the frames disagree
//! (`image_compare::alternative_pixels`, `backend::alpha_test_alternatives_at`, issue 14) give the
//! same classified report as whole alternative frames: the main job and the parity tests may use
//! the cheap ones without changing a verdict, a count or a class image.

use forestlod_harness::backend::{alpha_test_alternatives, alpha_test_alternatives_at, images_of};
use forestlod_harness::image_compare::{alternative_pixels, compare_images};
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
