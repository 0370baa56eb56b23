//! Parity of the GPU `refine` stage (`gpu/src/shaders/refine.wgsl`, beyond the thesis: per-tree
//! culling of the selected commands) with the reference (`reference/src/refine.rs`):
//! - **buffers**: the refined commands and the indirection ranges they use equal the reference's
//!   exactly, in order (a stable compaction), with the copy of the batch indirection in `[2n, 3n)`
//!   and the counters (trees tested, kept). Each frame is refined three ways: the reference's
//!   selection uploaded (`SelectBuffers::from_cpu`, so `refine.wgsl` alone is judged), and
//!   `select.wgsl`'s own output (stable and atomic compaction, refined in the select buffers with
//!   their spare capacity) judged against the reference's `refine` of that same selection. Trees
//!   whose decision sits within [`AMBIGUITY_REL`] of a threshold are classified *ambiguous*
//!   (counted, reported) instead of failing. Scenes: `tiny` and the cropped `synthetic` of
//!   `parity::draw`, each at three grid sizes (down to one batch of every tree: hundreds of scan
//!   chunks), from the named cameras at three yaws, `tree_cull` `lod0` and `all`, the draw
//!   distance as given and pulled in to 150 m; 64 random cameras and parameters around each
//!   scene; 64 random scenes of card trees with random cameras.
//! - **oracle**: under `all`, the (tree, LOD) pairs the GPU draws (refining the reference's
//!   selection) are the per-tree oracle's (`select::select_per_tree`), up to ambiguous trees; the
//!   exact property on the reference side lives in `properties/refine_properties.rs`.
//! - **images**: frames with `tree_cull` `lod0` and `all` rendered by the sweeps' runner
//!   (`GpuScene`, `GpuPipeline::Ours` with both compactions, GPU textures) and by the main
//!   job's `render_gpu` (selection from the GPU, refined by `refine.wgsl`, and from the CPU,
//!   refined by the reference, with its `3n` indirection uploaded) against the reference frame
//!   (`Prepared::render`, which honours `tree_cull`), judged by `forestlod_harness::image_compare`
//!   with its named tolerances and alternative frames.
//!
//! Without an adapter the tests fail with an install hint unless `FORESTLOD_ALLOW_NO_GPU=1`.

use std::collections::BTreeSet;
use std::time::Instant;

use forestlod_gpu::{
    Compaction, CullTree, GpuContext, GpuRefine, GpuRefined, GpuSelect, RefineCounters,
    SelectBuffers,
};
use forestlod_harness::alternatives::alpha_test_alternatives;
use forestlod_harness::context::gpu_context;
use forestlod_harness::gpu_frame::{GpuPipeline, GpuScene, StagesFromCpu, gpu_draw, render_gpu};
use forestlod_harness::image_compare::{Images, MaxDiffs, judge_image, print_max_diffs};
use forestlod_harness::stage::images_of;
use forestlod_harness::stats::decision_budget_failure;
use forestlod_reference::batches::{Batches, build_batches};
use forestlod_reference::cameras::named_camera;
use forestlod_reference::geometry::PackedGeometry;
use forestlod_reference::pipeline::Prepared;
use forestlod_reference::refine::refine;
use forestlod_reference::scene::{Scene, builtin};
use forestlod_reference::select::{SelectUniform, Selection, select, select_per_tree};
use forestlod_shared::{Camera, FadeMode, LOD_MESH, Params, TreeCull, view_interval};
use forestlod_tests::scenarios::{
    FrameScenario, crop_params, cropped_synthetic, named_views, tiny_and_crop_frames, tiny_params,
};
use forestlod_tests::{
    CullInput, Thresholds, assert_no_failures, cameras, cameras_around, half_side, instances,
    params, params_around, run_cases, scene_of, threshold_ambiguity,
};
use proptest::prelude::*;

