//! Every published counter checked against a recount (issue 36, class 6). The sweeps' CSV columns
//! (`experiments/src/sweep/rows.rs`: `batches_tested`, `commands`, `trees_drawn`, `trees_finer`,
//! `trees_coarser`, `trees_outside_view`, `trees_missing_lod`) and the render job's metrics.json
//! keys (`experiments/src/render.rs`: `selection.{batches_tested, culled_distance,
//! culled_frustum, commands, lod0_commands, lod1_commands, transition_batches, instances}`,
//! `refine.{trees_tested, trees_kept}`, `draw.trees_discarded_by_draw_distance`) are built from
//! the selection's counters. Each is recomputed here independently of the code that counts it:
//! - from the **emitted commands**: `commands`, `lod0_commands`, `lod1_commands` (per LOD),
//!   `instances` (their instance counts), `transition_batches` (batches or nodes, by
//!   `CommandData::batch`, with a command at each LOD, counted on the uncoalesced list);
//! - from the **decisions**: `batches_tested`, `culled_distance`, `culled_frustum` of the grid from
//!   `batch_decisions`; of a hierarchy from its per-node codes by a plain **recursion** from the
//!   roots (C§5 "nodes walked": a node is visited when its parent was visited and recursed), not
//!   by the cut's ancestor walk (`HierSelection::nodes_visited`);
//! - from the **per-tree oracle** (`select_per_tree`): the batching counts (`trees_finer`, ...) as
//!   set differences of (tree, LOD) pairs, and `trees_drawn` as the trees of the commanded pairs;
//! - `refine`'s `trees_tested` (instances of the commands its mode refines, before) and
//!   `trees_kept` (after), and the draw's `trees_discarded` (command instances whose tree lies
//!   beyond the draw distance).
//!
//! Backends: every counter on the **reference** (random cases with a fixed seed, grid and every
//! hierarchy, coalescing on and off, every `tree_cull` mode; and `tiny` at its named views
//! through the whole frame, `Prepared::render`, as the render job and the sweep read it). On the
//! **GPU**, the counters it reports: `select.wgsl`'s eight (both compactions), the cut's eight
//! before and after coalescing (against a recount from the GPU's own per-node codes and
//! commands), `refine.wgsl`'s two, and the baselines' `commands` and `trees_drawn`
//! (`GpuScene::render`, what the sweep's GPU rows copy). The batching counts, `trees_drawn` of
//! ours and `trees_discarded` exist only on the reference (the sweep's GPU rows take them from
//! the reference's selection of the same frame, `experiments/src/sweep/runner.rs`).

use std::collections::{BTreeMap, BTreeSet};

use forestlod_gpu::{Compaction, GpuRefine, GpuSelect};
use forestlod_harness::bridge::cull_trees_of;
use forestlod_harness::context::gpu_context;
use forestlod_harness::gpu_frame::{GpuPipeline, GpuScene, SelectionChain, StagesFromCpu};
use forestlod_reference::baselines::trees_drawn_by_selection;
use forestlod_reference::draw::{LOD_ID_BILLBOARD, LOD_ID_MESH, LOD_ID_TRANSITION};
use forestlod_reference::hierarchy::Hierarchy;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::refine::refine;
use forestlod_reference::scene::builtin;
use forestlod_reference::select::{
    BatchingCounts, SelectUniform, Selection, batch_decisions, batching_counts, select,
    select_per_tree, tree_within_draw_distance,
};
use forestlod_shared::{
    Camera, Coalesce, DECISION_DRAW, DECISION_KIND_MASK, Decision, FadeMode, Hierarchy as Mode,
    LOD_BILLBOARD, LOD_MESH, NO_PARENT, NODE_RECURSE, Params, SelectCounters, TreeCull,
};
use forestlod_tests::scenarios::{named_views, tiny_params};
use forestlod_tests::{Packed, cameras, full_cut, instances, params};
use proptest::test_runner::{Config, TestCaseError, TestRunner};

