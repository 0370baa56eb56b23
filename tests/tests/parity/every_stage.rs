//! Every stage of the stage table (`forestlod_harness::stages::STAGES`, issue 27) run alone on the
//! GPU on the reference's input of it (`forestlod_harness::gpu_stages::FrameStages::check`: the
//! reference backend and the GPU backend through `&dyn Backend<S>`) and judged by the stage's
//! harness judge (`forestlod_harness::stage::Judged`, tolerances in `forestlod_harness::judge`),
//! on a few small frames of `tiny`: the grid with `tree_cull = lod0`, the octree with coalescing
//! on, `front-to-back` and `tree_cull = all`, the quadtree with coalescing off and `node` order;
//! two cameras each. Every row must run at least once and pass; the largest difference per stage
//! is printed. The stage-specific parity files judge each stage in depth on random cases.
//!
//! And **the walk** (issue 36, coverage by construction): every case of
//! `forestlod_tests::stage_cases` (every choice of every mode a stage's row names, every numeric
//! parameter it names at its least and greatest accepted value) runs the stages it targets alone
//! on the GPU against the reference; a target whose stage does not run (other than a choice that
//! turns the stage off, where the plan must skip it) or differs fails the test, which prints the
//! reached targets per stage and the largest difference.
//!
//! And the diagnosis (`forestlod_harness::diagnose::check_stages`) walks the frame's plan: on a
//! cut with `refine`, its checks are the textures, then `hier_select`, `coalesce`,
//! `command_order`, `refine` in that order, then the chained selection, and none differs.

use std::collections::BTreeMap;
use std::time::Instant;

use forestlod_harness::context::gpu_context;
use forestlod_harness::diagnose::{check_stages, first_differing};
use forestlod_harness::gpu_stages::FrameStages;
use forestlod_harness::stages::STAGES;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::builtin;
use forestlod_shared::{Coalesce, CommandOrder, Hierarchy, Params, StageId, TreeCull};
use forestlod_tests::stage_cases::{judged_elsewhere, skips, stage_cases};
use forestlod_tests::{small_poses, tiny_hierarchy_params};

/// The frames' parameters (module docs): one flat selection and two cuts covering both coalesce
/// modes, both command orders and both refining tree-cull modes, and a flat selection with
/// occlusion culling.
fn frame_params() -> Vec<(&'static str, Params)> {
    let cut = |mode, coalesce: Coalesce, order: CommandOrder, cull: TreeCull| Params {
        coalesce: coalesce as u32,
        command_order: order as u32,
        tree_cull: cull as u32,
        ..tiny_hierarchy_params(mode)
    };
    vec![
        (
            "grid-lod0",
            cut(
                Hierarchy::Grid,
                Coalesce::Off,
                CommandOrder::Node,
                TreeCull::Lod0,
            ),
        ),
        (
            "octree-coalesce-on-front-to-back-all",
            cut(
                Hierarchy::Octree,
                Coalesce::On,
                CommandOrder::FrontToBack,
                TreeCull::All,
            ),
        ),
        (
            "quadtree-coalesce-off-node",
            cut(
                Hierarchy::Quadtree,
                Coalesce::Off,
                CommandOrder::Node,
                TreeCull::None,
            ),
        ),
        // The far level's bake (issue 32) runs only under `lod_levels = 3` (which refuses
        // per-tree refinement: far commands index cells).
        (
            "octree-far",
            Params {
                lod_levels: 3,
                ..cut(
                    Hierarchy::Octree,
                    Coalesce::On,
                    CommandOrder::FrontToBack,
                    TreeCull::None,
                )
            },
        ),
        // Occlusion culling's stages (issue 31): `pyramid` and `occlude` run only with it on.
        (
            "grid-none-occlusion-single",
            Params {
                occlusion: forestlod_shared::Occlusion::Single as u32,
                ..cut(
                    Hierarchy::Grid,
                    Coalesce::Off,
                    CommandOrder::Node,
                    TreeCull::None,
                )
            },
        ),
    ]
}