/// Relative distance to a threshold within which the GPU and the reference may keep a tree
/// differently.
///
/// Why: the same as `parity::select`'s and `parity::baselines`' `AMBIGUITY_REL` (the same interval
/// and plane arithmetic, `common.wgsl` `decide_sphere` and `within_draw_distance`, on the same
/// `f32` spheres): the GPU compiler may contract `a * b + c` into a fused multiply-add, which
/// moves an interval end, the centre's depth or a plane distance by a few ulp of `|c - e|₁ + r`;
/// 1e-5 of that is some 80 ulp, ample for any such rounding and far below what a wrong rule
/// moves it by.
const AMBIGUITY_REL: f32 = 1e-5;

/// Random cases per random property.
const CASES: u32 = 64;

/// The refinement modes under test (`none` does not run the stage).
const MODES: [TreeCull; 2] = [TreeCull::Lod0, TreeCull::All];

/// Why a tree's refinement is ambiguous, or `None` when it is not near any threshold: the
/// interval's near end against the draw distance, the centre's depth against it (the per-tree
/// discard), the interval's ends against the fade band (which LODs it needs) and the six plane
/// distances against `-r - m`.
fn ambiguity(center: [f32; 3], radius: f32, u: &SelectUniform) -> Option<String> {
    threshold_ambiguity(
        center,
        radius,
        u,
        AMBIGUITY_REL,
        Thresholds::TREE_REFINEMENT,
    )
}

/// Tallies of the buffer comparisons, printed at the end.
#[derive(Clone, Debug, Default)]
struct Tally {
    cases: u32,
    exact_cases: u32,
    ambiguous_cases: u32,
    commands: u64,
    refined_commands: u64,
    trees_tested: u64,
    trees_kept: u64,
    ambiguous_trees: u64,
    /// GPU-selection cases whose selection differed from the reference's (ambiguous batches,
    /// judged by `parity::select`); refine is still judged against the reference's `refine` of
    /// the GPU's own selection.
    selection_differs: u32,
    /// Cases where the oracle (per-tree) comparison ran.
    oracle_cases: u32,
}

impl std::fmt::Display for Tally {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} refines ({} exact, {} with ambiguous trees), {} commands ({} refined), \
             {} trees tested, {} kept, {} ambiguous trees, {} GPU selections differing from the \
             reference's, {} oracle comparisons",
            self.cases,
            self.exact_cases,
            self.ambiguous_cases,
            self.commands,
            self.refined_commands,
            self.trees_tested,
            self.trees_kept,
            self.ambiguous_trees,
            self.selection_differs,
            self.oracle_cases
        )
    }
}

/// One batching of a scene on both sides.
struct Batched<'a> {
    batches: Batches,
    geometry: &'a PackedGeometry,
    spheres: &'a [([f32; 3], f32)],
    select: GpuSelect<'static>,
    refine: GpuRefine<'static>,
}

impl<'a> Batched<'a> {
    fn new(
        ctx: &'static GpuContext,
        scene: &Scene,
        geometry: &'a PackedGeometry,
        spheres: &'a [([f32; 3], f32)],
        trees: &[CullTree],
        grid: f32,
    ) -> Result<Self, String> {
        let batches = build_batches(scene, &geometry.meshes, grid).map_err(|e| e.to_string())?;
        let select = GpuSelect::new(ctx, &batches.metas, &geometry.meshes, &geometry.billboard)
            .map_err(|e| e.to_string())?;
        let refine = GpuRefine::new(ctx, trees, &batches.indirection).map_err(|e| e.to_string())?;
        Ok(Self {
            batches,
            geometry,
            spheres,
            select,
            refine,
        })
    }
}