/// Every hierarchical mode.
const MODES: [Mode; 5] = [
    Mode::GridAabb,
    Mode::Quadtree,
    Mode::Octree,
    Mode::OctreeEuclidean,
    Mode::Kmeans,
];

/// The per-tree culling modes.
const TREE_CULLS: [TreeCull; 3] = [TreeCull::None, TreeCull::Lod0, TreeCull::All];

/// The command-derived counters of `s`: `commands`, `lod0_commands`, `lod1_commands`,
/// `instances`, and `transition_batches` as the batches (`CommandData::batch`) with a command at
/// each LOD (meaningful on a list before coalescing). The decision counters are left 0.
fn from_commands(s: &Selection) -> SelectCounters {
    let mut lods: BTreeMap<u32, BTreeSet<u32>> = BTreeMap::new();
    for d in &s.data {
        lods.entry(d.batch).or_default().insert(d.lod);
    }
    SelectCounters {
        commands: s.commands.len() as u32,
        lod0_commands: s.data.iter().filter(|d| d.lod == LOD_MESH).count() as u32,
        lod1_commands: s.data.iter().filter(|d| d.lod == LOD_BILLBOARD).count() as u32,
        instances: s.commands.iter().map(|c| c.instance_count).sum(),
        transition_batches: lods.values().filter(|l| l.len() == 2).count() as u32,
        ..SelectCounters::default()
    }
}

/// The grid selection's counters recounted: the command counters of `s` and the decision
/// counters of `decisions`.
fn grid_recount(decisions: &[Decision], s: &Selection) -> SelectCounters {
    SelectCounters {
        batches_tested: decisions.len() as u32,
        culled_distance: decisions
            .iter()
            .filter(|d| **d == Decision::CulledDistance)
            .count() as u32,
        culled_frustum: decisions
            .iter()
            .filter(|d| **d == Decision::CulledFrustum)
            .count() as u32,
        ..from_commands(s)
    }
}

/// The nodes of `h` a recursion from the roots visits under `codes`: a node is visited when it is
/// a root or its parent was visited, drawn and recursed.
fn visited_by_recursion(h: &Hierarchy, codes: &[u32]) -> Vec<usize> {
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); h.nodes.len()];
    let mut stack = Vec::new();
    for (i, n) in h.nodes.iter().enumerate() {
        if n.parent == NO_PARENT {
            stack.push(i);
        } else {
            children[n.parent as usize].push(i);
        }
    }
    let mut visited = Vec::new();
    while let Some(i) = stack.pop() {
        visited.push(i);
        let c = codes[i];
        if c & DECISION_KIND_MASK == DECISION_DRAW && c & NODE_RECURSE != 0 {
            stack.extend(&children[i]);
        }
    }
    visited
}

/// The cut's counters recounted from its per-node `codes` (by recursion) and its uncoalesced
/// commands `raw`; with `merged`, the command counts are the merged list's (coalescing keeps the
/// others).
fn cut_recount(
    h: &Hierarchy,
    codes: &[u32],
    raw: &Selection,
    merged: Option<&Selection>,
) -> SelectCounters {
    let visited = visited_by_recursion(h, codes);
    let kind = |i: &usize| Decision::from_code(codes[*i] & !NODE_RECURSE);
    let raw_counts = from_commands(raw);
    let merged_counts = merged.map_or(raw_counts, from_commands);
    SelectCounters {
        batches_tested: visited.len() as u32,
        culled_distance: visited
            .iter()
            .filter(|i| kind(i) == Decision::CulledDistance)
            .count() as u32,
        culled_frustum: visited
            .iter()
            .filter(|i| kind(i) == Decision::CulledFrustum)
            .count() as u32,
        transition_batches: raw_counts.transition_batches,
        instances: raw_counts.instances,
        ..merged_counts
    }
}

