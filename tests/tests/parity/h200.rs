//! The first real GPU's logged pixels (`experiments/results/gpu_check_h200/`, an NVIDIA H200,
//! driver 580.159.04) classified on the reference alone (no adapter needed): each test renders
//! the reference frames `forestlod_harness::image_compare` judges a GPU pixel against, at the
//! logged pixel, and states which class explains the logged GPU value, or that none does. They
//! pin the analysis of the H200's single-pixel failures (issue notes of the real-GPU session):
//! - `parity::from_cpu`, pixel (154, 177) of `tiny` at 320x180: a mesh pixel whose depth was 77
//!   ulp off the reference's. The adapter takes the footprint ellipse's major axis for the scale
//!   factor (`parity::sampler_lod`), a coarser level on this sheared crown card, and the alpha
//!   test keeps another card: the reference frame under that model
//!   (`reference::sampler::LodRule::Ellipse`, one of `image_compare::LOD_RULES`) shows the H200's
//!   depth to 1 ulp, so the pixel is threshold-ambiguous;
//! - `parity::draw`, pixel (56, 104) of `synthetic-crop600-medium-none` at 160x160: the GPU shows
//!   a fading fragment (LOD id 3) of colour `[112, 127, 88]` where the reference shows a
//!   billboard `[84, 111, 50]`; no alternative frame (cutoff shifts, LOD models) shows it, nor do
//!   the reference frames probed while triaging (cutoffs 0.3 to 0.7, the transition moved by
//!   0.5 m and 5 m, the other fade modes), and it lies 34 outside the edge margin: unexplained,
//!   left failing on the H200 rather than forgiven by a wider class.

use forestlod_harness::alternatives::alpha_test_alternatives_at;
use forestlod_harness::image_compare::{COLOR_TOLERANCE, DEPTH_MAX_ULPS, Images};
use forestlod_reference::cameras::named_camera;
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::builtin;
use forestlod_shared::{Camera, Coalesce, CommandOrder, FadeMode, Hierarchy, Params, TreeCull};
use forestlod_tests::scenarios::{crop_params, cropped_synthetic};

/// The reference frame and its alternatives at pixel (`x`, `y`) (the harness's masked render of
/// the pixel's 3x3 neighbourhood, as `image_compare::alternative_pixels` asks for).
fn at_pixel(
    prepared: &Prepared,
    camera: &Camera,
    params: &Params,
    x: u32,
    y: u32,
) -> (Images, Vec<Images>) {
    let (w, h) = (camera.width, camera.height);
    let mut mask = vec![false; (w * h) as usize];
    for yy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
        for xx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
            mask[(yy * w + xx) as usize] = true;
        }
    }
    let want = forestlod_harness::stage::images_of(
        &prepared
            .render(camera, params)
            .expect("reference frame")
            .drawn
            .target,
    );
    (
        want,
        alpha_test_alternatives_at(prepared, camera, params, &mask),
    )
}

/// `|a - b|` in units in the last place of the (positive) reference depth `b`.
fn ulps(a: f32, b: f32) -> u32 {
    a.to_bits().abs_diff(b.to_bits())
}

#[test]
fn h200_from_cpu_depth_pixel_is_the_ellipse_lod_frames() {
    let params = Params {
        hierarchy: Hierarchy::Octree as u32,
        coalesce: Coalesce::On as u32,
        command_order: CommandOrder::FrontToBack as u32,
        tree_cull: TreeCull::Lod0 as u32,
        texture_size: 64,
        ..Params::default()
    };
    let prepared = prepare(builtin::by_name("tiny").unwrap(), &params).expect("prepare");
    let camera = named_camera("medium", &prepared.scene, 0.0, 320, 180).expect("camera");
    let (x, y, gpu_depth) = (154, 177, 0.998_327_5f32);
    let (want, alternatives) = at_pixel(&prepared, &camera, &params, x, y);
    let i = (y * camera.width + x) as usize;
    let reference = want.depth[i];
    let nearest = alternatives
        .iter()
        .map(|a| ulps(gpu_depth, a.depth[i]))
        .min()
        .expect("alternatives");
    eprintln!(
        "from-cpu ({x}, {y}): H200 depth {gpu_depth}, reference {reference} ({} ulp), nearest \
         alternative {nearest} ulp (of {} frames)",
        ulps(gpu_depth, reference),
        alternatives.len()
    );
    assert_eq!(reference, 0.998_322_9, "the reference frame changed");
    assert!(ulps(gpu_depth, reference) > DEPTH_MAX_ULPS);
    assert!(
        nearest <= DEPTH_MAX_ULPS,
        "no alternative frame explains the H200's depth ({nearest} ulp)"
    );
}

#[test]
fn h200_draw_colour_pixel_stays_unexplained() {
    let crop = cropped_synthetic(300.0);
    let prepared = prepare(crop.clone(), &crop_params(FadeMode::Alpha)).expect("prepare crop");
    let params = crop_params(FadeMode::None);
    let camera = named_camera("medium", &crop, 0.0, 160, 160).expect("camera");
    let (x, y, gpu) = (56, 104, [112u8, 127, 88, 255]);
    let (want, alternatives) = at_pixel(&prepared, &camera, &params, x, y);
    let i = (y * camera.width + x) as usize;
    let diff = |c: [u8; 4]| (0..4).map(|k| c[k].abs_diff(gpu[k])).max().unwrap_or(0);
    let nearest = alternatives
        .iter()
        .map(|a| diff(a.color[i]))
        .min()
        .expect("alternatives");
    eprintln!(
        "draw ({x}, {y}): H200 {gpu:?}, reference {:?} (id {}), nearest alternative {nearest} \
         away (of {} frames)",
        want.color[i],
        want.lod_id[i],
        alternatives.len()
    );
    assert_eq!(
        want.color[i],
        [84, 111, 50, 255],
        "the reference frame changed"
    );
    assert!(
        nearest > COLOR_TOLERANCE,
        "an alternative frame now explains the H200's colour: update the analysis"
    );
}
