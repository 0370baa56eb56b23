//! Scenario coverage (issue 15, part 4): every decision threshold of the reference's `select`,
//! `refine`, per-tree cull, hierarchy cut and `draw` (`forestlod_shared::coverage::ALL`: draw
//! distance, each frustum plane, the fade band's ends, the alpha cutoff, the dither, the
//! transition id, the cut's visits and recursion) must be *straddled* (both sides reached) by at
//! least one parity scenario or property case. The cases below are those the parity tests feed
//! to both backends (the reference's run of a case is what the GPU is compared with, so a side
//! the reference reaches in a case is a side the parity test compares), run on the reference
//! with the test-only counters of `forestlod_shared::coverage` (feature `coverage`, enabled for
//! this crate only).
//!
//! The test prints the table (threshold x case: `a/b` = times side one / side two was reached)
//! and writes it to `$CARGO_TARGET_TMPDIR/coverage.md`; the committed copy is
//! `experiments/results/coverage/README.md`. It runs in its own test binary so that no other test
//! records into the global counters while it runs.

use forestlod_reference::baselines::{proxies, render_primitive, render_vegetation, tree_spheres};
use forestlod_reference::batches::build_batches;
use forestlod_reference::cameras::named_camera;
use forestlod_reference::geometry::pack_geometry;
use forestlod_reference::hierarchy::Hierarchy as Tree;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::builtin;
use forestlod_reference::select::{select, select_per_tree};
use forestlod_shared::coverage::{self, ALL, Threshold};
use forestlod_shared::{Camera, FadeMode, Hierarchy, Params, TreeCull};
use forestlod_tests::scenarios::{
    golden_scenarios, named_views, refine_image_frames, tiny_and_crop_frames, tiny_params,
    unrefined_straddling_case,
};
use forestlod_tests::stage_cases::stage_cases;
use forestlod_tests::{
    Packed, cameras, far_plane_cases, instances, params, scene_of, small_poses, straddling_cameras,
    straddling_params,
};
use proptest::strategy::{Strategy, ValueTree};
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

/// Random cases of each property's strategy run here (a fixed seed; the properties run more:
/// `parity::select` 256 and 32 far-plane cases, `parity::hier_select` its own count).
const PROPERTY_CASES: u32 = 48;

/// A deterministic runner for the property sources.
fn runner() -> TestRunner {
    TestRunner::new_with_rng(
        Config::default(),
        TestRng::from_seed(RngAlgorithm::ChaCha, &[15; 32]),
    )
}

/// One case source and its counts, per threshold of [`ALL`].
struct Column {
    name: String,
    /// The one hierarchy mode every case of the column runs, where it has one (the per-mode
    /// requirements of [`MODE_ROWS`] read these columns).
    mode: Option<Hierarchy>,
    counts: Vec<(Threshold, [u64; 2])>,
}

fn record(name: &str, run: impl FnOnce()) -> Column {
    coverage::enable();
    run();
    Column {
        name: name.to_string(),
        mode: None,
        counts: coverage::disable(),
    }
}

fn record_mode(name: &str, mode: Hierarchy, run: impl FnOnce(Hierarchy)) -> Column {
    Column {
        mode: Some(mode),
        ..record(&format!("{name} ({})", mode.name()), || run(mode))
    }
}

/// The hierarchical modes, as `parity::hier_select::MODES`.
const HIER_MODES: [Hierarchy; 5] = [
    Hierarchy::GridAabb,
    Hierarchy::Quadtree,
    Hierarchy::Octree,
    Hierarchy::OctreeEuclidean,
    Hierarchy::Kmeans,
];

/// Every threshold of every mode (issue 36): per hierarchical mode, the cut's rows that its own
/// rule decides on, each of which a column running that mode alone must straddle. The rows every
/// mode shares (the node's decision on its two bounds, `CutCullSphereVsBox`) are one code path
/// and are required once, by the table. `grid-aabb` and `kmeans` are depth-1 (every node is a
/// root: always visited, none recurses) and have no row of their own; their columns must still
/// reach the cut. The quadtree's interior nodes always recurse; the octrees decide recursion on
/// LOD0, depth, partial visibility and (Euclidean) distance.
const MODE_ROWS: &[(Hierarchy, &[Threshold])] = {
    use Threshold::*;
    &[
        (Hierarchy::GridAabb, &[]),
        (Hierarchy::Quadtree, &[CutVisited]),
        (
            Hierarchy::Octree,
            &[
                CutVisited,
                CutRecurse,
                CutCullDepth,
                CutPartial,
                CutPartialCentre,
            ],
        ),
        (
            Hierarchy::OctreeEuclidean,
            &[
                CutVisited,
                CutRecurse,
                CutCullDepth,
                CutPartial,
                CutPartialCentre,
                CutEuclidean,
            ],
        ),
        (Hierarchy::Kmeans, &[]),
    ]
};