/// The commanded (tree, LOD) pairs of `s` (trees past the draw stage's per-tree draw distance
/// dropped, as the draw stage does).
fn commanded_pairs(
    spheres: &[([f32; 3], f32)],
    indirection: &[u32],
    s: &Selection,
    u: &SelectUniform,
) -> BTreeSet<(u32, u32)> {
    let mut out = BTreeSet::new();
    for (c, d) in s.commands.iter().zip(&s.data) {
        let range = c.first_instance as usize..(c.first_instance + c.instance_count) as usize;
        for &t in &indirection[range] {
            if tree_within_draw_distance(u, spheres[t as usize].0) {
                out.insert((t, d.lod));
            }
        }
    }
    out
}

/// [`BatchingCounts`] and `trees_drawn` recounted as set differences of (tree, LOD) pairs against
/// the per-tree oracle.
fn batching_recount(
    spheres: &[([f32; 3], f32)],
    indirection: &[u32],
    s: &Selection,
    camera: &Camera,
    params: &Params,
) -> (BatchingCounts, u64) {
    let u = SelectUniform::new(camera, params);
    let got = commanded_pairs(spheres, indirection, s, &u);
    let oracle = select_per_tree(spheres, camera, params);
    let mut want = BTreeSet::new();
    let mut drawn_by_oracle = BTreeSet::new();
    for (t, d) in oracle.iter().enumerate() {
        let t = t as u32;
        if let Decision::Draw(n) = d {
            drawn_by_oracle.insert(t);
            if n.lod0 {
                want.insert((t, LOD_MESH));
            }
            if n.lod1 {
                want.insert((t, LOD_BILLBOARD));
            }
        }
    }
    let trees = |pairs: &BTreeSet<(u32, u32)>| pairs.iter().map(|p| p.0).collect::<BTreeSet<_>>();
    let (commanded, needed) = (trees(&got), trees(&want));
    let extra: BTreeSet<(u32, u32)> = got.difference(&want).copied().collect();
    let at = |lod: u32| {
        extra
            .iter()
            .filter(|&&(t, l)| l == lod && drawn_by_oracle.contains(&t))
            .count() as u64
    };
    let counts = BatchingCounts {
        trees_needed: needed.len() as u64,
        trees_commanded: commanded.len() as u64,
        trees_finer: at(LOD_MESH),
        trees_coarser: at(LOD_BILLBOARD),
        trees_outside_view: commanded.difference(&drawn_by_oracle).count() as u64,
        trees_missing_lod: trees(&want.difference(&got).copied().collect()).len() as u64,
    };
    (counts, commanded.len() as u64)
}

/// `refine`'s `(trees_tested, trees_kept)` recounted: the instances of the commands its mode
/// refines, before (`input`) and after (`output`).
fn refine_recount(mode: TreeCull, input: &Selection, output: &Selection) -> (u64, u64) {
    let sum = |s: &Selection| -> u64 {
        s.commands
            .iter()
            .zip(&s.data)
            .filter(|(_, d)| mode.refines(d.lod))
            .map(|(c, _)| u64::from(c.instance_count))
            .sum()
    };
    (sum(input), sum(output))
}

/// A random case's parameters: `p` with a grid of at most 400 m (so batches hold few trees) and
/// the given tree culling.
fn case_params(p: Params, tree_cull: TreeCull) -> Params {
    Params {
        grid_size: p.grid_size.min(400.0),
        tree_cull: tree_cull as u32,
        ..p
    }
}

/// Cases of the random tests (each: the grid and one hierarchy, both coalescing modes).
const CASES: u32 = 64;