#[test]
fn every_stage_alone_on_the_gpu_matches_the_reference() {
    let Some(ctx) = gpu_context() else {
        eprintln!("every_stage: no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    let started = Instant::now();
    let scene = builtin::by_name("tiny").unwrap();
    // Per stage: checks run, the largest difference seen.
    let mut seen: BTreeMap<StageId, (u32, f64)> = BTreeMap::new();
    let mut failures = Vec::new();
    for (k, (name, params)) in frame_params().into_iter().enumerate() {
        let prepared = prepare(scene.clone(), &params).unwrap();
        for (j, (camera_name, yaw, camera)) in
            small_poses(&prepared.scene, &[("medium", 0.0), ("close", 30.0)])
                .into_iter()
                .enumerate()
        {
            let frame = FrameStages::new(&prepared, &camera, &params);
            for e in STAGES {
                // The texture stages read no camera: once. The frames' stages: one camera each.
                let once = matches!(e.id, StageId::Bake | StageId::Mips);
                // The far frame is there for `far_bake` (a texture stage: one camera); its
                // other stages are the octree frame's.
                if name == "octree-far" && (e.id != StageId::FarBake || j != 0) {
                    continue;
                }
                let per_scene = matches!(e.id, StageId::Draw | StageId::Primitive);
                if (once && (k, j) != (0, 0)) || (per_scene && j != 0) {
                    continue;
                }
                let Some(check) = frame.check(ctx, e.id) else {
                    continue;
                };
                eprintln!(
                    "{name} {camera_name} yaw {yaw}: {}: {} ({})",
                    check.stage,
                    if check.differs { "DIFFERS" } else { "ok" },
                    check.summary
                );
                if check.differs {
                    failures.push(format!(
                        "{name} {camera_name} yaw {yaw}: {}: {}",
                        check.stage, check.summary
                    ));
                }
                let s = seen.entry(e.id).or_default();
                s.0 += 1;
                s.1 = s.1.max(check.max_difference);
            }
        }
    }
    for (id, (n, max)) in &seen {
        eprintln!(
            "every_stage: {}: {n} checks, max difference {max}",
            id.name()
        );
    }
    eprintln!(
        "every_stage: {} stages in {:.1} s",
        seen.len(),
        started.elapsed().as_secs_f64()
    );
    let missing: Vec<&str> = STAGES
        .iter()
        .filter(|e| !seen.contains_key(&e.id))
        .map(|e| e.id.name())
        .collect();
    assert!(missing.is_empty(), "stages never checked: {missing:?}");
    assert!(
        failures.is_empty(),
        "stages differ:\n{}",
        failures.join("\n")
    );
}

#[test]
fn the_diagnosis_walks_the_plan() {
    let Some(ctx) = gpu_context() else {
        eprintln!("every_stage diagnosis: no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    let (_, params) = frame_params().remove(1);
    let scene = builtin::by_name("tiny").unwrap();
    let prepared = prepare(scene, &params).unwrap();
    let (_, _, camera) = small_poses(&prepared.scene, &[("medium", 0.0)]).remove(0);
    let checks = check_stages(ctx, &prepared, &camera, &params, false, false);
    let names: Vec<&str> = checks.iter().map(|c| c.stage).collect();
    eprintln!("diagnosis checks: {names:?}");
    for c in &checks {
        eprintln!(
            "  {}: {} (max difference {})",
            c.stage, c.summary, c.max_difference
        );
    }
    let selection: Vec<&str> = [
        StageId::HierSelect,
        StageId::Coalesce,
        StageId::CommandOrder,
        StageId::Refine,
    ]
    .map(StageId::name)
    .to_vec();
    assert_eq!(
        names[2..6],
        selection[..],
        "the plan's selection stages, in order"
    );
    assert_eq!(names.len(), 7, "textures (2), four stages, the chain");
    if let Some(f) = first_differing(&checks) {
        panic!("{f}");
    }
}

/// The walk of one stage (module docs): every case of `forestlod_tests::stage_cases` with a
/// target of `stage`, that stage alone on the GPU against the reference.
fn walk(stage: StageId) {
    let Some(ctx) = gpu_context() else {
        eprintln!("every_stage walk: no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    let started = Instant::now();
    let cases: Vec<_> = stage_cases()
        .into_iter()
        .filter(|c| c.targets.iter().any(|t| t.stage == stage))
        .collect();
    let mut failures = Vec::new();
    let (mut reached, mut max, mut targets) = (Vec::new(), 0.0f64, 0);
    for case in &cases {
        let case_started = Instant::now();
        let scene = forestlod_tests::stage_cases::scene(case.scene);
        let prepared = match prepare(scene, &case.params) {
            Ok(p) => p,
            Err(e) => {
                failures.push(format!("{}: prepare failed: {e}", case.name));
                continue;
            }
        };
        let (_, _, camera) = small_poses(&prepared.scene, &[("medium", 0.0)]).remove(0);
        let prepared_s = case_started.elapsed().as_secs_f64();
        let frame = FrameStages::new(&prepared, &camera, &case.params);
        let check = frame.check(ctx, stage);
        eprintln!(
            "walk: {}: {}: prepare {prepared_s:.1} s, case {:.1} s",
            stage.name(),
            case.name,
            case_started.elapsed().as_secs_f64()
        );
        for t in case.targets.iter().filter(|t| t.stage == stage) {
            targets += 1;
            let what = format!("{}: {} {} = {}", stage.name(), t.reach, t.param, t.value);
            let skipped = skips(stage, t.param, &t.value);
            match (&check, skipped) {
                (None, true) => reached.push(format!("{}={} (skips the stage)", t.param, t.value)),
                (Some(_), true) => failures.push(format!(
                    "{}: {what}: the stage ran, but this choice must turn it off",
                    case.name
                )),
                (None, false) => failures.push(format!(
                    "{}: {what}: the stage did not run (not reached)",
                    case.name
                )),
                (Some(c), false) => {
                    if let Some(test) = judged_elsewhere(t) {
                        // Judged in depth by `test`, which must exist.
                        let (module, name) = test.split_once("::").expect("module::test");
                        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                            .join(format!("tests/parity/{module}.rs"));
                        let src = std::fs::read_to_string(&file).unwrap_or_default();
                        if !src.contains(&format!("fn {name}()")) {
                            failures
                                .push(format!("{what}: judged by {test}, which does not exist"));
                        }
                        eprintln!("walk: {what}: judged by {test} ({})", c.summary);
                        reached.push(format!("{}={} (judged by {test})", t.param, t.value));
                        continue;
                    }
                    if c.differs {
                        failures.push(format!("{}: {what}: {}", case.name, c.summary));
                    }
                    reached.push(format!("{}={}", t.param, t.value));
                    max = max.max(c.max_difference);
                }
            }
        }
    }
    eprintln!(
        "walk: {}: {} cases, {targets} targets, max difference {max}, {:.1} s: {}",
        stage.name(),
        cases.len(),
        started.elapsed().as_secs_f64(),
        reached.join(", ")
    );
    let entry = STAGES.iter().find(|e| e.id == stage).expect("a row");
    assert!(
        targets > 0 || (entry.modes.is_empty() && entry.params.is_empty()),
        "the walk reached no target of {}",
        stage.name()
    );
    assert!(
        failures.is_empty(),
        "the walk failed:\n{}",
        failures.join("\n")
    );
}

/// One walk test per stage (they run in parallel; a failure names its stage), and the list of
/// stages they cover, which must be every [`StageId`].
macro_rules! walks {
    ($($test:ident => $stage:ident),+ $(,)?) => {
        $(
            #[test]
            fn $test() {
                walk(StageId::$stage);
            }
        )+
        const WALKED: &[StageId] = &[$(StageId::$stage),+];
    };
}

walks! {
    walk_bake => Bake,
    walk_mips => Mips,
    walk_far_bake => FarBake,
    walk_select => Select,
    walk_hier_select => HierSelect,
    walk_coalesce => Coalesce,
    walk_command_order => CommandOrder,
    walk_refine => Refine,
    walk_pyramid => Pyramid,
    walk_occlude => Occlude,
    walk_draw => Draw,
    walk_cull => Cull,
    walk_primitive => Primitive,
}

/// The walk covers every stage of the table: a stage added to [`StageId`] needs its `walks!`
/// line.
#[test]
fn the_walk_covers_every_stage() {
    assert_eq!(
        WALKED,
        &StageId::ALL[..],
        "one walk test per stage, in StageId::ALL order"
    );
}