/// Judges the GPU's refinement `got` of the selection `input` against the reference's `refine`
/// of the same selection (module docs). With `oracle`, `input` is the reference's selection and
/// under `all` the GPU's (tree, LOD) pairs are also checked against the per-tree oracle.
#[allow(clippy::too_many_arguments)]
fn judge(
    name: &str,
    b: &Batched,
    input: &Selection,
    got: &GpuRefined,
    camera: &Camera,
    params: &Params,
    oracle: bool,
    tally: &mut Tally,
) -> Result<(), String> {
    let ind = &b.batches.indirection;
    let n = ind.len() as u32;
    let mode = params.tree_culling().map_err(|e| e.to_string())?;
    let mut want = input.clone();
    let r = refine(&mut want, ind, b.spheres, camera, params);
    let g = &got.selection;
    tally.cases += 1;
    tally.commands += input.commands.len() as u64;
    tally.trees_tested += r.trees_tested;
    tally.trees_kept += r.trees_kept;

    // Untouched: counters, data, command count, the copy of the batch indirection.
    if g.counters != input.counters
        || g.data != input.data
        || g.commands.len() != want.commands.len()
    {
        return Err(format!(
            "{name}: refine changed the counters, data or command count ({:?} vs {:?}, {} vs {} \
             commands)",
            g.counters,
            input.counters,
            g.commands.len(),
            want.commands.len()
        ));
    }
    if got.indirection.len() != 3 * n as usize {
        return Err(format!(
            "{name}: indirection of {} entries, expected 3n = {}",
            got.indirection.len(),
            3 * n
        ));
    }
    if &got.indirection[2 * n as usize..] != ind.as_slice() {
        return Err(format!("{name}: [2n, 3n) is not the batch indirection"));
    }

    let u = SelectUniform::new(camera, params);
    let mut ambiguous: BTreeSet<u32> = BTreeSet::new();
    let mut gpu_kept = 0u64;
    let mut pairs: BTreeSet<(u32, u32)> = BTreeSet::new();
    for (i, ((o, w), (c, d))) in input
        .commands
        .iter()
        .zip(&want.commands)
        .zip(g.commands.iter().zip(&g.data))
        .enumerate()
    {
        if (c.index_count, c.first_index, c.base_vertex)
            != (o.index_count, o.first_index, o.base_vertex)
        {
            return Err(format!(
                "{name}: command {i}: index range or base_vertex changed: {c:?} from {o:?}"
            ));
        }
        if c.first_instance != w.first_instance {
            return Err(format!(
                "{name}: command {i} (LOD {}): first_instance {} but the reference's {} (input \
                 {o:?}, n = {n})",
                d.lod, c.first_instance, w.first_instance
            ));
        }
        let range = |fi: u32, len: u32, what: &str| -> Result<std::ops::Range<usize>, String> {
            let r = fi as usize..fi as usize + len as usize;
            if r.end > 3 * n as usize {
                Err(format!(
                    "{name}: command {i}: {what} range {r:?} past 3n = {}",
                    3 * n
                ))
            } else {
                Ok(r)
            }
        };
        let batch = &ind[range(o.first_instance, o.instance_count, "batch")?];
        let wl = &r.indirection[range(w.first_instance, w.instance_count, "reference")?];
        let gl = &got.indirection[range(c.first_instance, c.instance_count, "GPU")?];
        if !mode.refines(d.lod) {
            if c.instance_count != o.instance_count {
                return Err(format!(
                    "{name}: unrefined command {i} (LOD {}): instance_count {} changed from {}",
                    d.lod, c.instance_count, o.instance_count
                ));
            }
            pairs.extend(gl.iter().map(|&t| (t, d.lod)));
            continue;
        }
        tally.refined_commands += 1;
        gpu_kept += gl.len() as u64;
        // The GPU's list is a subsequence of its batch, in batch order.
        let mut it = batch.iter();
        if let Some(t) = gl.iter().find(|&&t| !it.any(|&x| x == t)) {
            return Err(format!(
                "{name}: command {i} (LOD {}): tree {t} is not in batch order (or not in the \
                 batch): GPU {gl:?}, batch {batch:?}",
                d.lod
            ));
        }
        pairs.extend(gl.iter().map(|&t| (t, d.lod)));
        if gl == wl {
            continue;
        }
        let (ws, gs): (BTreeSet<u32>, BTreeSet<u32>) =
            (wl.iter().copied().collect(), gl.iter().copied().collect());
        for &t in ws.symmetric_difference(&gs) {
            let (center, radius) = b.spheres[t as usize];
            match ambiguity(center, radius, &u) {
                Some(why) => {
                    eprintln!(
                        "{name}: tree {t} ambiguous in command {i} LOD {} ({why}): reference {}, \
                         GPU {}",
                        d.lod,
                        ws.contains(&t),
                        gs.contains(&t)
                    );
                    ambiguous.insert(t);
                }
                None => {
                    return Err(format!(
                        "{name}: command {i} (LOD {}): tree {t} (sphere {center:?} r {radius}) is \
                         {} by the GPU but {} by the reference, and is not within \
                         {AMBIGUITY_REL} of any threshold (interval {:?})\n  GPU {gl:?}\n  ref \
                         {wl:?}",
                        d.lod,
                        if gs.contains(&t) { "kept" } else { "dropped" },
                        if ws.contains(&t) { "kept" } else { "dropped" },
                        view_interval(center, radius, u.eye, u.forward)
                    ));
                }
            }
        }
        let strip = |l: &[u32]| -> Vec<u32> {
            l.iter()
                .copied()
                .filter(|t| !ambiguous.contains(t))
                .collect()
        };
        if strip(gl) != strip(wl) {
            return Err(format!(
                "{name}: command {i} (LOD {}): the unambiguous trees differ in order\n  GPU \
                 {gl:?}\n  ref {wl:?}",
                d.lod
            ));
        }
    }

    // Counters: tested never depends on a decision; kept is the GPU's own sum, and the
    // reference's when nothing is ambiguous.
    let expect = RefineCounters {
        trees_tested: r.trees_tested as u32,
        trees_kept: gpu_kept as u32,
    };
    if got.counters != expect {
        return Err(format!(
            "{name}: counters {:?}, expected {expect:?} (reference kept {})",
            got.counters, r.trees_kept
        ));
    }

    // The per-tree oracle under `all`: the GPU's (tree, LOD) pairs are the oracle's.
    if oracle && mode == TreeCull::All {
        tally.oracle_cases += 1;
        let want_pairs: BTreeSet<(u32, u32)> = select_per_tree(b.spheres, camera, params)
            .iter()
            .enumerate()
            .flat_map(|(t, decision)| {
                let need = decision.needs();
                [
                    need.lod0.then_some((t as u32, LOD_MESH)),
                    need.lod1.then_some((t as u32, 1)),
                ]
            })
            .flatten()
            .collect();
        if let Some(&(t, lod)) = pairs.symmetric_difference(&want_pairs).find(|(t, _)| {
            !ambiguous.contains(t) && {
                let (c, r) = b.spheres[*t as usize];
                ambiguity(c, r, &u).is_none()
            }
        }) {
            return Err(format!(
                "{name}: under `all` the GPU {} (tree {t}, LOD {lod}) but the per-tree oracle {}",
                if pairs.contains(&(t, lod)) {
                    "draws"
                } else {
                    "does not draw"
                },
                if want_pairs.contains(&(t, lod)) {
                    "does"
                } else {
                    "does not"
                }
            ));
        }
    }

    if ambiguous.is_empty() {
        if gpu_kept != r.trees_kept {
            return Err(format!(
                "{name}: {gpu_kept} trees kept, the reference {}",
                r.trees_kept
            ));
        }
        tally.exact_cases += 1;
    } else {
        tally.ambiguous_cases += 1;
        tally.ambiguous_trees += ambiguous.len() as u64;
    }
    Ok(())
}

