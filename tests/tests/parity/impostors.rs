//! Parity of hierarchical impostors' frame (issue 33 item 2, C§4.6.3, Alg. 9;
//! `forestlod_shared::impostor`): the GPU's cut (`hier_select.wgsl`'s `impostor_code`) and draw
//! (`draw.wgsl`'s impostor arm of `far_vertex` and its nearest-texel fragment) of each frame of a
//! short camera path against the reference's (`Prepared::render_impostors`), both reading the
//! same impostor state: the reference's `ImpostorCache`, stepped once per frame, uploaded over
//! the GPU scene's far level (`GpuScene::render_impostors`). The tiles are rendered by the
//! reference; the GPU draws them. Judged by the existing image classes
//! (`forestlod_harness::image_compare`, SPEC §8) with the alternatives drawn on the frame's
//! impostor state (`alpha_test_alternatives_on`).
//!
//! Scenario: 400 trees of the five built-in species on a 600 m square (as the impostor
//! properties), an octree, impostors from 100 m at up to depth 3 in 16 tiles of 64², refreshed
//! two per frame; 4 frames of a camera 500 m west of the forest at 60 m, moving 40 m east and
//! 20 m north per frame, 160x90. Frame 0 creates the impostors; frames 1-3 draw them from an eye
//! they were not rendered from (until refreshed), so the quads' world placement is judged.

use forestlod_gpu::Compaction;
use forestlod_harness::context::gpu_context;
use forestlod_harness::gpu_frame::{GpuPipeline, GpuScene, StagesFromCpu, gpu_draw};
use forestlod_harness::image_compare::{Images, MaxDiffs, judge_image, print_max_diffs};
use forestlod_reference::impostor_cache::ImpostorCache;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::Scene;
use forestlod_shared::{Camera, FadeMode, FarLod, Hierarchy, LOD_ID_FAR, Params};
use forestlod_tests::{assert_no_failures, species_forest};

/// The least impostor pixels (`LOD_ID_FAR`) a reference frame of the path must show, so the
/// impostor path is judged rather than an empty far level. Why 100: measured 147-347 on this path
/// (11-16 impostors); far fewer means the scenario lost its impostors.
const MIN_IMPOSTOR_PIXELS: usize = 100;

/// Frames of the path: the first creates, the others draw moved impostors and refresh some.
const FRAMES: usize = 4;

/// The frame size: small enough for 4 frames of two backends in a few seconds on lavapipe.
const SIZE: (u32, u32) = (160, 90);

/// The forest's parameters (module docs). Dithered fades, so that the screen door of the other
/// trees is judged beside the impostors.
fn params() -> Params {
    Params {
        hierarchy: Hierarchy::Octree as u32,
        lod_levels: 3,
        far_lod: FarLod::Impostor as u32,
        fade_mode: FadeMode::DitherSequential as u32,
        lod1_transition: 150.0,
        fade_width: 30.0,
        far_start: 150.0,
        texture_size: 32,
        grid_size: 100.0,
        impostor_pixels: 64,
        impostor_tiles: 16,
        impostor_min_distance: 100.0,
        impostor_max_depth: 3,
        impostor_update_interval: 1,
        impostor_refresh_interval: 1,
        impostor_refresh_number: 2,
        ..Params::default()
    }
}

/// 400 trees of the five species on a 600 m square (`impostor_properties.rs`'s forest).
fn forest() -> Scene {
    species_forest(400)
}

/// The GPU side of `prepared`: its buffers, the reference's textures.
fn gpu_scene(
    ctx: &'static forestlod_gpu::GpuContext,
    prepared: &forestlod_reference::pipeline::Prepared,
    params: &Params,
) -> GpuScene<'static> {
    GpuScene::with_pipelines(
        ctx,
        gpu_draw(ctx),
        prepared,
        params,
        StagesFromCpu::TEXTURES,
    )
    .expect("GPU scene")
}

