//! Frames recorded from several threads on one GPU context equal their single-thread twins, bit
//! for bit (issue 10; the rule in `gpu/src/lib.rs`: no per-frame state behind `&self`).
//!
//! The flake this guards against: `GpuDraw::encode(&self)` wrote its one uniform buffer through
//! the queue, and two tests shared one `GpuDraw` through a static, so both threads' writes landed
//! before either submit and one frame was drawn with the other's camera (FLIP 0.465, most trees
//! missing). Here four threads share the context, the process-wide `GpuDraw` and `GpuPrimitive`
//! (the same statics the other GPU tests use), and each renders a *different* scenario (scene,
//! camera, fade mode, variant) several rounds in a row; every frame must equal the one that
//! scenario gave when rendered alone. The GPU pipeline is deterministic for a given input (stable
//! compaction, fixed submission order within a frame), so equality is exact: no tolerance.
//!
//! Mutation check (done by hand when this test was written): giving `GpuDraw` back a shared
//! uniform buffer written in `encode` makes this test fail within its first round.

use std::sync::Barrier;

use forestlod_harness::context::gpu_context;
use forestlod_harness::gpu_frame::{GpuPipeline, GpuScene, StagesFromCpu, gpu_draw, render_gpu};
use forestlod_harness::image_compare::Images;
use forestlod_reference::cameras::named_camera;
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::builtin;
use forestlod_shared::{Camera, FadeMode, Params};
use forestlod_tests::scenarios::{crop_params, cropped_synthetic, tiny_params};

/// Rounds each thread renders its scenario (each round must equal the single-thread frame).
const ROUNDS: usize = 3;

/// Side of the frames, pixels (small: lavapipe renders on the CPU).
const SIZE: u32 = 96;

/// One scenario: which prepared scene, camera, parameters and pipeline.
struct Case {
    name: String,
    scene: usize,
    camera: Camera,
    params: Params,
    /// `None`: `render_gpu` (fresh buffers per frame, shared `GpuDraw`); `Some`: a
    /// `GpuScene` owned by the thread (shared `GpuDraw` and `GpuPrimitive`).
    variant: Option<GpuPipeline>,
}

fn scenes() -> Vec<(Prepared, Params)> {
    let tiny = builtin::tiny();
    let crop = cropped_synthetic(300.0);
    let tiny_p = tiny_params(FadeMode::Alpha);
    let crop_p = crop_params(FadeMode::Alpha);
    vec![
        (prepare(tiny, &tiny_p).expect("prepare tiny"), tiny_p),
        (prepare(crop, &crop_p).expect("prepare crop"), crop_p),
    ]
}

fn cases(scenes: &[(Prepared, Params)]) -> Vec<Case> {
    let camera = |scene: usize, name: &str, yaw: f32| {
        named_camera(name, &scenes[scene].0.scene, yaw, SIZE, SIZE).expect("named camera")
    };
    let with_fade = |scene: usize, fade: FadeMode| Params {
        fade_mode: fade as u32,
        ..scenes[scene].1
    };
    vec![
        Case {
            name: "tiny-close-yaw0-alpha".into(),
            scene: 0,
            camera: camera(0, "close", 0.0),
            params: with_fade(0, FadeMode::Alpha),
            variant: None,
        },
        Case {
            name: "tiny-medium-yaw120-dither".into(),
            scene: 0,
            camera: camera(0, "medium", 120.0),
            params: with_fade(0, FadeMode::DitherSequential),
            variant: None,
        },
        Case {
            name: "crop-medium-yaw0-vegetation".into(),
            scene: 1,
            camera: camera(1, "medium", 0.0),
            params: with_fade(1, FadeMode::Alpha),
            variant: Some(GpuPipeline::Vegetation),
        },
        Case {
            name: "crop-close-yaw200-primitive".into(),
            scene: 1,
            camera: camera(1, "close", 200.0),
            params: with_fade(1, FadeMode::None),
            variant: Some(GpuPipeline::Primitive),
        },
    ]
}

/// `rounds` frames of `case`, each rendered from scratch by its pipeline.
fn render(case: &Case, prepared: &Prepared, prepared_with: &Params, rounds: usize) -> Vec<Images> {
    let ctx = gpu_context().expect("checked by the caller");
    match case.variant {
        None => (0..rounds)
            .map(|_| {
                render_gpu(
                    ctx,
                    gpu_draw(ctx),
                    prepared,
                    &case.camera,
                    &case.params,
                    StagesFromCpu::default(),
                )
                .unwrap_or_else(|e| panic!("{}: {e}", case.name))
                .images
            })
            .collect(),
        Some(variant) => {
            let mut sweep = GpuScene::new(ctx, prepared, prepared_with, StagesFromCpu::NONE)
                .unwrap_or_else(|e| panic!("{}: {e}", case.name));
            (0..rounds)
                .map(|_| {
                    sweep
                        .render(prepared, variant, &case.camera, &case.params)
                        .unwrap_or_else(|e| panic!("{}: {e}", case.name))
                        .images
                })
                .collect()
        }
    }
}

/// How many pixels of any buffer differ (0 when equal).
fn differing_pixels(a: &Images, b: &Images) -> usize {
    assert_eq!((a.width, a.height), (b.width, b.height));
    (0..a.color.len())
        .filter(|&i| {
            a.color[i] != b.color[i]
                || a.depth[i].to_bits() != b.depth[i].to_bits()
                || a.lod_id[i] != b.lod_id[i]
        })
        .count()
}

#[test]
fn frames_from_several_threads_equal_their_single_thread_twins() {
    if gpu_context().is_none() {
        return; // FORESTLOD_ALLOW_NO_GPU=1 (gpu_context printed that it skips)
    }
    let scenes = scenes();
    let cases = cases(&scenes);
    // Alone: each scenario once, one after the other.
    let alone: Vec<Images> = cases
        .iter()
        .map(|c| {
            let (prepared, with) = &scenes[c.scene];
            render(c, prepared, with, 1).remove(0)
        })
        .collect();
    // The scenarios must differ from each other, or a mixed-up frame could not be seen.
    for i in 0..cases.len() {
        for j in i + 1..cases.len() {
            if alone[i].width == alone[j].width {
                assert!(
                    differing_pixels(&alone[i], &alone[j]) > 100,
                    "{} and {} render alike: the test could not see frames swapped",
                    cases[i].name,
                    cases[j].name
                );
            }
        }
    }
    // Together: one thread per scenario, started at once, ROUNDS frames each.
    let barrier = Barrier::new(cases.len());
    let together: Vec<Vec<Images>> = std::thread::scope(|s| {
        let handles: Vec<_> = cases
            .iter()
            .map(|c| {
                let (prepared, with) = &scenes[c.scene];
                let barrier = &barrier;
                s.spawn(move || {
                    barrier.wait();
                    render(c, prepared, with, ROUNDS)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("render thread"))
            .collect()
    });
    let mut failures = Vec::new();
    let mut worst = 0;
    for ((case, alone), frames) in cases.iter().zip(&alone).zip(&together) {
        for (round, frame) in frames.iter().enumerate() {
            let n = differing_pixels(alone, frame);
            worst = worst.max(n);
            if n != 0 {
                failures.push(format!(
                    "{} round {round}: {n} pixels differ from the single-thread frame",
                    case.name
                ));
            }
        }
    }
    println!(
        "{} scenarios x {ROUNDS} rounds on {} threads: at most {worst} pixels differ",
        cases.len(),
        cases.len()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