/// One frame refined three ways (module docs) and judged.
fn check_frame(
    ctx: &'static GpuContext,
    name: &str,
    b: &mut Batched,
    camera: &Camera,
    params: &Params,
    tally: &mut Tally,
) -> Result<(), String> {
    let e = |e: forestlod_gpu::GpuError| format!("{name}: {e}");
    let g = b.geometry;
    let reference = select(&b.batches.metas, &g.meshes, &g.billboard, camera, params);
    // 1. The reference's selection: refine.wgsl alone.
    let mut buffers = SelectBuffers::from_cpu(
        ctx,
        &reference.commands,
        &reference.data,
        &reference.counters,
    )
    .map_err(e)?;
    b.refine.dispatch(&mut buffers, camera, params).map_err(e)?;
    let got = b.refine.read(&buffers).map_err(e)?;
    judge(
        &format!("{name}/cpu-selection"),
        b,
        &reference,
        &got,
        camera,
        params,
        true,
        tally,
    )?;
    // 2. select.wgsl's own output, refined in its buffers.
    for compaction in Compaction::ALL {
        let s = b.select.run(camera, params, compaction).map_err(e)?;
        let input = Selection {
            commands: s.commands,
            data: s.data,
            counters: s.counters,
        };
        let same = input == reference;
        if compaction == Compaction::Stable && !same {
            tally.selection_differs += 1;
        }
        b.refine
            .dispatch(b.select.buffers_mut(), camera, params)
            .map_err(e)?;
        let got = b.refine.read(b.select.buffers()).map_err(e)?;
        judge(
            &format!("{name}/gpu-{}", compaction.name()),
            b,
            &input,
            &got,
            camera,
            params,
            same,
            tally,
        )?;
    }
    Ok(())
}