fn golden_frames() {
    let tiny = builtin::tiny();
    for s in golden_scenarios() {
        let p = prepare(tiny.clone(), &s.params).expect("prepare");
        p.render(&s.camera(&tiny), &s.params).expect("render");
    }
}

fn refine_and_cull_views() {
    let tiny = builtin::tiny();
    let params = tiny_params(FadeMode::Alpha);
    let p = prepare(tiny.clone(), &params).expect("prepare");
    for v in named_views(&tiny, &params, 96) {
        let params = Params {
            tree_cull: TreeCull::All as u32,
            ..v.params
        };
        p.select_refined(&v.camera, &params);
        select_per_tree(&p.tree_spheres, &v.camera, &params);
    }
}

fn hierarchy_frames() {
    let tiny = builtin::tiny();
    for mode in [Hierarchy::Quadtree, Hierarchy::Octree] {
        let params = Params {
            hierarchy: mode as u32,
            ..tiny_params(FadeMode::DitherSequential)
        };
        let p = prepare(tiny.clone(), &params).expect("prepare");
        for camera in ["medium", "close", "far"] {
            let c = named_camera(camera, &tiny, 0.0, 96, 96).expect("camera");
            p.hier_select(&c, &params).expect("a hierarchy");
        }
    }
}

fn monotone_sweep() {
    let params = Params {
        grid_size: 50.0,
        lod1_transition: 400.0,
        fade_width: 80.0,
        draw_distance: 900.0,
        lod_levels: 2,
        texture_size: 16,
        angle_count: 2,
        ..Params::default()
    };
    let p = prepare(builtin::single(), &params).expect("prepare");
    for step in 0..150u32 {
        let x = 2.0 + step as f32 * 8.0;
        let camera = Camera::look_at([-x, 0.3, 10.0], [0.0, 0.0, 8.0], 50.0, 64, 64);
        p.select(&camera, &params);
    }
}

fn tile_frames() {
    let scene = builtin::tiny();
    let params = tiny_params(FadeMode::DitherSequential);
    let camera = named_camera("medium", &scene, 0.0, 96, 96).expect("camera");
    let p = prepare(scene, &params).expect("prepare");
    for (x0, y0, w, h) in [
        (0, 0, 40, 80),
        (40, 0, 56, 80),
        (0, 80, 40, 16),
        (40, 80, 56, 16),
    ] {
        p.render(&camera.tile(x0, y0, w, h), &params)
            .expect("render");
    }
}

fn select_cases(
    strategy: impl Strategy<Value = (Vec<forestlod_reference::scene::Instance>, Camera, Params)>,
) {
    let mut runner = runner();
    for _ in 0..PROPERTY_CASES {
        let (trees, camera, p) = strategy.new_tree(&mut runner).expect("a case").current();
        let scene = scene_of(trees);
        let geometry = pack_geometry(&scene);
        let batches = build_batches(&scene, &geometry.meshes, p.grid_size).expect("batches");
        select(
            &batches.metas,
            &batches.scales,
            &geometry.meshes,
            &geometry.billboard,
            &camera,
            &p,
        );
    }
}

fn select_property_cases() {
    select_cases((instances(300), cameras(), params()));
}

fn far_plane_property_cases() {
    select_cases(far_plane_cases());
}

