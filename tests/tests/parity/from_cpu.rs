//! `--stage-from-cpu` by stage name (`forestlod_harness::gpu_frame::StagesFromCpu`): a frame whose
//! first stages the reference computed, the GPU the rest, is judged against the reference frame
//! for every cut point of a cut plan with every stage in it (octree, coalescing on, front to back,
//! `refine`) and of a flat plan with `refine`: its commands must be the reference's exactly and
//! its image within the draw's tolerance; the frame reports which stage ran where, in the plan's
//! order. A cut point whose upload or binding is wrong (the coalesced list standing in for
//! the raw cut, run offsets off by one, the refined indirection missing) draws another image.

use forestlod_gpu::Compaction;
use forestlod_harness::alternatives::alpha_test_alternatives;
use forestlod_harness::context::gpu_context;
use forestlod_harness::gpu_frame::{GpuPipeline, GpuScene, RanOn, StagesFromCpu, gpu_draw};
use forestlod_harness::image_compare::{MaxDiffs, judge_image, print_max_diffs};
use forestlod_harness::stage::images_of;
use forestlod_reference::cameras::named_camera;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::builtin;
use forestlod_shared::{Coalesce, CommandOrder, FramePlan, Hierarchy, Params, StageId, TreeCull};

/// Every list a user can give, one cut point each (and the two aliases).
const LISTS: &[&str] = &[
    "none",
    "bake",
    "mips",
    "hier_select",
    "coalesce",
    "command_order",
    "refine",
    "select",
    "select,textures",
];

#[test]
fn every_cut_point_draws_the_reference_frame() {
    let Some(ctx) = gpu_context() else { return };
    let draw = gpu_draw(ctx);
    let cut = Params {
        hierarchy: Hierarchy::Octree as u32,
        coalesce: Coalesce::On as u32,
        command_order: CommandOrder::FrontToBack as u32,
        tree_cull: TreeCull::Lod0 as u32,
        texture_size: 64,
        ..Params::default()
    };
    let flat = Params {
        hierarchy: Hierarchy::Grid as u32,
        ..cut
    };
    let mut failures = Vec::new();
    let mut max: MaxDiffs = Default::default();
    for params in [cut, flat] {
        let plan = FramePlan::new(&params).expect("valid parameters");
        let prepared = prepare(builtin::by_name("tiny").unwrap(), &params).expect("prepare");
        let camera = named_camera("medium", &prepared.scene, 0.0, 320, 180).expect("camera");
        let want = images_of(
            &prepared
                .render(&camera, &params)
                .expect("reference frame")
                .drawn
                .target,
        );
        let alternatives = alpha_test_alternatives(&prepared, &camera, &params);
        let want_commands = prepared.select_stages(&camera, &params, false).selection;
        for list in LISTS {
            let from_cpu = StagesFromCpu::parse(list).expect("a stage list");
            let mut scene = GpuScene::with_pipelines(ctx, draw, &prepared, &params, from_cpu)
                .unwrap_or_else(|e| panic!("{list}: {e}"));
            let frame = scene
                .render(
                    &prepared,
                    GpuPipeline::Ours(Compaction::Stable),
                    &camera,
                    &params,
                )
                .unwrap_or_else(|e| panic!("{list}: {e}"));
            // The commands the draw read are the reference's (this small frame has no decision
            // within ε of a threshold), whichever stages ran where.
            let got = scene
                .chain()
                .expect("a frame of ours has a chain")
                .buffers()
                .read(ctx)
                .expect("read the frame's commands");
            assert_eq!(got.commands, want_commands.commands, "{list}: commands");
            assert_eq!(got.data, want_commands.data, "{list}: command data");
            assert_eq!(got.counters, want_commands.counters, "{list}: counters");
            // The frame ran the plan's stages in order, each where the list says.
            let ran: Vec<StageId> = frame.stages.iter().map(|&(s, _)| s).collect();
            assert_eq!(ran, plan.stages(), "{list}: the plan's stages in order");
            for &(stage, on) in &frame.stages {
                let want_on = if from_cpu.computes(&plan, stage) {
                    RanOn::Reference
                } else {
                    RanOn::Gpu
                };
                assert_eq!(on, want_on, "{list}: stage {}", stage.name());
            }
            let name = format!(
                "from-cpu/{}/{}",
                if plan.is_cut() { "octree" } else { "grid" },
                list.replace(',', "+")
            );
            if let Some(f) = judge_image(
                &name,
                &frame.images,
                &want,
                &alternatives,
                &camera,
                &mut max,
            ) {
                failures.push(f);
            }
        }
    }
    print_max_diffs("from-cpu frames", &max);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