/// The reference's counters on random cases equal their recount: the grid's selection, one
/// hierarchy's cut (coalesced and not), the batching counts and `trees_drawn` of the grid and the
/// cut, and `refine`'s counters under a random `tree_cull`.
#[test]
fn reference_counters_equal_their_recount() {
    let mut runner = TestRunner::new(Config {
        cases: CASES,
        failure_persistence: None,
        ..Config::default()
    });
    let checked = std::cell::RefCell::new([0u64; 4]);
    let strategy = (
        instances(300),
        cameras(),
        params(),
        0usize..MODES.len(),
        0usize..3,
        2u32..16,
    );
    let result = runner.run(&strategy, |(trees, camera, p, mode_i, cull_i, npn)| {
        let mut checked = checked.borrow_mut();
        let p = Params {
            nodes_per_node: npn,
            ..case_params(p, TREE_CULLS[cull_i])
        };
        let packed = Packed::new(trees, p.grid_size);
        let (g, b) = (&packed.geometry, &packed.batches);
        // The grid.
        let s = select(&b.metas, &b.scales, &g.meshes, &g.billboard, &camera, &p);
        let want = grid_recount(&batch_decisions(&b.metas, &camera, &p), &s);
        prop_assert_eq_counters(&s.counters, &want, "grid select")?;
        check_batching(&packed.spheres, &b.indirection, &s, &camera, &p, "grid")?;
        let mut refined = s.clone();
        let r = refine(
            &mut refined,
            &b.indirection,
            &packed.spheres,
            &packed.scales(),
            &camera,
            &p,
        );
        let mode = TREE_CULLS[cull_i];
        let want = if mode == TreeCull::None {
            (0, 0)
        } else {
            refine_recount(mode, &s, &refined)
        };
        if (r.trees_tested, r.trees_kept) != want {
            return Err(TestCaseError::fail(format!(
                "refine ({mode:?}): tested {} kept {}, recount {want:?}",
                r.trees_tested, r.trees_kept
            )));
        }
        if mode != TreeCull::None {
            check_batching(
                &packed.spheres,
                &r.indirection,
                &refined,
                &camera,
                &p,
                "refined",
            )?;
        }
        checked[0] += 1;
        // One hierarchy, both coalescing modes.
        let mode = MODES[mode_i];
        for coalesce in [Coalesce::Off, Coalesce::On] {
            let p = Params {
                hierarchy: mode as u32,
                coalesce: coalesce as u32,
                ..p
            };
            let h = Hierarchy::build(&packed.scene, &g.meshes, &p)
                .unwrap()
                .unwrap();
            let (selection, trace) =
                forestlod_reference::frame::cut(&h, &g.meshes, &g.billboard, None, &camera, &p);
            let cut = &trace.cut;
            let want = cut_recount(&h, &cut.codes, &cut.selection, None);
            prop_assert_eq_counters(&cut.selection.counters, &want, &format!("{mode:?} raw cut"))?;
            if cut.nodes_visited() != want.batches_tested {
                return Err(TestCaseError::fail(format!(
                    "{mode:?}: nodes_visited {} but the recursion visits {}",
                    cut.nodes_visited(),
                    want.batches_tested
                )));
            }
            let want = cut_recount(&h, &cut.codes, &cut.selection, Some(&selection));
            prop_assert_eq_counters(
                &selection.counters,
                &want,
                &format!("{mode:?} {coalesce:?} cut"),
            )?;
            let full = full_cut(&h, &g.meshes, &g.billboard, &camera, &p);
            assert_eq!(full.nodes_visited(), want.batches_tested);
            check_batching(
                &packed.spheres,
                &h.indirection,
                &selection,
                &camera,
                &p,
                &format!("{mode:?}"),
            )?;
            checked[1] += 1;
            checked[2] += u64::from(want.transition_batches);
            checked[3] += u64::from(want.batches_tested);
        }
        Ok(())
    });
    let checked = checked.into_inner();
    eprintln!(
        "counters (reference): {} grid cases, {} cuts, {} transition nodes, {} nodes visited",
        checked[0], checked[1], checked[2], checked[3]
    );
    if let Err(e) = result {
        panic!("counters (reference): {e}");
    }
    assert!(
        checked[2] > 0 && checked[3] > checked[1],
        "the cases reach no transition node or no recursion: {checked:?}"
    );
}