/// `parity::hier_select`'s property: its strategy, the cut alone, `mode` in every case (the
/// parity test draws one of [`HIER_MODES`] per case).
fn hier_property_cases(mode: Hierarchy) {
    let strategy = (instances(300), cameras(), params(), 2u32..24, 0u32..9);
    let mut runner = runner();
    for _ in 0..PROPERTY_CASES {
        let (trees, camera, p, npn, mcd) =
            strategy.new_tree(&mut runner).expect("a case").current();
        let p = Params {
            nodes_per_node: npn,
            max_cull_depth: mcd,
            grid_size: p.grid_size.min(400.0),
            hierarchy: mode as u32,
            ..p
        };
        let packed = Packed::new(trees, p.grid_size);
        let g = &packed.geometry;
        let h = Tree::build(&packed.scene, &g.meshes, &p)
            .expect("a hierarchy")
            .expect("a hierarchical mode");
        forestlod_tests::full_cut(&h, &g.meshes, &g.billboard, &camera, &p);
    }
}

/// `parity::hier_select::gpu_cut_on_frustum_straddling_boxes`' cases for `mode` (an octree).
fn straddling_cases(mode: Hierarchy) {
    let p = straddling_params(mode);
    let trees = forestlod_tests::tiny_card_trees();
    let packed = Packed::new(trees, p.grid_size);
    let g = &packed.geometry;
    let h = Tree::build(&packed.scene, &g.meshes, &p)
        .expect("a hierarchy")
        .expect("a hierarchical mode");
    for (_, camera) in straddling_cameras(&h.nodes, &p, 96, 72, 16) {
        forestlod_tests::full_cut(&h, &g.meshes, &g.billboard, &camera, &p);
    }
}

/// `parity::every_stage`'s walk (`forestlod_tests::stage_cases`): every case's frame on the
/// reference (the GPU test runs each targeted stage alone on the reference's input of it).
fn walk_frames() {
    for case in stage_cases() {
        let scene = forestlod_tests::stage_cases::scene(case.scene);
        let p = prepare(scene, &case.params).expect("prepare");
        let (_, _, camera) = small_poses(&p.scene, &[("medium", 0.0)]).remove(0);
        p.render(&camera, &case.params).expect("render");
    }
}

/// The image frames of `parity::refine` (`tree_cull` `lod0` and `all`, as `refine::MODES`; the
/// draw distance pulled in to 150 m and to 300 m, the transition to 120 m) and `parity::baselines`
/// (the Vegetation and Primitive baselines; the draw distance 300 m): `tiny`'s frames only. Mirrors each test's own frames and modes exactly (issue 36: this source used to run
/// both lists with `none` and `all`, which claimed for `parity::refine` a `tree_cull = none`
/// frame it never compares).
fn refine_and_baseline_images() {
    let p = tiny_params(FadeMode::Alpha);
    let refine = refine_image_frames();
    let (prepared, frames) = refine;
    for f in frames.iter().filter(|f| f.prepared_key == 0) {
        for tree_cull in [TreeCull::Lod0, TreeCull::All] {
            let params = Params {
                tree_cull: tree_cull as u32,
                ..f.params
            };
            prepared[f.prepared_key]
                .render(&f.camera, &params)
                .expect("render");
        }
    }
    // `parity::baselines` judges the Vegetation and Primitive baselines there, not our pipeline
    // (issue 36: this source used to render ours, claiming a `tree_cull = none` frame of the draw
    // stage at 300 m that no GPU test compared).
    let (prepared, frames) = tiny_and_crop_frames(&[(
        "draw-distance-300",
        Params {
            draw_distance: 300.0,
            ..p
        },
    )]);
    for f in frames.iter().filter(|f| f.prepared_key == 0) {
        let pr = &prepared[f.prepared_key];
        let spheres = tree_spheres(&pr.scene, &pr.geometry.meshes);
        render_vegetation(pr, &spheres, &f.camera, &f.params);
        let proxy_list = proxies(pr, f.params.alpha_cutoff);
        render_primitive(pr, &spheres, &proxy_list, &f.camera, &f.params);
    }
}

/// `parity::draw::unrefined_mesh_batches_straddling_the_draw_distance`.
fn unrefined_straddling() {
    let (prepared, camera, params) = unrefined_straddling_case();
    prepared.render(&camera, &params).expect("render");
}

