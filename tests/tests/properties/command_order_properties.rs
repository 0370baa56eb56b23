//! Properties of the front-to-back command order (`reference/src/command_order.rs`, issue 13,
//! E§7 "distance-sorted commands") on the hierarchical cut: 256 random scenes (up to 300 trees of
//! three meshes), cameras and parameters (`nodes_per_node` 2..24, `max_cull_depth` 0..9), every
//! hierarchical mode, coalescing off and on. Frames sorted vs unsorted are checked in
//! `hierarchy_properties` (reference) and `parity::hier_select` (GPU); the GPU's order against
//! this one in `parity::hier_select`.

use forestlod_reference::hierarchy::Hierarchy;
use forestlod_shared::{
    COMMAND_SHIFT, Coalesce, CommandOrder, Hierarchy as Mode, Params, ViewUniform, view_interval,
};
use forestlod_tests::full_cut;
use forestlod_tests::{Packed, cameras, instances, params, property_config};
use proptest::prelude::*;

const MODES: [Mode; 5] = [
    Mode::GridAabb,
    Mode::Quadtree,
    Mode::Octree,
    Mode::OctreeEuclidean,
    Mode::Kmeans,
];

fn hier_params() -> impl Strategy<Value = Params> {
    (params(), 2u32..24, 0u32..9, any::<bool>()).prop_map(|(p, npn, mcd, merge)| Params {
        nodes_per_node: npn,
        max_cull_depth: mcd,
        grid_size: p.grid_size.min(400.0),
        coalesce: if merge { Coalesce::On } else { Coalesce::Off } as u32,
        ..p
    })
}

proptest! {
    #![proptest_config(property_config())]

    /// `front-to-back` is a permutation of the `node` list (every command and its data once,
    /// `base_vertex` renumbered, counters unchanged); its keys are the unsorted list's keys carried
    /// along, non-decreasing, with equal keys in their unsorted order (so the order is the total
    /// `(key, position)` order); `node` leaves the coalesced list as it is (the keys are computed,
    /// the order is not touched); and every key is a lower bound of the view depth of every tree
    /// the command draws (each tree's computed sphere interval starts at or beyond it), which is
    /// what makes it a front-to-back key. Mutation-checked: see the issue 13 report (sorting
    /// descending, ties by reversed position, a run's key taken from its head only, `node`
    /// sorting too, and the sphere-only lower end each fail it).
    #[test]
    fn front_to_back_is_a_sorted_permutation_of_node_order(trees in instances(300), camera in cameras(), p in hier_params()) {
        let packed = Packed::new(trees, p.grid_size);
        let g = &packed.geometry;
        let u = ViewUniform::new(&camera, &p);
        for mode in MODES {
            let p = Params { hierarchy: mode as u32, ..p };
            let h = Hierarchy::build(&packed.scene, &g.meshes, &p).unwrap().unwrap();
            let node = Params { command_order: CommandOrder::Node as u32, ..p };
            let unsorted = full_cut(&h, &g.meshes, &g.billboard, &camera, &node);
            let merged = {
                let raw = Params { coalesce: Coalesce::Off as u32, ..node };
                let raw = full_cut(&h, &g.meshes, &g.billboard, &camera, &raw).selection;
                forestlod_reference::coalesce::coalesce(&raw, p.coalescing().unwrap())
            };
            prop_assert_eq!(&unsorted.selection, &merged, "{:?}: node is not the coalesced list", mode);
            let ftb = Params { command_order: CommandOrder::FrontToBack as u32, ..p };
            let sorted = full_cut(&h, &g.meshes, &g.billboard, &camera, &ftb);
            let (u_sel, s_sel) = (&unsorted.selection, &sorted.selection);
            prop_assert_eq!(s_sel.commands.len(), u_sel.commands.len());
            prop_assert_eq!(s_sel.counters, u_sel.counters);
            prop_assert_eq!(unsorted.keys.len(), u_sel.commands.len());
            prop_assert_eq!(sorted.keys.len(), s_sel.commands.len());
            // Each sorted command's position in the unsorted list (commands of one LOD never
            // overlap, so (range, LOD) identifies one).
            let mut used = vec![false; u_sel.commands.len()];
            let mut last: Option<(u32, usize)> = None;
            for (i, (c, d)) in s_sel.commands.iter().zip(&s_sel.data).enumerate() {
                prop_assert_eq!(c.base_vertex, (i as i32) << COMMAND_SHIFT, "{:?}: base_vertex", mode);
                let at = u_sel.commands.iter().zip(&u_sel.data).position(|(uc, ud)| {
                    uc.first_instance == c.first_instance && uc.instance_count == c.instance_count && ud == d
                });
                let Some(at) = at else {
                    return Err(TestCaseError::fail(format!("{mode:?}: sorted command {i} is not in the node list")));
                };
                prop_assert_eq!(u_sel.commands[at].first_index, c.first_index);
                prop_assert_eq!(u_sel.commands[at].index_count, c.index_count);
                prop_assert!(!used[at], "{:?}: command {} twice", mode, at);
                used[at] = true;
                let key = sorted.keys[i];
                prop_assert_eq!(key, unsorted.keys[at], "{:?}: key of command {} not carried", mode, at);
                if let Some(prev) = last {
                    prop_assert!(prev < (key, at), "{:?}: slot {}: {:?} after {:?}", mode, i, (key, at), prev);
                }
                last = Some((key, at));
                // The key bounds every drawn tree's view depth from below.
                if key > 0 {
                    let near = f32::from_bits(key);
                    for &t in &h.indirection[c.first_instance as usize..(c.first_instance + c.instance_count) as usize] {
                        let (centre, radius) = packed.spheres[t as usize];
                        let lo = view_interval(centre, radius, u.eye, u.forward).lo;
                        prop_assert!(near <= lo, "{:?}: command {} key {} above tree {}'s near depth {}", mode, i, near, t, lo);
                    }
                }
            }
        }
    }
}