/// Random cameras around a scene's footprint (as `parity::baselines`) with random per-frame
/// parameters, a refinement mode and one of the prepared grid sizes.
fn cases_around(bounds: [f32; 4], grids: usize) -> impl Strategy<Value = (Camera, Params, usize)> {
    let m = half_side(bounds);
    let p = (
        params_around(bounds, 0.0..(2.0 * m), 0.0..(0.5 * m)),
        1u32..=2,
    )
        .prop_map(|(p, mode)| Params {
            tree_cull: mode,
            ..p
        });
    (cameras_around(bounds), p, 0..grids)
}

#[test]
fn gpu_refine_matches_the_reference() {
    let Some(ctx) = gpu_context() else { return };
    let started = Instant::now();
    let mut failures = Vec::new();
    let mut tally = Tally::default();
    let tiny = builtin::tiny();
    let crop = cropped_synthetic(300.0);
    // Grid sizes down to one batch of every tree (tiny: 1.5k trees, 24 chunks; crop: 13k trees,
    // 200+ chunks per command).
    for (scene, p, size, grids) in [
        (&tiny, tiny_params(FadeMode::Alpha), 96, [50.0, 20.0, 400.0]),
        (
            &crop,
            crop_params(FadeMode::Alpha),
            160,
            [100.0, 300.0, 1000.0],
        ),
    ] {
        let input = CullInput::new(scene);
        let mut batched: Vec<Batched> = grids
            .iter()
            .map(|&g| {
                Batched::new(ctx, scene, &input.geometry, &input.spheres, &input.trees, g)
                    .expect("batches")
            })
            .collect();
        for (b, grid) in batched.iter_mut().zip(grids) {
            for v in named_views(scene, &p, size) {
                for mode in MODES {
                    let params = Params {
                        grid_size: grid,
                        tree_cull: mode as u32,
                        ..v.params
                    };
                    let case = format!(
                        "{}-g{grid}-{}-yaw{}-dd{}-{}",
                        scene.name,
                        v.camera_name,
                        v.yaw,
                        v.params.draw_distance,
                        mode.name()
                    );
                    if let Err(e) = check_frame(ctx, &case, b, &v.camera, &params, &mut tally) {
                        failures.push(e);
                    }
                }
            }
        }
        // Random cameras and parameters around the scene.
        run_cases(
            &format!("{} random cameras", scene.name),
            CASES,
            cases_around(scene.bounds, grids.len()),
            |(camera, params, g)| {
                let params = Params {
                    grid_size: grids[g],
                    ..params
                };
                check_frame(
                    ctx,
                    &format!("{} random", scene.name),
                    &mut batched[g],
                    &camera,
                    &params,
                    &mut tally,
                )
            },
        );
    }
    // Random scenes of card trees, random cameras and parameters (`parity::select`'s generators).
    run_cases(
        "random scenes",
        CASES,
        (instances(300), cameras(), params(), 1u32..=2),
        |(trees, camera, params, mode)| {
            let params = Params {
                tree_cull: mode,
                ..params
            };
            let scene = scene_of(trees);
            let i = CullInput::new(&scene);
            let mut b = Batched::new(
                ctx,
                &scene,
                &i.geometry,
                &i.spheres,
                &i.trees,
                params.grid_size,
            )?;
            check_frame(ctx, "random scene", &mut b, &camera, &params, &mut tally)
        },
    );
    println!(
        "refine parity: {tally} in {:.2} s",
        started.elapsed().as_secs_f64()
    );
    assert!(
        tally.cases >= 3 * (2 * 3 * 36 + 3 * 64),
        "too few cases ran: {}",
        tally.cases
    );
    assert!(
        tally.trees_kept < tally.trees_tested && tally.trees_kept > 0,
        "refinement kept {} of {} trees: the scenarios test nothing",
        tally.trees_kept,
        tally.trees_tested
    );
    failures.extend(decision_budget_failure(
        "refine near-threshold trees",
        tally.ambiguous_trees,
        tally.trees_tested,
    ));
    assert_no_failures(
        &format!("refine parity failed ({} frames)", failures.len()),
        &failures,
    );
}

