//! Parity of the point LOD's draw (issue 33 item 1, C§4.4, §4.6.3; `forestlod_shared::points`,
//! "the point command path"): the GPU twin (`point_commands.wgsl` expanding each LOD1 command
//! into `trees × n` quad instances, `draw.wgsl` decoding them and applying `point_keep`) against
//! the reference's point draw (`reference/src/draw.rs` `shade_points`), judged by the existing
//! image classes (`forestlod_harness::image_compare`, SPEC §8) after the stage checks.
//!
//! Scenarios: `tiny` (`tiny_params`, transition 400 m, 80 m band, dithered fade so the band's
//! screen door is judged too) under `lod1 = points` with the hole-free cut and the seed's
//! interval rule, from the `medium` camera, and from `close` with the transition pulled in to
//! 60 m (20 m band) so that near points cover many pixels, at 128², 256 points per mesh. Backends: the
//! draw alone (`from-cpu: select,textures`) and `select.wgsl` feeding it (`from-cpu: textures`).

use forestlod_harness::context::gpu_context;
use forestlod_harness::image_compare::{MaxDiffs, print_max_diffs};
use forestlod_harness::stage::{Backend, Draw, FrameInput, Reference};
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::builtin;
use forestlod_shared::points::{Lod1, PointSelect};
use forestlod_shared::{FadeMode, LOD_ID_BILLBOARD, LOD_ID_TRANSITION, Params};
use forestlod_tests::scenarios::tiny_params;
use forestlod_tests::{assert_no_failures, gpu_frame_failures};

/// The least LOD1 pixels (billboard or transition ids: the points' ids) the reference frame must
/// show, so the point path is judged rather than an empty LOD1. Why 200: measured 1349-1422
/// (`medium`) and 5524-5575 (`close`) on the reference; a far smaller count means the scenario
/// lost its points (the `far` camera, 8 km out, shows none: past the draw distance).
const MIN_POINT_PIXELS: usize = 200;

/// The frame side, pixels: small enough that four frames on two backends stay under a few
/// seconds on lavapipe, large enough that the far trees' squares cover several pixels.
const SIZE: u32 = 128;

/// Points per mesh: enough for a hierarchy of several levels, cheap to build (`prepare`).
const POINTS: u32 = 256;

#[test]
fn gpu_points_match_the_reference() {
    let Some(ctx) = gpu_context() else { return };
    let tiny = builtin::tiny();
    let base = Params {
        lod1: Lod1::Points as u32,
        point_count: POINTS,
        ..tiny_params(FadeMode::DitherSequential)
    };
    // `prepare` does not depend on `point_select` (per-frame), so one prepared scene serves both.
    let prepared = prepare(tiny.clone(), &base).expect("prepare tiny with points");
    let mut failures = Vec::new();
    let mut max = MaxDiffs::default();
    for select in PointSelect::ALL {
        for (camera_name, transition, band) in [("medium", 400.0, 80.0), ("close", 60.0, 20.0)] {
            let params = Params {
                point_select: select as u32,
                lod1_transition: transition,
                fade_width: band,
                ..base
            };
            let camera =
                forestlod_reference::cameras::named_camera(camera_name, &tiny, 0.0, SIZE, SIZE)
                    .expect("named camera");
            let input = FrameInput {
                prepared: &prepared,
                camera: &camera,
                params: &params,
            };
            let want = Backend::<Draw>::run(&Reference, input);
            let lod1 = want
                .lod_id
                .iter()
                .filter(|&&id| id == LOD_ID_BILLBOARD || id == LOD_ID_TRANSITION)
                .count();
            let name = format!("tiny-{camera_name}-{}", select.name());
            eprintln!("{name}: {lod1} LOD1 pixels in the reference frame");
            if lod1 < MIN_POINT_PIXELS {
                failures.push(format!(
                    "{name}: only {lod1} LOD1 pixels (want {MIN_POINT_PIXELS})"
                ));
            }
            failures.extend(gpu_frame_failures(ctx, &name, input, &want, &mut max));
        }
    }
    print_max_diffs("points parity", &max);
    assert_no_failures("point LOD parity failed", &failures);
}