/// Reference frames on `tiny` (small cells: many commands; medium and close, both yaws),
/// the quadtree, the octree and k-means, coalescing on, in dither-sequential and alpha: `front-to-back`
/// draws the same pixels as `node` except at depth ties and, in `alpha`, where blending meets the
/// fade band; every differing pixel is classified ([`forestlod_tests::classify_order_diffs`]) and
/// the test fails on any unclassified one. It also checks that the sort changed the order.
#[test]
fn front_to_back_frames_differ_only_at_ties_and_blending() {
    use forestlod_harness::stage::images_of;
    use forestlod_reference::pipeline::prepare;
    use forestlod_shared::FadeMode;
    let scene = forestlod_reference::scene::builtin::by_name("tiny").unwrap();
    let mut reordered = 0;
    let mut total = forestlod_tests::OrderDiffs::default();
    for mode in [Mode::Quadtree, Mode::Octree, Mode::Kmeans] {
        let base = forestlod_tests::tiny_hierarchy_params(mode);
        let prepared = prepare(scene.clone(), &base).unwrap();
        for (camera_name, yaw, camera) in forestlod_tests::small_poses(
            &prepared.scene,
            &[("medium", 0.0), ("close", 30.0), ("close", 200.0)],
        ) {
            for fade in [FadeMode::DitherSequential, FadeMode::Alpha] {
                let node = Params {
                    fade_mode: fade as u32,
                    ..base
                };
                let ftb = Params {
                    command_order: CommandOrder::FrontToBack as u32,
                    ..node
                };
                let a = prepared.render(&camera, &node).unwrap();
                let b = prepared.render(&camera, &ftb).unwrap();
                if a.selection.commands != b.selection.commands {
                    reordered += 1;
                }
                let d = forestlod_tests::classify_order_diffs(
                    &images_of(&a.drawn.target),
                    &images_of(&b.drawn.target),
                    fade == FadeMode::Alpha,
                );
                println!(
                    "reference {mode:?} {camera_name} yaw {yaw} {fade:?}: {} commands, {d:?}",
                    b.selection.commands.len()
                );
                assert_eq!(
                    d.unclassified, 0,
                    "{mode:?} {camera_name} {yaw} {fade:?}: {d:?}"
                );
                total.differing += d.differing;
                total.ties += d.ties;
                total.blend_order += d.blend_order;
            }
        }
    }
    println!("reference front-to-back frames: {total:?}");
    assert!(reordered > 0, "the sort never changed the order");
}