/// With `tree_cull` `none` every caller skips the stage; run anyway, it points every command at
/// the copy of the batch indirection, so the same trees are drawn. Bad inputs are refused.
#[test]
fn tree_cull_none_points_every_command_at_the_copy() {
    let Some(ctx) = gpu_context() else { return };
    let tiny = builtin::tiny();
    let p = tiny_params(FadeMode::Alpha);
    let i = CullInput::new(&tiny);
    let mut b = Batched::new(ctx, &tiny, &i.geometry, &i.spheres, &i.trees, p.grid_size).unwrap();
    let camera = named_camera("medium", &tiny, 0.0, 96, 96).unwrap();
    let s = b.select.run(&camera, &p, Compaction::Stable).unwrap();
    assert!(!s.commands.is_empty());
    b.refine
        .dispatch(b.select.buffers_mut(), &camera, &p)
        .unwrap();
    let got = b.refine.read(b.select.buffers()).unwrap();
    let n = b.batches.indirection.len() as u32;
    for (c, o) in got.selection.commands.iter().zip(&s.commands) {
        assert_eq!(c.first_instance, 2 * n + o.first_instance);
        assert_eq!(c.instance_count, o.instance_count);
    }
    assert_eq!(got.counters, RefineCounters::default());
    // Refusals are named.
    let err = GpuRefine::new(ctx, &i.trees[..1], &b.batches.indirection)
        .err()
        .unwrap();
    assert!(err.to_string().contains("batch indirection"), "{err}");
}

/// The image comparisons' frames: the shared `tiny` and cropped `synthetic` frames, with the
/// draw distance pulled in to 150 m and the transition to 120 m.
fn image_scenarios() -> (Vec<Prepared>, Vec<FrameScenario>) {
    let p = tiny_params(FadeMode::Alpha);
    tiny_and_crop_frames(&[
        (
            "draw-distance-150",
            Params {
                draw_distance: 150.0,
                ..p
            },
        ),
        (
            "transition-120",
            Params {
                lod1_transition: 120.0,
                fade_width: 40.0,
                ..p
            },
        ),
    ])
}