/// Fails naming `what` and every field that differs.
fn prop_assert_eq_counters(
    got: &SelectCounters,
    want: &SelectCounters,
    what: &str,
) -> Result<(), TestCaseError> {
    if got == want {
        Ok(())
    } else {
        Err(TestCaseError::fail(format!(
            "{what}: counters {got:?}, recount {want:?}"
        )))
    }
}

/// `batching_counts` and `trees_drawn_by_selection`-style counts against [`batching_recount`].
fn check_batching(
    spheres: &[([f32; 3], f32)],
    indirection: &[u32],
    s: &Selection,
    camera: &Camera,
    params: &Params,
    what: &str,
) -> Result<(), TestCaseError> {
    let got = batching_counts(spheres, indirection, s, camera, params);
    let (want, _) = batching_recount(spheres, indirection, s, camera, params);
    if got != want {
        return Err(TestCaseError::fail(format!(
            "{what}: batching counts {got:?}, recount {want:?}"
        )));
    }
    Ok(())
}

/// `tiny` at its named views (`medium`, `close`, `far`, yaw 0, with the default draw distance and
/// with the trees' median view depth as the draw distance) through the whole frame (`Prepared::render`, what the render job's metrics.json and
/// the sweep's reference rows read), the grid and every hierarchy, `tree_cull` none, lod0 and
/// all: the selection's counters, `refine`'s, the batching counts, `trees_drawn` and the draw's
/// `trees_discarded` equal their recount.
#[test]
fn reference_frame_counters_equal_their_recount() {
    let scene = builtin::by_name("tiny").unwrap();
    let base = Params {
        nodes_per_node: 8,
        max_cull_depth: 3,
        ..tiny_params(FadeMode::DitherSequential)
    };
    let views: Vec<_> = named_views(&scene, &base, 32)
        .into_iter()
        .filter(|v| v.yaw == 0.0 && v.params.draw_distance == base.draw_distance)
        .collect();
    let mut frames = 0;
    let mut reached = [0u64; 4];
    let mut reached_draw = 0u64;
    for grouping in std::iter::once(None).chain(MODES.map(Some)) {
        let p = Params {
            hierarchy: grouping.map_or(Mode::Grid as u32, |m| m as u32),
            coalesce: Coalesce::On as u32,
            ..base
        };
        let prepared = prepare(scene.clone(), &p).unwrap();
        let spheres = forestlod_reference::baselines::tree_spheres(
            &prepared.scene,
            &prepared.geometry.meshes,
        );
        for (v, tree_cull) in views.iter().flat_map(|v| TREE_CULLS.map(|t| (v, t))) {
            // The view's draw distance, and the median view depth of the trees (so that trees
            // of one drawn batch lie on either side of it: the draw's per-tree discard).
            let mut depths: Vec<f32> = spheres
                .iter()
                .map(|(c, _)| {
                    (0..3)
                        .map(|k| (c[k] - v.camera.eye[k]) * v.camera.forward[k])
                        .sum()
                })
                .collect();
            depths.sort_by(f32::total_cmp);
            for draw_distance in [v.params.draw_distance, depths[depths.len() / 2].max(1.0)] {
                let p = Params {
                    draw_distance,
                    tree_cull: tree_cull as u32,
                    ..p
                };
                let what = format!(
                    "tiny {} draw distance {} {:?} {tree_cull:?}",
                    v.camera_name, p.draw_distance, grouping
                );
                let camera = &v.camera;
                let trace = prepared.select_stages(camera, &p, true);
                let frame = prepared.render(camera, &p).unwrap();
                // The selection before refine: its counters.
                let unrefined = trace.unrefined.as_ref().unwrap_or(&trace.selection);
                let want = match (&prepared.hierarchy, &trace.cut) {
                    (Some(h), Some(cut)) => {
                        cut_recount(h, &cut.cut.codes, &cut.cut.selection, Some(unrefined))
                    }
                    _ => grid_recount(
                        &batch_decisions(&prepared.batches.metas, camera, &p),
                        unrefined,
                    ),
                };
                assert_eq!(frame.selection.counters, want, "{what}: selection counters");
                // refine.
                if let Some(r) = &frame.refined {
                    let want = refine_recount(tree_cull, unrefined, &frame.selection);
                    assert_eq!((r.trees_tested, r.trees_kept), want, "{what}: refine");
                    reached[0] += r.trees_tested - r.trees_kept;
                } else {
                    assert_eq!(tree_cull, TreeCull::None, "{what}: refine did not run");
                }
                // The batching counts and trees drawn (the sweep's columns).
                let indirection = frame.indirection(&prepared);
                let got = batching_counts(&spheres, indirection, &frame.selection, camera, &p);
                let (want, drawn) =
                    batching_recount(&spheres, indirection, &frame.selection, camera, &p);
                assert_eq!(got, want, "{what}: batching counts");
                let trees =
                    trees_drawn_by_selection(&prepared, &frame.selection, indirection, camera, &p);
                assert_eq!(trees.len() as u64, drawn, "{what}: trees drawn");
                reached[1] += got.trees_finer + got.trees_coarser + got.trees_outside_view;
                // The draw's per-tree discard: command instances beyond the draw distance.
                let u = SelectUniform::new(camera, &p);
                let discarded: u64 = frame
                    .selection
                    .commands
                    .iter()
                    .flat_map(|c| {
                        &indirection[c.first_instance as usize
                            ..(c.first_instance + c.instance_count) as usize]
                    })
                    .filter(|&&t| !tree_within_draw_distance(&u, spheres[t as usize].0))
                    .count() as u64;
                assert_eq!(
                    frame.drawn.trees_discarded, discarded,
                    "{what}: trees discarded"
                );
                reached[2] += discarded;
                reached[3] += u64::from(frame.selection.counters.transition_batches);
                // The draw's work counters (metrics.json `draw.*`): the triangles submitted are
                // those of every command's trees within the draw distance; the later counters
                // can only shrink down the pipeline; every pixel that shows a tree was written by
                // at least one tree fragment.
                let ds = &frame.drawn.tree_stats;
                let triangles: u64 = frame
                    .selection
                    .commands
                    .iter()
                    .map(|c| {
                        let within = indirection[c.first_instance as usize
                            ..(c.first_instance + c.instance_count) as usize]
                            .iter()
                            .filter(|&&t| tree_within_draw_distance(&u, spheres[t as usize].0))
                            .count() as u64;
                        within * u64::from(c.index_count / 3)
                    })
                    .sum();
                assert_eq!(ds.triangles_in, triangles, "{what}: triangles submitted");
                assert!(
                    ds.triangles_rasterized <= ds.triangles_clipped
                        && ds.fragments_written <= ds.fragments_shaded
                        && ds.fragments_shaded <= ds.fragments_covered,
                    "{what}: draw counters out of order: {ds:?}"
                );
                let tree_pixels = frame
                    .drawn
                    .target
                    .aux()
                    .iter()
                    .filter(|&&id| [LOD_ID_MESH, LOD_ID_BILLBOARD, LOD_ID_TRANSITION].contains(&id))
                    .count() as u64;
                assert!(
                    ds.fragments_written >= tree_pixels,
                    "{what}: {} tree fragments written, but {tree_pixels} pixels show a tree",
                    ds.fragments_written
                );
                reached_draw += tree_pixels.min(ds.triangles_in);
                frames += 1;
            }
        }
    }
    eprintln!(
        "counters (reference frames): {frames} frames; trees dropped by refine {}, batching \
         extras {}, discarded by the draw distance {}, transition batches {}",
        reached[0], reached[1], reached[2], reached[3]
    );
    assert!(
        reached.iter().all(|&r| r > 0) && reached_draw > 0,
        "some counter is never non-zero: {reached:?}, draw {reached_draw}"
    );
}

