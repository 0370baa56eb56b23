//! Properties of the `refine` stage (`reference/src/refine.rs`): per-tree culling of the selected
//! commands. Each property runs at least 256 random scenes, cameras and parameters; the image
//! tests render the same frames with and without refinement.

use forestlod_reference::pipeline::prepare;
use forestlod_reference::refine::refine;
use forestlod_reference::scene::builtin;
use forestlod_reference::select::{select, select_per_tree};
use forestlod_shared::{LOD_MESH, Params, TreeCull};
use forestlod_tests::{Packed, cameras, instances, params, property_config, with_threads};
use proptest::prelude::*;

proptest! {
    #![proptest_config(property_config())]

    /// Under `all` the (tree, LOD) pairs drawn are exactly the per-tree oracle's; under `lod0` the
    /// LOD0 pairs are the oracle's and the LOD1 commands are the batches' untouched. Refined
    /// lists are subsequences of their batch (never add, keep order). Mutation-checked: keeping
    /// trees that need the other LOD breaks the first assertion.
    #[test]
    fn refine_draws_the_per_tree_oracles_trees(trees in instances(300), camera in cameras(), p in params()) {
        let packed = Packed::new(trees, p.grid_size);
        let scales = packed.scales();
        let Packed { geometry, spheres, batches, .. } = packed;
        let oracle = select_per_tree(&spheres, &camera, &p);
        let n = batches.indirection.len() as u32;
        for mode in [TreeCull::Lod0, TreeCull::All] {
            let p = Params { tree_cull: mode as u32, ..p };
            let original = select(&batches.metas, &batches.scales, &geometry.meshes, &geometry.billboard, &camera, &p);
            let mut s = original.clone();
            let r = refine(&mut s, &batches.indirection, &spheres, &scales, &camera, &p);
            prop_assert_eq!(r.indirection.len() as u32, 3 * n);
            prop_assert_eq!(s.commands.len(), original.commands.len());
            let mut drawn = vec![[false; 2]; spheres.len()];
            for ((c, o), d) in s.commands.iter().zip(&original.commands).zip(&s.data) {
                prop_assert_eq!((c.base_vertex, c.index_count, c.first_index), (o.base_vertex, o.index_count, o.first_index));
                let batch = &batches.indirection[o.first_instance as usize..(o.first_instance + o.instance_count) as usize];
                let got = &r.indirection[c.first_instance as usize..(c.first_instance + c.instance_count) as usize];
                if mode.refines(d.lod) {
                    prop_assert_eq!(c.first_instance, d.lod * n + o.first_instance);
                    // A subsequence of the batch, in batch order.
                    let mut it = batch.iter();
                    for t in got {
                        prop_assert!(it.any(|b| b == t), "tree {} not in batch order", t);
                    }
                } else {
                    prop_assert_eq!(c.first_instance, 2 * n + o.first_instance);
                    prop_assert_eq!(got, batch);
                }
                for &t in got {
                    drawn[t as usize][d.lod as usize] = true;
                }
            }
            for (t, decision) in oracle.iter().enumerate() {
                let need = decision.needs();
                let lod0 = drawn[t][LOD_MESH as usize];
                prop_assert_eq!(lod0, need.lod0, "tree {} LOD0, mode {:?}", t, mode);
                if mode == TreeCull::All {
                    prop_assert_eq!(drawn[t][1], need.lod1, "tree {} LOD1", t);
                } else {
                    // Unrefined LOD1 commands still cover every tree that needs LOD1.
                    prop_assert!(drawn[t][1] || !need.lod1, "tree {} LOD1 missing", t);
                }
            }
        }
    }

    /// Identical output with 1 and 2 rayon threads.
    #[test]
    fn refine_is_thread_count_independent(trees in instances(300), camera in cameras(), p in params()) {
        let packed = Packed::new(trees, p.grid_size);
        let scales = packed.scales();
        let Packed { geometry, spheres, batches, .. } = packed;
        let p = Params { tree_cull: TreeCull::All as u32, ..p };
        let run = || {
            let mut s = select(&batches.metas, &batches.scales, &geometry.meshes, &geometry.billboard, &camera, &p);
            let r = refine(&mut s, &batches.indirection, &spheres, &scales, &camera, &p);
            (s, r)
        };
        prop_assert_eq!(with_threads(1, run), with_threads(2, run));
    }
}

/// Refinement changes the work, not the pixels: the fade is per fragment and a tree's fragments
/// lie in its bounding sphere's view interval, so a tree dropped for not needing a LOD would have
/// had every fragment of that LOD discarded anyway, and one outside the view has none. Colour,
/// depth and LOD ids are bit-identical with every `tree_cull` mode, on the golden cameras of
/// `tiny` at two grid sizes; the work (triangles submitted) drops.
#[test]
fn refined_frames_equal_unrefined_frames_and_cost_less() {
    for (grid, camera_name, yaw) in [
        (50.0, "medium", 0.0),
        (50.0, "close", 30.0),
        (100.0, "medium", 330.0),
        (100.0, "close", 0.0),
    ] {
        let scene = builtin::by_name("tiny").unwrap();
        let base = Params {
            grid_size: grid,
            lod1_transition: 120.0,
            fade_width: 40.0,
            texture_size: 32,
            ..Params::default()
        };
        let prepared = prepare(scene, &base).unwrap();
        let camera =
            forestlod_reference::cameras::named_camera(camera_name, &prepared.scene, yaw, 96, 72)
                .unwrap();
        let render = |mode: TreeCull| {
            let p = Params {
                tree_cull: mode as u32,
                ..base
            };
            prepared.render(&camera, &p).unwrap()
        };
        let none = render(TreeCull::None);
        assert!(none.refined.is_none());
        for mode in [TreeCull::Lod0, TreeCull::All] {
            let f = render(mode);
            let (a, b) = (&none.drawn.target, &f.drawn.target);
            assert!(
                a.color() == b.color(),
                "{camera_name} g={grid} {mode:?}: colour differs"
            );
            assert!(
                a.aux() == b.aux(),
                "{camera_name} g={grid} {mode:?}: LOD ids differ"
            );
            let depth_equal = a
                .depth()
                .iter()
                .zip(b.depth())
                .all(|(x, y)| x.to_bits() == y.to_bits());
            assert!(
                depth_equal,
                "{camera_name} g={grid} {mode:?}: depth differs"
            );
            let (t0, t1) = (
                none.drawn.tree_stats.triangles_in,
                f.drawn.tree_stats.triangles_in,
            );
            let r = f.refined.as_ref().unwrap();
            println!(
                "{camera_name} yaw {yaw} g={grid} {mode:?}: triangles {t0} -> {t1}, trees tested {}, kept {}",
                r.trees_tested, r.trees_kept
            );
            assert!(t1 <= t0);
            if mode == TreeCull::All {
                assert!(t1 < t0, "{camera_name} g={grid}: refinement saved nothing");
            }
        }
    }
}