fn table(columns: &[Column]) -> String {
    let mut out = String::from("| threshold | sides |");
    for c in columns {
        out.push_str(&format!(" {} |", c.name));
    }
    out.push_str(" straddled by |\n|---|---|");
    out.push_str(&"---|".repeat(columns.len() + 1));
    out.push('\n');
    for (i, &t) in ALL.iter().enumerate() {
        let (name, a, b) = t.sides();
        out.push_str(&format!("| {name} | {a} / {b} |"));
        let mut by = Vec::new();
        for c in columns {
            let [x, y] = c.counts[i].1;
            out.push_str(&if x == 0 && y == 0 {
                " – |".to_string()
            } else {
                format!(" {x}/{y} |")
            });
            if x > 0 && y > 0 {
                by.push(c.name.as_str());
            }
        }
        out.push_str(&format!(
            " {} |\n",
            if by.is_empty() {
                "**none**".to_string()
            } else {
                by.join(", ")
            }
        ));
    }
    out
}

/// `parity::occlusion`'s frames (issue 31): the crop at tree height, `single` and a three-frame
/// `two-phase` path, a dithered fade mode and `alpha` (the grid configuration; the parity test
/// runs `refine` and the octree on the same views too).
fn occlusion_frames() {
    use forestlod_shared::Occlusion;
    let scene = forestlod_tests::scenarios::cropped_synthetic(300.0);
    let base = forestlod_tests::scenarios::occlusion_params(FadeMode::DitherSequential);
    let p = prepare(scene.clone(), &base).expect("prepare");
    for fade in [FadeMode::DitherSequential, FadeMode::Alpha] {
        for mode in [Occlusion::Single, Occlusion::TwoPhase] {
            let params = Params {
                fade_mode: fade as u32,
                occlusion: mode as u32,
                ..base
            };
            let mut history = Vec::new();
            for camera in
                forestlod_tests::scenarios::occlusion_path(&scene, (120.0, 25.0), (96, 72), 3)
            {
                let f = p
                    .render_with_history(&camera, &params, &history)
                    .expect("render");
                history = f.occlusion.expect("occlusion ran").visible;
            }
        }
    }
}

/// `parity::blend`'s frames (issue 30, G§4: texture-space noise, per-tree progress).
fn blend_frames() {
    for s in forestlod_tests::scenarios::blend_scenarios() {
        let p = prepare(s.scene(), &s.params).expect("prepare");
        p.render(&s.camera(&p.scene), &s.params).expect("render");
    }
}

#[test]
fn every_threshold_is_straddled_by_a_parity_case() {
    let columns = vec![
        record("parity::draw goldens", golden_frames),
        record(
            "parity::refine + baselines (cull) views",
            refine_and_cull_views,
        ),
        record("parity::hier_select frames", hierarchy_frames),
        record("metamorphic monotone", monotone_sweep),
        record("metamorphic tiles", tile_frames),
        record("parity::select property", select_property_cases),
        record("parity::select far plane", far_plane_property_cases),
        record(
            "parity::refine + baselines images",
            refine_and_baseline_images,
        ),
        record("parity::every_stage walk", walk_frames),
        record("parity::draw unrefined straddling", unrefined_straddling),
        record("parity::blend frames", blend_frames),
        record("parity::occlusion frames", occlusion_frames),
    ];
    let mut columns = columns;
    for mode in HIER_MODES {
        columns.push(record_mode(
            "parity::hier_select property",
            mode,
            hier_property_cases,
        ));
    }
    for mode in [Hierarchy::Octree, Hierarchy::OctreeEuclidean] {
        columns.push(record_mode(
            "parity::hier_select straddling",
            mode,
            straddling_cases,
        ));
    }
    let table = table(&columns);
    println!("{table}");
    let path = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("coverage.md");
    std::fs::write(&path, &table).expect("write the table");
    println!("table: {}", path.display());
    let missing: Vec<String> = ALL
        .iter()
        .enumerate()
        .filter(|&(i, _)| {
            !columns.iter().any(|c| {
                let [x, y] = c.counts[i].1;
                x > 0 && y > 0
            })
        })
        .map(|(_, t)| {
            let (name, a, b) = t.sides();
            format!("{name} ({a} / {b})")
        })
        .collect();
    assert!(
        missing.is_empty(),
        "thresholds no parity case straddles: {}",
        missing.join("; ")
    );
    // Every threshold of every hierarchical mode, by a column running that mode alone.
    let mut per_mode = Vec::new();
    for &(mode, rows) in MODE_ROWS {
        let reached = columns.iter().filter(|c| c.mode == Some(mode)).any(|c| {
            let [x, y] = c.counts[Threshold::CutVisited as usize].1;
            x + y > 0
        });
        if !reached {
            per_mode.push(format!("{}: no case reaches the cut", mode.name()));
        }
        for &t in rows {
            let straddled = columns.iter().filter(|c| c.mode == Some(mode)).any(|c| {
                let [x, y] = c.counts[t as usize].1;
                x > 0 && y > 0
            });
            if !straddled {
                per_mode.push(format!("{}: {}", mode.name(), t.sides().0));
            }
        }
    }
    assert!(
        per_mode.is_empty(),
        "thresholds of a mode no case of that mode straddles: {}",
        per_mode.join("; ")
    );
    // In this test, not a test of its own: the counters are global.
    cut_counters_count_what_they_name();
    select_counters_count_what_they_name();
}