#[test]
fn gpu_refined_images_match_the_reference() {
    let Some(ctx) = gpu_context() else { return };
    let started = Instant::now();
    let (prepared, scenarios) = image_scenarios();
    let mut sweeps: Vec<GpuScene> = prepared
        .iter()
        .zip([tiny_params(FadeMode::Alpha), crop_params(FadeMode::Alpha)])
        .map(|(p, params)| {
            GpuScene::new(ctx, p, &params, StagesFromCpu::NONE).expect("GpuScene::new")
        })
        .collect();
    let draw = gpu_draw(ctx);
    let paths = [
        "sweep ours-stable",
        "sweep ours-atomic (dithered fade)",
        "render_gpu (GPU select + refine)",
        "render_gpu (CPU select + refine)",
    ];
    let mut max: Vec<MaxDiffs> = vec![(0, 0, 0.0); paths.len()];
    let mut failures = Vec::new();
    let (mut frames, mut tested, mut kept) = (0, 0u64, 0u64);
    for s in &scenarios {
        let p = &prepared[s.prepared_key];
        for mode in MODES {
            let params = Params {
                tree_cull: mode as u32,
                ..s.params
            };
            let name = format!("{}-{}", s.name, mode.name());
            let frame = p.render(&s.camera, &params).expect("reference frame");
            let r = frame.refined.as_ref().expect("the reference refined");
            tested += r.trees_tested;
            kept += r.trees_kept;
            let want = images_of(&frame.drawn.target);
            let alternatives = alpha_test_alternatives(p, &s.camera, &params);
            let commands = frame.selection.commands.len() as u64;
            let sweep = &mut sweeps[s.prepared_key];
            let mut judge = |k: usize, got: &Images, against: Option<&(Images, _)>| {
                let (want, alternatives) = against.map_or((&want, &alternatives), |(w, a)| (w, a));
                if let Some(f) = judge_image(
                    &format!("{name}/{}", paths[k]),
                    got,
                    want,
                    alternatives,
                    &s.camera,
                    &mut max[k],
                ) {
                    failures.push(f);
                }
                frames += 1;
            };
            for (k, compaction) in Compaction::ALL.into_iter().enumerate() {
                // Atomic compaction draws the commands in whatever order the GPU's threads
                // reach the counter, and alpha fades blend in draw order: against the
                // reference's stable order its colour then differs wherever fading trees
                // overlap, by as much as that run's order makes it (CI, session 10: 800 window
                // pixels of 25,600 where three local runs gave 400-517, over the class budget
                // of 772). So this path is judged with a dithered fade, which draws the same
                // image in any order (a fragment is kept or discarded, never blended), against
                // the reference at the same parameters; the alpha fade's blending is judged on
                // the stable paths.
                let order_free = Params {
                    fade_mode: FadeMode::DitherSequential as u32,
                    ..params
                };
                let (params, reference) = match compaction {
                    Compaction::Stable => (params, None),
                    Compaction::Atomic => {
                        let frame = p.render(&s.camera, &order_free).expect("reference frame");
                        let want = images_of(&frame.drawn.target);
                        let alternatives = alpha_test_alternatives(p, &s.camera, &order_free);
                        (order_free, Some((want, alternatives)))
                    }
                };
                let got = sweep
                    .render(p, GpuPipeline::Ours(compaction), &s.camera, &params)
                    .expect("sweep frame");
                assert_eq!(got.commands, commands, "{name}: commands");
                let chain = sweep.chain().expect("a frame of ours ran the GPU chain");
                let refined = sweep
                    .refine()
                    .expect("the plan refines on the GPU")
                    .read(chain.buffers())
                    .expect("read refine");
                assert_eq!(
                    refined.counters.trees_tested as u64, r.trees_tested,
                    "{name}/{}: trees tested",
                    paths[k]
                );
                judge(k, &got.images, reference.as_ref());
            }
            for (k, select_from_cpu) in [(2, false), (3, true)] {
                let from_cpu = if select_from_cpu {
                    StagesFromCpu::ALL
                } else {
                    StagesFromCpu::TEXTURES
                };
                let got = render_gpu(ctx, draw, p, &s.camera, &params, from_cpu)
                    .expect("render_gpu frame");
                judge(k, &got.images, None);
            }
        }
    }
    println!(
        "refined images: {} scenarios x {} modes, {frames} GPU frames in {:.1} s; the reference \
         refines kept {kept} of {tested} trees tested",
        scenarios.len(),
        MODES.len(),
        started.elapsed().as_secs_f64()
    );
    for (path, m) in paths.iter().zip(&max) {
        print_max_diffs(path, m);
    }
    assert!(kept < tested, "refinement dropped no tree in any scenario");
    assert_no_failures("refined image parity failed", &failures);
}