/// The GPU's counters equal their recount from the GPU's own output, on random cases:
/// `select.wgsl` (both compactions; the decision counters from the reference's decisions, where
/// the GPU's commands equal the reference's), the cut (uncoalesced and coalesced, the decision
/// counters from the GPU's own per-node codes by recursion) and `refine.wgsl` (on the GPU's
/// stable selection).
#[test]
fn gpu_counters_equal_their_recount() {
    let Some(ctx) = gpu_context() else {
        eprintln!("counters (GPU): no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    let mut runner = TestRunner::new(Config {
        cases: CASES / 2,
        failure_persistence: None,
        ..Config::default()
    });
    // Cases, cases whose grid commands differ from the reference's (decision counters not
    // recounted there), cuts, refines.
    let tally = std::cell::RefCell::new([0u64; 4]);
    let strategy = (
        instances(300),
        cameras(),
        params(),
        0usize..MODES.len(),
        1usize..3,
        2u32..16,
    );
    let result = runner.run(&strategy, |(trees, camera, p, mode_i, cull_i, npn)| {
        let mut tally = tally.borrow_mut();
        let fail = |e: forestlod_gpu::GpuError| TestCaseError::fail(e.to_string());
        let mode = TREE_CULLS[cull_i];
        let p = Params {
            nodes_per_node: npn,
            ..case_params(p, mode)
        };
        let packed = Packed::new(trees, p.grid_size);
        let (g, b) = (&packed.geometry, &packed.batches);
        tally[0] += 1;
        // select.wgsl.
        let reference = select(&b.metas, &b.scales, &g.meshes, &g.billboard, &camera, &p);
        let decisions = batch_decisions(&b.metas, &camera, &p);
        let mut gpu =
            GpuSelect::new(ctx, &b.metas, &b.scales, &g.meshes, &g.billboard).map_err(fail)?;
        for compaction in Compaction::ALL {
            let s = gpu.run(&camera, &p, compaction).map_err(fail)?;
            let s = Selection {
                commands: s.commands,
                data: s.data,
                counters: s.counters,
            };
            let own = from_commands(&s);
            let want = if multiset(&s) == multiset(&reference) {
                grid_recount(&decisions, &s)
            } else {
                tally[1] += 1;
                SelectCounters {
                    batches_tested: b.metas.len() as u32,
                    culled_distance: s.counters.culled_distance,
                    culled_frustum: s.counters.culled_frustum,
                    ..own
                }
            };
            prop_assert_eq_counters(&s.counters, &want, &format!("GPU select {compaction:?}"))?;
        }
        // refine.wgsl on the GPU's stable selection.
        let s = gpu.run(&camera, &p, Compaction::Stable).map_err(fail)?;
        let input = Selection {
            commands: s.commands,
            data: s.data,
            counters: s.counters,
        };
        let trees = cull_trees_of(&packed.scene, &packed.spheres);
        let mut r = GpuRefine::new(ctx, &trees, &b.indirection).map_err(fail)?;
        r.dispatch(gpu.buffers_mut(), &camera, &p).map_err(fail)?;
        let got = r.read(gpu.buffers_mut()).map_err(fail)?;
        let output = Selection {
            commands: got.selection.commands,
            data: got.selection.data,
            counters: got.selection.counters,
        };
        let want = refine_recount(mode, &input, &output);
        let have = (
            u64::from(got.counters.trees_tested),
            u64::from(got.counters.trees_kept),
        );
        if have != want {
            return Err(TestCaseError::fail(format!(
                "GPU refine ({mode:?}): tested, kept {have:?}, recount {want:?}"
            )));
        }
        tally[3] += 1;
        // The cut.
        let hmode = MODES[mode_i];
        let p = Params {
            hierarchy: hmode as u32,
            coalesce: Coalesce::On as u32,
            tree_cull: TreeCull::None as u32,
            ..p
        };
        let h = Hierarchy::build(&packed.scene, &g.meshes, &p)
            .unwrap()
            .unwrap();
        let mut chain = SelectionChain::cut(
            ctx,
            &h.nodes,
            &h.scales,
            hmode as u32,
            &g.meshes,
            &g.billboard,
            None,
        )
        .map_err(fail)?;
        let sel = chain.run(&camera, &p, Compaction::Stable).map_err(fail)?;
        let (codes, _) = chain.read_codes_and_states().map_err(fail)?;
        let raw = chain.read_uncoalesced().map_err(fail)?;
        let raw = Selection {
            commands: raw.commands,
            data: raw.data,
            counters: raw.counters,
        };
        let merged = Selection {
            commands: sel.commands,
            data: sel.data,
            counters: sel.counters,
        };
        prop_assert_eq_counters(
            &raw.counters,
            &cut_recount(&h, &codes, &raw, None),
            &format!("GPU {hmode:?} raw cut"),
        )?;
        prop_assert_eq_counters(
            &merged.counters,
            &cut_recount(&h, &codes, &raw, Some(&merged)),
            &format!("GPU {hmode:?} coalesced cut"),
        )?;
        tally[2] += 1;
        Ok(())
    });
    let tally = tally.into_inner();
    eprintln!(
        "counters (GPU): {} cases ({} select runs with commands differing from the reference's: \
         decision counters not recounted there), {} cuts, {} refines",
        tally[0], tally[1], tally[2], tally[3]
    );
    if let Err(e) = result {
        panic!("counters (GPU): {e}");
    }
    assert!(
        tally[1] * 10 <= tally[0],
        "too many cases without a decision recount: {tally:?}"
    );
}