#[test]
fn gpu_impostor_frames_match_the_reference_along_a_path() {
    let Some(ctx) = gpu_context() else { return };
    let params = params();
    let prepared = prepare(forest(), &params).expect("prepare the forest");
    let mut scene = gpu_scene(ctx, &prepared, &params);
    let mut cache = ImpostorCache::new(&prepared, &params).expect("impostor cache");
    let mut failures = Vec::new();
    let mut max = MaxDiffs::default();
    for k in 0..FRAMES {
        let eye = [-500.0 + 40.0 * k as f32, 300.0 + 20.0 * k as f32, 60.0];
        let camera = Camera::look_at(eye, [300.0, 300.0, 10.0], 50.0, SIZE.0, SIZE.1);
        let step = cache.step(&prepared, &camera, &params).expect("step");
        let frame = prepared
            .render_impostors(&camera, &params, &cache)
            .expect("reference frame");
        let target = &frame.drawn.target;
        let want = Images {
            width: target.width(),
            height: target.height(),
            color: target.color().to_vec(),
            depth: target.depth().to_vec(),
            lod_id: target.aux().to_vec(),
        };
        let far_pixels = want.lod_id.iter().filter(|&&id| id == LOD_ID_FAR).count();
        let name = format!("impostor path frame {k}");
        eprintln!(
            "{name}: {} impostors ({} created, {} refreshed, {} removed), {far_pixels} impostor pixels",
            cache.occupancy().1,
            step.created,
            step.refreshed,
            step.removed
        );
        if far_pixels < MIN_IMPOSTOR_PIXELS {
            failures.push(format!(
                "{name}: only {far_pixels} impostor pixels (want {MIN_IMPOSTOR_PIXELS})"
            ));
        }
        let got = scene
            .render_impostors(
                &prepared,
                GpuPipeline::Ours(Compaction::Stable),
                &camera,
                &params,
                cache.level(),
            )
            .expect("GPU frame");
        let got_far = got
            .images
            .lod_id
            .iter()
            .filter(|&&id| id == LOD_ID_FAR)
            .count();
        eprintln!("{name}: {got_far} impostor pixels on the GPU");
        let alternatives = forestlod_harness::alternatives::alpha_test_alternatives_on(
            &prepared,
            cache.level(),
            &camera,
            &params,
        );
        failures.extend(judge_image(
            &name,
            &got.images,
            &want,
            &alternatives,
            &camera,
            &mut max,
        ));
    }
    print_max_diffs("impostor path parity", &max);
    assert_no_failures("impostor path parity failed", &failures);
}

/// Bad input to `GpuScene::render_impostors` is refused with an error naming the field: a frame
/// whose parameters draw no impostors, and an impostor state of another shape than the scene's
/// (here an atlas of other tile counts).
#[test]
fn gpu_impostor_frames_refuse_a_foreign_state() {
    let Some(ctx) = gpu_context() else { return };
    let params = params();
    let prepared = prepare(forest(), &params).expect("prepare the forest");
    let mut scene = gpu_scene(ctx, &prepared, &params);
    let camera = Camera::look_at([-500.0, 300.0, 60.0], [300.0, 300.0, 10.0], 50.0, 32, 18);
    let cache = ImpostorCache::new(&prepared, &params).expect("impostor cache");
    let pipeline = GpuPipeline::Ours(Compaction::Stable);
    let cube = Params {
        far_lod: FarLod::OctantCube as u32,
        ..params
    };
    let err = scene
        .render_impostors(&prepared, pipeline, &camera, &cube, cache.level())
        .expect_err("octant cubes are no impostor frame");
    assert!(err.to_string().contains("far_lod"), "{err}");
    let other = Params {
        impostor_tiles: params.impostor_tiles + 1,
        ..params
    };
    let foreign = ImpostorCache::new(&prepared, &other).expect("impostor cache");
    let err = scene
        .render_impostors(&prepared, pipeline, &camera, &other, foreign.level())
        .expect_err("an atlas of another shape");
    assert!(err.to_string().contains("far level"), "{err}");
}
