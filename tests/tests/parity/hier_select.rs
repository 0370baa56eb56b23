//! Parity of the GPU hierarchical cut (`gpu/src/shaders/hier_select.wgsl`) with the reference
//! (`reference/src/hier_select.rs`), issue 13, on random scenes, cameras and parameters, for every
//! hierarchical mode (`octree-euclidean` included: the GPU must reproduce it, conservative or not):
//! - per-node codes (decision + recurse bit) equal the reference's, except nodes whose sphere or box
//!   lies within `forestlod_harness::judge::AMBIGUITY_REL` of a threshold (the shared judge's
//!   classification, `judge::node_ambiguity`) (interval ends against the draw distance and the
//!   fade band, plane distances against the cull and "wholly inside" limits, the Euclidean box
//!   distance against the transition): those are classified *ambiguous*, counted and reported;
//! - whatever the codes, the GPU's states, commands, data and counters equal the reference's
//!   resolution and compaction of the **GPU's own codes** exactly (stable order), both the cut's
//!   list before coalescing and the coalesced list (`coalesce` on or off at random, issue 13);
//! - where no code differs, they equal the reference's output exactly; the only floats
//!   (`fade_start`, `fade_end`) are copied from the uniform, max difference 0.
//!
//! - with `command_order = front-to-back` (at random, issue 13, E§7), the GPU's sorted commands
//!   equal the reference's order of the same coalesced list exactly; a run key
//!   (`command_depth_key`) the GPU computed away from the reference's by at most the error bound
//!   of a contracted view depth (`judge::run_key_bounds`: fused multiply-adds in the dot product,
//!   bounded in the magnitudes of its terms) is classified *ambiguous* and counted, and then the
//!   GPU's order must equal the reference's sort under the GPU's keys; a key further away fails.
//!
//! And the frame: the GPU renders `tiny` with each hierarchy bit-identically to its grid frame
//! (dither-sequential), and in `alpha` mode differs only inside the fade band.
//!
//! Without an adapter the tests fail with an install hint unless `FORESTLOD_ALLOW_NO_GPU=1`.

use std::time::Instant;

use forestlod_gpu::{Compaction, GpuSelection};
use forestlod_harness::context::gpu_context;
use forestlod_harness::gpu_frame::{SelectionChain, StagesFromCpu, gpu_draw, render_gpu};
use forestlod_harness::judge::{check_order, node_ambiguity, run_key_bounds};
use forestlod_reference::hierarchy::Hierarchy;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::builtin;
use forestlod_reference::select::Selection;
use forestlod_shared::{
    Camera, Coalesce, CommandOrder, FadeMode, Hierarchy as Mode, LOD_ID_TRANSITION, NodeMeta,
    Params, ViewUniform,
};
use forestlod_tests::{Packed, cameras, instances, params, straddling_cameras, straddling_params};
use forestlod_tests::{full_cut, full_resolve};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestCaseError, TestRunner};

/// Proptest cases (each one random hierarchical mode).
const CASES: u32 = 256;

/// Every hierarchical mode (the GPU must match the reference on all of them).
const MODES: [Mode; 5] = [
    Mode::GridAabb,
    Mode::Quadtree,
    Mode::Octree,
    Mode::OctreeEuclidean,
    Mode::Kmeans,
];

#[derive(Debug, Default)]
struct Tally {
    cases: u64,
    exact_cases: u64,
    nodes: u64,
    ambiguous_nodes: u64,
    commands_compared: u64,
    max_float_diff: f32,
    coalesced_cases: u64,
    commands_before: u64,
    commands_after: u64,
    ordered_cases: u64,
    keys_compared: u64,
    ambiguous_keys: u64,
    /// Largest key difference as a fraction of its contraction bound (`judge::check_order`).
    max_key_of_bound: f64,
    moved_commands: u64,
}

/// The GPU's selection as the reference's (the shared judges read [`Selection`]s).
fn selection_of(s: &GpuSelection) -> Selection {
    Selection {
        commands: s.commands.clone(),
        data: s.data.clone(),
        counters: s.counters,
    }
}