/// `select`'s decision rows (and the per-tree oracle's) count what they name, recomputed from the
/// per-batch (per-tree) decisions
/// (`batch_decisions`): `SelectDrawDistance` every batch (culled by distance or not),
/// `SelectFrustum` every batch within the draw distance (culled by the frustum or not), the fade
/// rows every drawn batch (its LODs). Added for a survivor of issue 36's Rust sample (mutant 1705:
/// `SelectFrustum`'s side `==` flipped to `!=` in `reference/src/select.rs`: both sides were still
/// reached, so the straddle test passed with the labels swapped).
fn select_counters_count_what_they_name() {
    use forestlod_reference::select::{Decision, batch_decisions};
    let tiny = builtin::tiny();
    let params = tiny_params(FadeMode::DitherSequential);
    let p = prepare(tiny.clone(), &params).expect("prepare");
    let (mut distance, mut frustum, mut fade_end, mut fade_start) =
        ([0u64; 2], [0u64; 2], [0u64; 2], [0u64; 2]);
    let mut cull = [[0u64; 2]; 4];
    coverage::enable();
    for camera in ["medium", "close", "far"] {
        let c = named_camera(camera, &tiny, 0.0, 96, 96).expect("camera");
        // The per-tree oracle's rows (`Cull*`), from its own returned decisions (Rust sample
        // mutant 1710 swapped `CullFrustum`'s sides).
        for d in select_per_tree(&p.tree_spheres, &c, &params) {
            cull[0][usize::from(d == Decision::CulledDistance)] += 1;
            if d == Decision::CulledDistance {
                continue;
            }
            cull[1][usize::from(d == Decision::CulledFrustum)] += 1;
            if let Decision::Draw(n) = d {
                cull[2][usize::from(n.lod0)] += 1;
                cull[3][usize::from(n.lod1)] += 1;
            }
        }
        p.select(&c, &params);
        for d in batch_decisions(&p.batches.metas, &c, &params) {
            distance[usize::from(d == Decision::CulledDistance)] += 1;
            if d == Decision::CulledDistance {
                continue;
            }
            frustum[usize::from(d == Decision::CulledFrustum)] += 1;
            if let Decision::Draw(n) = d {
                fade_end[usize::from(n.lod0)] += 1;
                fade_start[usize::from(n.lod1)] += 1;
            }
        }
    }
    let counts = coverage::disable();
    let row = |t: Threshold| counts.iter().find(|(u, _)| *u == t).expect("a row").1;
    for (t, want) in [
        Threshold::SelectDrawDistance,
        Threshold::SelectFrustum,
        Threshold::SelectFadeEnd,
        Threshold::SelectFadeStart,
        Threshold::CullDrawDistance,
        Threshold::CullFrustum,
        Threshold::CullFadeEnd,
        Threshold::CullFadeStart,
    ]
    .into_iter()
    .zip(
        [distance, frustum, fade_end, fade_start]
            .into_iter()
            .chain(cull),
    ) {
        assert_eq!(
            row(t),
            want,
            "{} [{}, {}]",
            t.sides().0,
            t.sides().1,
            t.sides().2
        );
    }
    assert!(
        distance[1] > 0 && frustum[0] > 0 && frustum[1] > 0,
        "the cases reach both sides: distance {distance:?}, frustum {frustum:?}"
    );
}

