//! Draw parity of the octahedral impostors' depth channel (issue 32, `shared/src/octahedral.rs`
//! module docs; reference `octahedral_texel`, `draw.wgsl`'s blend): the walk of
//! `every_stage.rs` reaches `octahedral_depth = on`, but its frames and image classes cannot tell
//! a parallax step from none (measured: a GPU mutant that ignored the depth passed the walk). So
//! this test asks which reference frame the GPU's frame is the twin of: on a close view of the
//! cropped `synthetic`, every tree an impostor of a coarse 4×4 hemi grid, the GPU frame drawn
//! from the reference's textures (depth layers included) must pass the image classes against the
//! reference's depth frame, and its mean colour difference from it over the impostor pixels must
//! be under [`TWIN_SHARE_MAX`] of the difference between the reference's depth and plane frames.
//! Mutation-checked: the parallax step zeroed in `common.wgsl` (`octahedral_parallax_uv`) fails
//! the image classes here (FLIP mean 0.0995 against the bound 0.03), which the walk did not.

use forestlod_harness::alternatives::alpha_test_alternatives;
use forestlod_harness::backend::GpuRenderer;
use forestlod_harness::context::gpu_context;
use forestlod_harness::gpu_frame::StagesFromCpu;
use forestlod_harness::image_compare::{Images, compare_images, write_failure_images};
use forestlod_harness::stage::{Backend, Draw, FrameInput, Named, Reference};
use forestlod_reference::draw::LOD_ID_BILLBOARD;
use forestlod_reference::pipeline::prepare;
use forestlod_shared::{AzimuthMode, FadeMode, OctahedralDepth, Params, ViewSphere};
use forestlod_tests::scenarios::{crop_params, cropped_synthetic};

/// The most of the plane-to-depth difference the GPU's frame may keep from its twin (mean
/// colour difference over the impostor pixels): the twins differ by the image classes' pixels
/// (sampler rounding, alpha-edge pixels), a small share; a GPU that ignores the depth keeps all
/// of it. Measured on lavapipe: 0.358 of 7.176 (share 0.050) over 18,933 impostor pixels.
const TWIN_SHARE_MAX: f64 = 0.35;

/// Least impostor pixels the reference frame must show for the comparison to mean something.
const MIN_IMPOSTOR_PIXELS: usize = 2000;

fn mean_colour_difference(a: &Images, b: &Images, mask: &[bool]) -> f64 {
    let (mut sum, mut n) = (0u64, 0u64);
    for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
        sum += (0..3)
            .map(|c| u64::from(a.color[i][c].abs_diff(b.color[i][c])))
            .sum::<u64>();
        n += 3;
    }
    sum as f64 / n.max(1) as f64
}

#[test]
fn gpu_depth_channel_draw_is_the_references_twin() {
    let Some(ctx) = gpu_context() else { return };
    let crop = cropped_synthetic(150.0);
    let params = |depth: OctahedralDepth| Params {
        lod1_transition: 0.0,
        fade_width: 0.0,
        billboard_views: ViewSphere::HemiOctahedral as u32,
        octahedral_grid: 4,
        octahedral_blend: AzimuthMode::Blend as u32,
        octahedral_depth: depth as u32,
        ..crop_params(FadeMode::DitherSequential)
    };
    let (on, off) = (params(OctahedralDepth::On), params(OctahedralDepth::Off));
    let camera = forestlod_reference::cameras::named_camera("close", &crop, 0.0, 192, 160)
        .expect("named camera");
    let with_depth = prepare(crop.clone(), &on).expect("prepare with depth");
    let plane = prepare(crop, &off).expect("prepare without depth");
    let input = FrameInput {
        prepared: &with_depth,
        camera: &camera,
        params: &on,
    };
    let want = Backend::<Draw>::run(&Reference, input);
    let want_plane = Backend::<Draw>::run(
        &Reference,
        FrameInput {
            prepared: &plane,
            camera: &camera,
            params: &off,
        },
    );
    let mask: Vec<bool> = want
        .lod_id
        .iter()
        .map(|&id| id == LOD_ID_BILLBOARD)
        .collect();
    let impostor_pixels = mask.iter().filter(|&&m| m).count();
    assert!(
        impostor_pixels >= MIN_IMPOSTOR_PIXELS,
        "only {impostor_pixels} impostor pixels (want {MIN_IMPOSTOR_PIXELS})"
    );
    let backend = GpuRenderer {
        ctx,
        option: StagesFromCpu::TEXTURES,
    };
    let got = backend.run(input);
    let label = format!("octahedral-depth/{}", backend.name());
    let alternatives = alpha_test_alternatives(&with_depth, &camera, &on);
    let report = compare_images(&label, &got, &want, &alternatives, &camera);
    eprintln!("{report}");
    if !report.passed() {
        let dir = write_failure_images(&report, &got, &want);
        panic!(
            "{label}: {} (images in {})",
            report.failures().join("; "),
            dir.display()
        );
    }
    let twin = mean_colour_difference(&got, &want, &mask);
    let parallax = mean_colour_difference(&want_plane, &want, &mask);
    eprintln!(
        "{impostor_pixels} impostor pixels: GPU vs reference (depth) {twin:.3}, reference plane vs \
         depth {parallax:.3} (share {:.3}, bound {TWIN_SHARE_MAX})",
        twin / parallax
    );
    assert!(
        parallax > 0.5,
        "the depth channel changed almost nothing ({parallax:.3})"
    );
    assert!(
        twin <= TWIN_SHARE_MAX * parallax,
        "the GPU's frame is {twin:.3} from the reference's depth frame, which is {parallax:.3} from \
         its plane frame: the GPU does not draw the depth channel's parallax"
    );
}