/// One case of the cut's parity (module docs): the GPU cut of `h` (built with `p`'s mode) against
/// the reference's, for one camera; counts go to `tally`.
fn check_cut(
    ctx: &'static forestlod_gpu::GpuContext,
    packed: &Packed,
    h: &Hierarchy,
    camera: &Camera,
    p: &Params,
    tally: &mut Tally,
) -> Result<(), TestCaseError> {
    let g = &packed.geometry;
    let u = ViewUniform::new(camera, p);
    let mode = Mode::from_id(p.hierarchy).expect("a hierarchical mode");
    let coalesce = Coalesce::from_id(p.coalesce).expect("a coalesce mode");
    let merge = coalesce == Coalesce::On;
    let sort = p.command_order == CommandOrder::FrontToBack as u32;
    let want = full_cut(h, &g.meshes, &g.billboard, camera, p);
    let mut gpu = SelectionChain::cut(
        ctx,
        &h.nodes,
        &h.scales,
        mode as u32,
        &g.meshes,
        &g.billboard,
        None,
    )
    .map_err(|e| TestCaseError::fail(e.to_string()))?;
    let sel = gpu
        .run(camera, p, Compaction::Stable)
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    let (codes, states) = gpu
        .read_codes_and_states()
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    tally.cases += 1;
    tally.nodes += h.nodes.len() as u64;
    // 1. Codes: differences only where ambiguous.
    let mut ambiguous = 0;
    for (i, (w, gc)) in want.codes.iter().zip(&codes).enumerate() {
        if w != gc {
            match node_ambiguity(&h.nodes[i], &u, None) {
                Some(why) => {
                    eprintln!(
                        "{mode:?}: node {i} ambiguous ({why}): reference {w:#x}, GPU {gc:#x}"
                    );
                    ambiguous += 1;
                }
                None => prop_assert!(
                    false,
                    "{:?}: node {} {:?} code {:#x} on the GPU, {:#x} in the reference, not near a threshold",
                    mode,
                    i,
                    h.nodes[i],
                    gc,
                    w
                ),
            }
        }
    }
    tally.ambiguous_nodes += ambiguous;
    // 2. The GPU's resolution and compaction of its own codes: exact.
    let own = full_resolve(
        h,
        codes.clone(),
        &g.meshes,
        &g.billboard,
        &u,
        coalesce,
        CommandOrder::Node,
    );
    // The cut's list before coalescing, and the coalescing of it, each exact.
    let raw = gpu
        .read_uncoalesced()
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    let own_raw = full_resolve(
        h,
        codes.clone(),
        &g.meshes,
        &g.billboard,
        &u,
        Coalesce::Off,
        CommandOrder::Node,
    );
    prop_assert_eq!(
        &raw.commands,
        &own_raw.selection.commands,
        "{:?}: uncoalesced commands",
        mode
    );
    prop_assert_eq!(
        &raw.data,
        &own_raw.selection.data,
        "{:?}: uncoalesced data",
        mode
    );
    prop_assert_eq!(
        raw.counters,
        own_raw.selection.counters,
        "{:?}: uncoalesced counters",
        mode
    );
    if merge {
        tally.coalesced_cases += 1;
        tally.commands_before += raw.commands.len() as u64;
        tally.commands_after += sel.commands.len() as u64;
    }
    prop_assert_eq!(&states, &own.states, "{:?}: states", mode);
    let mut ambiguous_keys = 0;
    if sort {
        // The GPU's sort of its own coalesced list, against the reference's (own: the
        // unsorted list and its keys per run).
        let pairs = gpu
            .read_order_pairs(sel.commands.len())
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        let bounds = run_key_bounds(&h.nodes, &own_raw.selection, own.keys.len(), &u, coalesce);
        let judged = check_order(
            &selection_of(&sel),
            &pairs,
            &own.selection,
            &own.keys,
            &bounds,
        )
        .map_err(|e| TestCaseError::fail(format!("{mode:?}: {e}")))?;
        ambiguous_keys = judged.ambiguous;
        tally.max_key_of_bound = tally.max_key_of_bound.max(judged.max_of_bound);
        tally.ordered_cases += 1;
        tally.keys_compared += pairs.len() as u64;
        tally.ambiguous_keys += ambiguous_keys;
        tally.moved_commands += pairs
            .iter()
            .enumerate()
            .filter(|(i, (_, r))| *i as u32 != *r)
            .count() as u64;
    } else {
        prop_assert_eq!(
            &sel.commands,
            &own.selection.commands,
            "{:?}: commands",
            mode
        );
        prop_assert_eq!(&sel.data, &own.selection.data, "{:?}: data", mode);
        prop_assert_eq!(sel.counters, own.selection.counters, "{:?}: counters", mode);
    }
    for d in &sel.data {
        let diff = (d.fade_start - u.fade_start)
            .abs()
            .max((d.fade_end - u.fade_end).abs());
        tally.max_float_diff = tally.max_float_diff.max(diff);
    }
    // 3. Exact against the reference where no code and no key differs.
    if ambiguous == 0 && ambiguous_keys == 0 {
        prop_assert_eq!(&sel.commands, &want.selection.commands, "{:?}", mode);
        prop_assert_eq!(&sel.data, &want.selection.data, "{:?}", mode);
        prop_assert_eq!(sel.counters, want.selection.counters, "{:?}", mode);
        prop_assert_eq!(&states, &want.states, "{:?}", mode);
        tally.exact_cases += 1;
        tally.commands_compared += sel.commands.len() as u64;
    }
    Ok(())
}