/// The cut's counters count what their rows name, recomputed from the cut's own per-node codes
/// and states: `CutVisited` every node (split by the visited bit), `CutRecurse` exactly the
/// visited, drawn **interior** nodes (split by whether they recurse). A counter that also counts
/// other cases can fake a straddle: added for a survivor of `mutate` (issue 15, Rust mutant 616:
/// `n.child_count > 0` → `>= 0` in `reference/src/hier_select.rs` counted every drawn leaf as an
/// interior node drawn "as one unit", and every test passed).
fn cut_counters_count_what_they_name() {
    use forestlod_reference::scene::Instance;
    use forestlod_shared::{DECISION_DRAW, DECISION_KIND_MASK, NODE_VISITED, code_recurses};
    let tiny = builtin::tiny();
    let (mut visited, mut recurse, mut drawn_leaves, mut drawn_one_child) =
        ([0u64; 2], [0u64; 2], 0u64, 0u64);
    // A stand of three trees and one tree 60 m east, in leaves of at most 2 (the least
    // `nodes_per_node`), seen from 30 m: the octree's stand octant halves three times before its
    // trees part, a chain of interior nodes of **one** child each, which `CutRecurse` must count
    // like any interior node. Issue 36, Rust mutant 1313 (`n.child_count > 0` -> `> 1` in
    // `reference/src/hier_select.rs`): `tiny`'s cuts below have no one-child node, so the recount
    // passed.
    let tree = |x: f32, y: f32| Instance {
        position: [x, y, 0.0],
        yaw: 0.0,
        scale: 1.0,
        mesh: 0,
    };
    let stand = scene_of(vec![
        tree(0.0, 0.0),
        tree(2.0, 0.0),
        tree(0.0, 2.0),
        tree(60.0, 0.0),
    ]);
    let stand_camera = Camera::look_at([-30.0, 1.0, 10.0], [10.0, 1.0, 4.0], 60.0, 96, 96);
    coverage::enable();
    // `hierarchy_frames`' cases, then the stand's, each recomputed from its own cut.
    for mode in [Hierarchy::Quadtree, Hierarchy::Octree] {
        let params = Params {
            hierarchy: mode as u32,
            ..tiny_params(FadeMode::DitherSequential)
        };
        let stand_params = Params {
            nodes_per_node: 2,
            ..params
        };
        let tiny_cameras = ["medium", "close", "far"]
            .map(|camera| named_camera(camera, &tiny, 0.0, 96, 96).expect("camera"));
        for (scene, params, cameras) in [
            (&tiny, params, &tiny_cameras[..]),
            (&stand, stand_params, &[stand_camera][..]),
        ] {
            let p = prepare(scene.clone(), &params).expect("prepare");
            let h = p.hierarchy.as_ref().expect("a hierarchy");
            for c in cameras {
                let cut = p.hier_select(c, &params).expect("a hierarchy");
                for (i, n) in h.nodes.iter().enumerate() {
                    let (code, seen) = (cut.codes[i], cut.states[i] & NODE_VISITED != 0);
                    visited[usize::from(seen)] += 1;
                    if seen && code & DECISION_KIND_MASK == DECISION_DRAW {
                        if n.child_count > 0 {
                            recurse[usize::from(code_recurses(code))] += 1;
                            drawn_one_child += u64::from(n.child_count == 1);
                        } else {
                            drawn_leaves += 1;
                        }
                    }
                }
            }
        }
    }
    let counts = coverage::disable();
    let row = |t: Threshold| counts.iter().find(|(u, _)| *u == t).expect("a row").1;
    assert_eq!(
        row(Threshold::CutVisited),
        visited,
        "CutVisited: [not visited, visited]"
    );
    assert_eq!(
        row(Threshold::CutRecurse),
        recurse,
        "CutRecurse: [drawn interior nodes as one unit, recursing]"
    );
    // The cases reach what the check is about: interior nodes that recurse, and drawn leaves
    // (which `CutRecurse` must not count).
    assert!(
        recurse[1] > 0 && drawn_leaves > 0 && drawn_one_child > 0,
        "recursing interior nodes {}, drawn leaves {drawn_leaves}, drawn one-child interior \
         nodes {drawn_one_child}",
        recurse[1]
    );
}