/// The commands of `s` as a multiset of `(batch, lod, instance_count, first_instance)`.
fn multiset(s: &Selection) -> Vec<[u32; 4]> {
    let mut v: Vec<[u32; 4]> = s
        .commands
        .iter()
        .zip(&s.data)
        .map(|(c, d)| [d.batch, d.lod, c.instance_count, c.first_instance])
        .collect();
    v.sort_unstable();
    v
}

/// The GPU baselines' `commands` and `trees_drawn` (the sweep's GPU rows for `vegetation` and
/// `primitive`) recounted from the trees the GPU culled to: one command per mesh with a visible
/// tree (Vegetation), one instanced draw when any tree is visible (Primitive).
#[test]
fn gpu_baseline_counters_equal_their_recount() {
    let Some(ctx) = gpu_context() else {
        eprintln!("counters (GPU baselines): no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    let scene = builtin::by_name("tiny").unwrap();
    let p = tiny_params(FadeMode::DitherSequential);
    let prepared = prepare(scene.clone(), &p).unwrap();
    let mut gs = GpuScene::new(ctx, &prepared, &p, StagesFromCpu::NONE).expect("GpuScene::new");
    let mut visible_total = 0;
    for v in named_views(&scene, &p, 32).iter().filter(|v| v.yaw == 0.0) {
        for variant in [GpuPipeline::Vegetation, GpuPipeline::Primitive] {
            let frame = gs
                .render(&prepared, variant, &v.camera, &v.params)
                .expect("frame");
            let visible = gs.cull().expect("culled").read_visible().expect("read");
            let meshes: BTreeSet<u32> = visible
                .iter()
                .map(|&t| prepared.scene.instances[t as usize].mesh)
                .collect();
            let commands = if variant == GpuPipeline::Vegetation {
                meshes.len() as u64
            } else {
                u64::from(!visible.is_empty())
            };
            let what = format!(
                "{} {} {}",
                variant.name(),
                v.camera_name,
                v.params.draw_distance
            );
            assert_eq!(frame.commands, commands, "{what}: commands");
            assert_eq!(
                frame.trees_drawn,
                Some(visible.len() as u64),
                "{what}: trees drawn"
            );
            visible_total += visible.len();
        }
    }
    assert!(visible_total > 0);
}