#[test]
fn gpu_cut_matches_reference() {
    let Some(ctx) = gpu_context() else {
        eprintln!("hier_select parity: no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    let started = Instant::now();
    let tally = std::cell::RefCell::new(Tally::default());
    let strategy = (
        instances(300),
        cameras(),
        params(),
        2u32..24,
        0u32..9,
        0usize..MODES.len(),
        any::<bool>(),
        any::<bool>(),
    );
    let mut runner = TestRunner::new(Config {
        cases: CASES,
        failure_persistence: None,
        ..Config::default()
    });
    let result = runner.run(
        &strategy,
        |(trees, camera, p, npn, mcd, mode_i, merge, sort)| {
            let mut tally = tally.borrow_mut();
            let coalesce = if merge { Coalesce::On } else { Coalesce::Off };
            let order_mode = if sort {
                CommandOrder::FrontToBack
            } else {
                CommandOrder::Node
            };
            // One mode per case (each mode in about a quarter of the cases) keeps the test near 20 s.
            let p = Params {
                nodes_per_node: npn,
                max_cull_depth: mcd,
                coalesce: coalesce as u32,
                command_order: order_mode as u32,
                grid_size: p.grid_size.min(400.0),
                hierarchy: MODES[mode_i] as u32,
                ..p
            };
            let packed = Packed::new(trees, p.grid_size);
            let g = &packed.geometry;
            let h = Hierarchy::build(&packed.scene, &g.meshes, &p)
                .unwrap()
                .unwrap();
            check_cut(ctx, &packed, &h, &camera, &p, &mut tally)
        },
    );
    let tally = tally.into_inner();
    eprintln!(
        "hier_select parity: {} (case, mode) pairs ({} exact, {} coalesced: {} commands -> {}), {} nodes compared, {} ambiguous nodes, {} commands compared exactly, max fade float difference {}; front-to-back: {} cases, {} run keys compared, {} ambiguous (within their contraction bound, the largest at {:.3} of it), {} commands moved by the sort; {:.1} s",
        tally.cases,
        tally.exact_cases,
        tally.coalesced_cases,
        tally.commands_before,
        tally.commands_after,
        tally.nodes,
        tally.ambiguous_nodes,
        tally.commands_compared,
        tally.max_float_diff,
        tally.ordered_cases,
        tally.keys_compared,
        tally.ambiguous_keys,
        tally.max_key_of_bound,
        tally.moved_commands,
        started.elapsed().as_secs_f64()
    );
    if let Err(e) = result {
        panic!("hier_select parity: {e}");
    }
    assert_eq!(tally.max_float_diff, 0.0);
    // The merging path ran: random hierarchies of up to 300 trees have adjacent runs.
    assert!(
        tally.commands_after < tally.commands_before,
        "coalescing merged nothing in {} cases",
        tally.coalesced_cases
    );
    // The sort ran and moved commands (random cameras see nodes out of depth-first depth order).
    assert!(
        tally.moved_commands > 0,
        "front-to-back moved nothing in {} cases",
        tally.ordered_cases
    );
}

/// Coalescing reads no slot past the command count (issue 36, a survivor of the WGSL sample):
/// eight contiguous commands of one mesh and LOD are uploaded, the count says five, and slot 5
/// (stale: what an earlier, longer cut left there) continues the last run. The GPU's runs must
/// equal the reference's coalescing of the first five: one command of 50 instances. A rule that
/// asks whether slot `n` starts a run to end the last one (`coalesce.wgsl`'s
/// `j + 1u == n || is_head(j + 1u)` with `==` flipped, which every other test passes: on
/// lavapipe its race has the right winner) leaves the last run's count unwritten.
#[test]
fn gpu_coalescing_ignores_stale_slots_past_the_count() {
    use forestlod_harness::stage::{Backend, Coalesce as CoalesceStage, CoalesceInput, Reference};
    use forestlod_shared::{CommandData, DrawCommand};
    let Some(ctx) = gpu_context() else {
        eprintln!("hier_select stale slots: no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    let (uploaded, count) = (8u32, 5u32);
    let mut full = Selection::default();
    for i in 0..uploaded {
        full.commands.push(DrawCommand {
            index_count: 6,
            instance_count: 10,
            first_index: 0,
            base_vertex: (i << forestlod_shared::COMMAND_SHIFT) as i32,
            first_instance: 10 * i,
        });
        full.data.push(CommandData {
            fade_start: 100.0,
            fade_end: 120.0,
            batch: i,
            mesh: 0,
            lod: forestlod_shared::LOD_MESH,
            billboard: 0,
            fading: 0,
            first_tree: 0,
            group_len: 0,
            _pad0: 0,
        });
    }
    full.counters.commands = uploaded;
    let mut prefix = full.clone();
    prefix.commands.truncate(count as usize);
    prefix.data.truncate(count as usize);
    prefix.counters.commands = count;
    full.counters.commands = count;
    let want = Backend::<CoalesceStage>::run(
        &Reference,
        CoalesceInput {
            raw: &prefix,
            mode: Coalesce::On,
        },
    );
    assert_eq!(
        want.selection.commands.len(),
        1,
        "the reference merges the five"
    );
    assert_eq!(want.selection.commands[0].instance_count, 50);
    // All eight uploaded, then the count lowered to five on the GPU: slots 5..8 are stale.
    let input = forestlod_gpu::SelectBuffers::from_cpu(ctx, &full.commands, &full.data, &{
        let mut c = full.counters;
        c.commands = uploaded;
        c
    })
    .expect("upload");
    ctx.queue.write_buffer(
        &input.counters,
        forestlod_gpu::SelectBuffers::COUNT_OFFSET,
        bytemuck::bytes_of(&count),
    );
    let mut gpu = forestlod_gpu::coalesce::GpuCoalesce::new(ctx, &input).expect("GpuCoalesce");
    let mut encoder = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("stale"),
        });
    gpu.encode(&mut encoder, Coalesce::On);
    ctx.queue.submit([encoder.finish()]);
    let out = gpu.buffers().read(ctx).expect("read the runs");
    let got_commands: Vec<_> = out.commands.clone();
    let got_data: Vec<_> = out.data.clone();
    eprintln!("stale slots: GPU runs {got_commands:?}");
    assert_eq!(got_commands, want.selection.commands, "commands");
    assert_eq!(got_data, want.selection.data, "data");
}

/// Cameras that get fewer than this many hard-side cases from `tiny`'s octrees fail the test: the
/// generator must keep reaching what it is for (measured: see the test's output).
const STRADDLING_CASES_MIN: usize = 8;

/// The octree's partial-visibility test on its hard side (issue 36, class 5): cameras turned so
/// that a side plane passes between a node's box centre and its sphere centre
/// (`forestlod_tests::straddling_cameras`), where the "wholly inside" test decides differently on
/// the two centres. Random cameras almost never land there, so a GPU cut that tested the wrong
/// centre, or dropped the test, passed the random property. `octree` and `octree-euclidean` on
/// `tiny`, coalescing and order alternating; each case judged as the random property's.
#[test]
fn gpu_cut_on_frustum_straddling_boxes() {
    let Some(ctx) = gpu_context() else {
        eprintln!("hier_select straddling: no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    let started = Instant::now();
    let mut tally = Tally::default();
    let (mut cases, mut failures) = (0usize, Vec::new());
    for mode in [Mode::Octree, Mode::OctreeEuclidean] {
        let p = straddling_params(mode);
        let trees = forestlod_tests::tiny_card_trees();
        let packed = Packed::new(trees, p.grid_size);
        let g = &packed.geometry;
        let h = Hierarchy::build(&packed.scene, &g.meshes, &p)
            .unwrap()
            .unwrap();
        let cameras = straddling_cameras(&h.nodes, &p, 96, 72, 16);
        eprintln!("{mode:?}: {} straddling cameras", cameras.len());
        assert!(
            cameras.len() >= STRADDLING_CASES_MIN,
            "{mode:?}: only {} straddling cameras",
            cameras.len()
        );
        for (k, (node, camera)) in cameras.iter().enumerate() {
            let p = Params {
                coalesce: [Coalesce::On, Coalesce::Off][k % 2] as u32,
                command_order: [CommandOrder::Node, CommandOrder::FrontToBack][(k / 2) % 2] as u32,
                ..p
            };
            cases += 1;
            if let Err(e) = check_cut(ctx, &packed, &h, camera, &p, &mut tally) {
                failures.push(format!("{mode:?}, camera on node {node}: {e}"));
            }
        }
    }
    eprintln!(
        "hier_select straddling: {cases} cases, {} nodes compared, {} ambiguous, {} exact cases; {:.1} s",
        tally.nodes,
        tally.ambiguous_nodes,
        tally.exact_cases,
        started.elapsed().as_secs_f64()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The cut's LOD decision on the knife edges of its box interval (issue 36's WGSL survivor 203:
/// `aabb_view_interval`'s `hi = d + r + m` with the margin subtracted passed every case): for
/// every root node of `tiny`'s card trees under each mode whose box interval end is nearer the
/// eye than its sphere's (so the box decides), seen along +x from outside, two frames with the
/// band's edge at the box's unwidened end: the fade start at `d + r` (the widened `hi` lies `m`
/// past it, so LOD1 is needed) and the fade end at `d - r` (the widened `lo` lies `m` before
/// it, so LOD0 is needed). Those nodes are within the ambiguity of a threshold, which the random
/// property excuses; the margin `m` (at least 16 `f32` steps of `|d|`) exists for exactly this
/// rounding, so here the GPU must take the conservative side: its code for the node equals the
/// reference's, which needs the LOD.
#[test]
fn gpu_cut_on_box_knife_edges() {
    let Some(ctx) = gpu_context() else {
        eprintln!("hier_select knife edges: no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    use forestlod_shared::{DECISION_LOD0, DECISION_LOD1, NO_PARENT, aabb_view_interval};
    let trees = forestlod_tests::tiny_card_trees();
    let (mut frames, mut failures) = (0usize, Vec::new());
    for mode in [Mode::GridAabb, Mode::Quadtree, Mode::Octree, Mode::Kmeans] {
        let base = straddling_params(mode);
        let packed = Packed::new(trees.clone(), base.grid_size);
        let g = &packed.geometry;
        let h = Hierarchy::build(&packed.scene, &g.meshes, &base)
            .unwrap()
            .unwrap();
        let mut gpu = SelectionChain::cut(
            ctx,
            &h.nodes,
            &h.scales,
            mode as u32,
            &g.meshes,
            &g.billboard,
            None,
        )
        .unwrap();
        for (i, n) in h.nodes.iter().enumerate() {
            if n.parent != NO_PARENT {
                continue;
            }
            // From outside along +x, three node radii away.
            let back = n.extent[0] + 3.0 * n.radius;
            let eye = [n.box_center[0] - back, n.box_center[1], n.box_center[2]];
            let target = [n.box_center[0], n.box_center[1], n.box_center[2]];
            let camera = Camera::look_at(eye, target, 60.0, 64, 64);
            let u = ViewUniform::new(&camera, &base);
            let b = aabb_view_interval(n.box_center, n.extent, u.eye, u.forward);
            let sphere = forestlod_shared::view_interval(n.center, n.radius, u.eye, u.forward);
            let f = u.forward;
            let r = f[0].abs() * n.extent[0] + f[1].abs() * n.extent[1] + f[2].abs() * n.extent[2];
            for (edge, at, box_decides, bit) in [
                (
                    "fade start at the box's d + r",
                    b.d + r,
                    b.hi < sphere.hi,
                    DECISION_LOD1,
                ),
                (
                    "fade end at the box's d - r",
                    b.d - r,
                    b.lo > sphere.lo,
                    DECISION_LOD0,
                ),
            ] {
                if !box_decides {
                    continue;
                }
                // A band of width 0 puts both its ends at `at` exactly.
                let p = Params {
                    lod1_transition: at,
                    fade_width: 0.0,
                    ..base
                };
                let want = full_cut(&h, &g.meshes, &g.billboard, &camera, &p);
                gpu.run(&camera, &p, Compaction::Stable).unwrap();
                let (codes, _) = gpu.read_codes_and_states().unwrap();
                frames += 1;
                let name = format!("{mode:?} root {i}, {edge} = {at}");
                if want.codes[i] & bit == 0 {
                    failures.push(format!(
                        "{name}: the reference's code {:#x} lacks the LOD (box interval {b:?})",
                        want.codes[i]
                    ));
                } else if codes[i] != want.codes[i] {
                    failures.push(format!(
                        "{name}: code {:#x} on the GPU, {:#x} in the reference (box interval {b:?})",
                        codes[i], want.codes[i]
                    ));
                }
            }
        }
    }
    eprintln!(
        "hier_select knife edges: {frames} frames, {} failures",
        failures.len()
    );
    assert!(
        frames >= 4,
        "only {frames} knife-edge frames: the box decides too rarely"
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The GPU frame with a hierarchy equals the GPU frame with the grid: bit for bit with
/// dither-sequential, and in `alpha` mode only inside the fade band (blending order). Counts
/// reported per frame.
#[test]
fn gpu_hierarchy_frames_equal_grid_frames() {
    let Some(ctx) = gpu_context() else {
        eprintln!("hier_select frames: no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    let draw = gpu_draw(ctx);
    let scene = builtin::by_name("tiny").unwrap();
    let base = forestlod_tests::tiny_hierarchy_params(Mode::Grid);
    let grid = prepare(scene.clone(), &base).unwrap();
    for mode in [Mode::GridAabb, Mode::Quadtree, Mode::Octree, Mode::Kmeans] {
        let p = Params {
            hierarchy: mode as u32,
            ..base
        };
        let prepared = prepare(scene.clone(), &p).unwrap();
        for (camera_name, yaw, camera) in
            forestlod_tests::small_poses(&prepared.scene, &[("medium", 0.0), ("close", 30.0)])
        {
            for fade in [FadeMode::DitherSequential, FadeMode::Alpha] {
                let p = Params {
                    fade_mode: fade as u32,
                    ..p
                };
                let gp = Params {
                    hierarchy: Mode::Grid as u32,
                    ..p
                };
                let a = render_gpu(ctx, draw, &grid, &camera, &gp, StagesFromCpu::default())
                    .unwrap()
                    .images;
                let b = render_gpu(ctx, draw, &prepared, &camera, &p, StagesFromCpu::default())
                    .unwrap()
                    .images;
                let colour = a.color.iter().zip(&b.color).filter(|(x, y)| x != y).count();
                let depth = a
                    .depth
                    .iter()
                    .zip(&b.depth)
                    .filter(|(x, y)| x.to_bits() != y.to_bits())
                    .count();
                let lod = a
                    .lod_id
                    .iter()
                    .zip(&b.lod_id)
                    .filter(|(x, y)| x != y)
                    .count();
                let outside_band = a
                    .color
                    .iter()
                    .zip(&b.color)
                    .zip(a.lod_id.iter().zip(&b.lod_id))
                    .filter(|((x, y), (la, lb))| {
                        x != y && !(**la == LOD_ID_TRANSITION && **lb == LOD_ID_TRANSITION)
                    })
                    .count();
                eprintln!(
                    "GPU {mode:?} {camera_name} yaw {yaw} {fade:?}: differing pixels colour {colour} (outside the band {outside_band}) depth {depth} lod {lod}"
                );
                assert_eq!(outside_band, 0, "{mode:?} {camera_name} yaw {yaw} {fade:?}");
                if fade != FadeMode::Alpha {
                    assert_eq!(
                        (colour, depth, lod),
                        (0, 0, 0),
                        "{mode:?} {camera_name} yaw {yaw} {fade:?}"
                    );
                }
            }
        }
    }
}

/// The ancestor walk goes all the way up: in a chain of six nodes (depth 0..5) whose bounds are
/// deliberately not nested, one culled node hides every node below it, however deep, although
/// each of those is in view and its own parent recursed. Random scenes rarely produce this
/// (nested bounds make a child of a non-recursing node rarely recurse), so it is built by hand.
/// Mutation-checked: walking only to the parent (`p = NO_PARENT` after the first step in
/// `hier_resolve`) visits and emits the deep nodes.
#[test]
fn gpu_cut_walks_every_ancestor() {
    let Some(ctx) = gpu_context() else {
        eprintln!("hier_select ancestors: no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    let packed = Packed::new(vec![forestlod_tests::tree_at_x(50.0)], 500.0);
    let g = &packed.geometry;
    let camera =
        forestlod_shared::Camera::look_at([0.0, 0.0, 5.0], [100.0, 0.0, 5.0], 60.0, 64, 64);
    let p = Params::default();
    let node = |x: f32, parent: u32, depth: u32, children: u32| NodeMeta {
        center: [x, 0.0, 5.0],
        radius: 8.0,
        extent: [5.0, 5.0, 5.0],
        mesh: 0,
        box_center: [x, 0.0, 5.0],
        len: 1,
        offset: 0,
        parent,
        depth,
        child_count: children,
    };
    for culled in 0..5u32 {
        let nodes: Vec<NodeMeta> = (0..6u32)
            .map(|d| {
                let x = if d == culled { -200.0 } else { 50.0 + d as f32 };
                let parent = if d == 0 {
                    forestlod_shared::NO_PARENT
                } else {
                    d - 1
                };
                node(x, parent, d, (d < 5) as u32)
            })
            .collect();
        let h = Hierarchy {
            mode: Mode::Quadtree,
            scales: vec![[1.0, 1.0]; nodes.len()],
            nodes: nodes.clone(),
            indirection: vec![0],
        };
        let want = full_cut(&h, &g.meshes, &g.billboard, &camera, &p);
        let mut gpu = SelectionChain::cut(
            ctx,
            &nodes,
            &h.scales,
            Mode::Quadtree as u32,
            &g.meshes,
            &g.billboard,
            None,
        )
        .unwrap();
        let sel = gpu.run(&camera, &p, Compaction::Stable).unwrap();
        let (codes, states) = gpu.read_codes_and_states().unwrap();
        assert_eq!(codes, want.codes, "culled node {culled}");
        assert_eq!(states, want.states, "culled node {culled}: states");
        assert_eq!(
            sel.commands, want.selection.commands,
            "culled node {culled}"
        );
        // Nothing below the culled node is visited; nothing at all is emitted (the leaf is below).
        assert!(
            states[culled as usize + 1..].iter().all(|&s| s == 0),
            "{states:?}"
        );
        assert!(sel.commands.is_empty());
    }
}

/// Coalescing on the GPU where the command list spans several scan chunks (over 256 commands:
/// `tiny`'s quadtree of 8-tree leaves at medium range emits some 280): the coalesced and the
/// uncoalesced commands, data and counters equal the reference's exactly, and merging happened.
/// The random cases of `gpu_cut_matches_reference` hold few commands each. Mutation-checked
/// (`FORESTLOD_MUTANT_WGSL=coalesce.wgsl=...`): the run index taken without the head's own flag,
/// no `coalesce_finish` subtraction, `continues_run` without the contiguity test, and the run's
/// last command found by `j + 1 == n` only each fail it.
#[test]
fn gpu_coalescing_spans_scan_chunks() {
    let Some(ctx) = gpu_context() else {
        eprintln!("hier_select coalescing: no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    let scene = builtin::by_name("tiny").unwrap();
    let p = forestlod_tests::tiny_hierarchy_params(Mode::Quadtree);
    let prepared = prepare(scene, &p).unwrap();
    let h = prepared.hierarchy.as_ref().unwrap();
    let g = &prepared.geometry;
    let mut gpu = SelectionChain::gpu(ctx, &prepared).unwrap();
    let mut most = 0;
    for yaw in [0.0, 330.0] {
        let camera =
            forestlod_reference::cameras::named_camera("medium", &prepared.scene, yaw, 96, 72)
                .unwrap();
        let u = ViewUniform::new(&camera, &p);
        let want = full_cut(h, &g.meshes, &g.billboard, &camera, &p);
        let sel = gpu.run(&camera, &p, Compaction::Stable).unwrap();
        let raw = gpu.read_uncoalesced().unwrap();
        let (codes, _) = gpu.read_codes_and_states().unwrap();
        assert_eq!(codes, want.codes, "yaw {yaw}: codes");
        let want_raw = full_resolve(
            h,
            codes,
            &g.meshes,
            &g.billboard,
            &u,
            Coalesce::Off,
            CommandOrder::Node,
        );
        eprintln!(
            "GPU coalescing on tiny, quadtree, medium, yaw {yaw}: {} commands -> {}",
            raw.commands.len(),
            sel.commands.len()
        );
        most = most.max(raw.commands.len());
        assert!(sel.commands.len() < raw.commands.len());
        assert_eq!(raw.commands, want_raw.selection.commands);
        assert_eq!(sel.commands, want.selection.commands, "yaw {yaw}");
        assert_eq!(sel.data, want.selection.data, "yaw {yaw}");
        assert_eq!(sel.counters, want.selection.counters, "yaw {yaw}");
    }
    assert!(most > 256, "at most {most} commands: one scan chunk");
}

/// The front-to-back sort on the GPU over lists that span many workgroups and bitonic steps
/// (`tiny`'s quadtree of 8-tree leaves at medium range: some 280 commands uncoalesced, 512 pair
/// slots, and the coalesced list), coalescing off and on, two yaws: the sorted commands, data and
/// counters equal the reference's exactly (keys within their `judge::run_key_bounds`, counted), keys
/// non-decreasing, and the sort moved commands. Mutation-checked in the report of issue 13.
#[test]
fn gpu_front_to_back_spans_workgroups() {
    let Some(ctx) = gpu_context() else {
        eprintln!("hier_select front-to-back: no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    let scene = builtin::by_name("tiny").unwrap();
    let base = Params {
        command_order: CommandOrder::FrontToBack as u32,
        ..forestlod_tests::tiny_hierarchy_params(Mode::Quadtree)
    };
    let prepared = prepare(scene, &base).unwrap();
    let h = prepared.hierarchy.as_ref().unwrap();
    let g = &prepared.geometry;
    let mut gpu = SelectionChain::gpu(ctx, &prepared).unwrap();
    let (mut ambiguous, mut moved, mut most) = (0, 0, 0);
    let mut max_of_bound = 0.0f64;
    for coalesce in [Coalesce::Off, Coalesce::On] {
        let p = Params {
            coalesce: coalesce as u32,
            ..base
        };
        for yaw in [0.0, 330.0] {
            let camera =
                forestlod_reference::cameras::named_camera("medium", &prepared.scene, yaw, 96, 72)
                    .unwrap();
            let u = ViewUniform::new(&camera, &p);
            let want = full_cut(h, &g.meshes, &g.billboard, &camera, &p);
            let sel = gpu.run(&camera, &p, Compaction::Stable).unwrap();
            let (codes, _) = gpu.read_codes_and_states().unwrap();
            assert_eq!(codes, want.codes, "{coalesce:?} yaw {yaw}: codes");
            let unsorted = full_resolve(
                h,
                codes,
                &g.meshes,
                &g.billboard,
                &u,
                coalesce,
                CommandOrder::Node,
            );
            let pairs = gpu.read_order_pairs(sel.commands.len()).unwrap();
            let raw = full_resolve(
                h,
                want.codes.clone(),
                &g.meshes,
                &g.billboard,
                &u,
                Coalesce::Off,
                CommandOrder::Node,
            );
            let bounds =
                run_key_bounds(&h.nodes, &raw.selection, unsorted.keys.len(), &u, coalesce);
            let a = check_order(
                &selection_of(&sel),
                &pairs,
                &unsorted.selection,
                &unsorted.keys,
                &bounds,
            )
            .map(|o| {
                max_of_bound = max_of_bound.max(o.max_of_bound);
                o.ambiguous
            })
            .unwrap_or_else(|e| panic!("{coalesce:?} yaw {yaw}: {e}"));
            if a == 0 {
                assert_eq!(
                    sel.commands, want.selection.commands,
                    "{coalesce:?} yaw {yaw}"
                );
                assert_eq!(sel.data, want.selection.data, "{coalesce:?} yaw {yaw}");
            }
            assert!(pairs.windows(2).all(|w| w[0] <= w[1]), "keys not sorted");
            ambiguous += a;
            moved += pairs
                .iter()
                .enumerate()
                .filter(|(i, (_, r))| *i as u32 != *r)
                .count();
            most = most.max(sel.commands.len());
            eprintln!(
                "GPU front-to-back on tiny, quadtree, medium, {coalesce:?}, yaw {yaw}: {} commands, {} moved so far, {a} ambiguous keys",
                sel.commands.len(),
                moved
            );
        }
    }
    eprintln!(
        "GPU front-to-back: {ambiguous} ambiguous keys in total (within their contraction bound, \
         the largest at {max_of_bound:.3} of it)"
    );
    assert!(
        most > 256,
        "at most {most} commands: the sort stayed in one workgroup"
    );
    assert!(moved > 0, "the sort moved nothing");
}

/// GPU frames on `tiny` (the quadtree, the octree and k-means; medium and close; dither-sequential and
/// alpha): `front-to-back` against `node` differs only at depth ties and, in `alpha`, where
/// blending meets the fade band; every differing pixel is classified
/// ([`forestlod_tests::classify_order_diffs`]), the test fails on an unclassified one and reports
/// the counts.
#[test]
fn gpu_front_to_back_frames_differ_only_at_ties_and_blending() {
    let Some(ctx) = gpu_context() else {
        eprintln!("hier_select front-to-back frames: no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    };
    let draw = gpu_draw(ctx);
    let scene = builtin::by_name("tiny").unwrap();
    let mut total = forestlod_tests::OrderDiffs::default();
    for mode in [Mode::Quadtree, Mode::Octree, Mode::Kmeans] {
        let base = forestlod_tests::tiny_hierarchy_params(mode);
        let prepared = prepare(scene.clone(), &base).unwrap();
        for (camera_name, yaw, camera) in
            forestlod_tests::small_poses(&prepared.scene, &[("medium", 0.0), ("close", 30.0)])
        {
            for fade in [FadeMode::DitherSequential, FadeMode::Alpha] {
                let node = Params {
                    fade_mode: fade as u32,
                    ..base
                };
                let ftb = Params {
                    command_order: CommandOrder::FrontToBack as u32,
                    ..node
                };
                let a = render_gpu(
                    ctx,
                    draw,
                    &prepared,
                    &camera,
                    &node,
                    StagesFromCpu::default(),
                )
                .unwrap()
                .images;
                let b = render_gpu(
                    ctx,
                    draw,
                    &prepared,
                    &camera,
                    &ftb,
                    StagesFromCpu::default(),
                )
                .unwrap()
                .images;
                let d = forestlod_tests::classify_order_diffs(&a, &b, fade == FadeMode::Alpha);
                eprintln!(
                    "GPU {mode:?} {camera_name} yaw {yaw} {fade:?}: front-to-back vs node {d:?}"
                );
                assert_eq!(
                    d.unclassified, 0,
                    "{mode:?} {camera_name} yaw {yaw} {fade:?}: {d:?}"
                );
                total.differing += d.differing;
                total.ties += d.ties;
                total.blend_order += d.blend_order;
            }
        }
    }
    eprintln!("GPU front-to-back frames: {total:?}");
}
