//! Properties of command coalescing (`reference/src/coalesce.rs`, issue 13) on the hierarchical
//! cut: 256 random scenes (up to 300 trees of three meshes), cameras and parameters
//! (`nodes_per_node` 2..24, `max_cull_depth` 0..9), every hierarchical mode. The frames with
//! coalescing (the default) are checked against the grid's in `hierarchy_properties`
//! (`hierarchy_frames_equal_grid_frames`) and on the GPU in `parity::hier_select`.

use forestlod_reference::coalesce::coalesce;
use forestlod_reference::hierarchy::Hierarchy;
use forestlod_reference::select::Selection;
use forestlod_shared::{
    COMMAND_SHIFT, Coalesce, Hierarchy as Mode, LOD_MESH, Params, continues_run,
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
    (params(), 2u32..24, 0u32..9).prop_map(|(p, npn, mcd)| Params {
        nodes_per_node: npn,
        max_cull_depth: mcd,
        grid_size: p.grid_size.min(400.0),
        ..p
    })
}

/// The draws of a selection in submission order: per instance slot, (tree slot in the
/// indirection, LOD, fading flag, mesh, first index, index count).
fn draws(s: &Selection) -> Vec<(u32, u32, u32, u32, u32, u32)> {
    let mut out = Vec::new();
    for (c, d) in s.commands.iter().zip(&s.data) {
        for i in c.first_instance..c.first_instance + c.instance_count {
            out.push((i, d.lod, d.fading, d.mesh, c.first_index, c.index_count));
        }
    }
    out
}

proptest! {
    #![proptest_config(property_config())]

    /// Coalescing draws exactly what the uncoalesced cut draws, in the same order (so the same
    /// (instance, LOD) multiset and the same pixels); its runs are maximal (no command continues
    /// its predecessor); ranges of one LOD never overlap; `base_vertex` numbers the commands; each
    /// command's data is its first node's; the counters count the merged commands; `off` is the
    /// identity. Mutation-checked: `continues_run` without the fading comparison (merges a
    /// fading LOD0 command into a plain one), without the contiguity test, the run's count set to
    /// its last command's, and `lod0_commands` left uncounted each fail it.
    #[test]
    fn coalesced_commands_draw_exactly_the_uncoalesced(trees in instances(300), camera in cameras(), p in hier_params()) {
        let packed = Packed::new(trees, p.grid_size);
        let g = &packed.geometry;
        let n = packed.spheres.len();
        for mode in MODES {
            let p = Params { hierarchy: mode as u32, ..p };
            let h = Hierarchy::build(&packed.scene, &g.meshes, &p).unwrap().unwrap();
            let off = Params { coalesce: Coalesce::Off as u32, ..p };
            let raw = full_cut(&h, &g.meshes, &g.billboard, &camera, &off).selection;
            let on = Params { coalesce: Coalesce::On as u32, ..p };
            let merged = full_cut(&h, &g.meshes, &g.billboard, &camera, &on).selection;
            prop_assert_eq!(&coalesce(&raw, Coalesce::Off), &raw, "{:?}: off is not the identity", mode);
            prop_assert_eq!(&merged, &coalesce(&raw, Coalesce::On));
            prop_assert_eq!(draws(&merged), draws(&raw), "{:?}: the draws differ", mode);
            prop_assert!(merged.commands.len() <= raw.commands.len());
            let mut covered = vec![[0u32; 2]; n];
            for (k, (c, d)) in merged.commands.iter().zip(&merged.data).enumerate() {
                prop_assert_eq!(c.base_vertex, (k as i32) << COMMAND_SHIFT);
                if k > 0 {
                    prop_assert!(
                        !continues_run(&merged.commands[k - 1], &merged.data[k - 1], c, d),
                        "{:?}: command {} continues its predecessor: runs not maximal", mode, k
                    );
                }
                // The run's data is its first command's (same range start, same data).
                prop_assert!(
                    raw.commands.iter().zip(&raw.data).any(|(r, rd)| r.first_instance == c.first_instance && rd == d),
                    "{:?}: command {} has no head in the uncoalesced list", mode, k
                );
                for i in c.first_instance..c.first_instance + c.instance_count {
                    covered[i as usize][d.lod as usize] += 1;
                }
            }
            prop_assert!(covered.iter().all(|c| c[0] <= 1 && c[1] <= 1), "{:?}: overlapping commands", mode);
            let lod0 = merged.data.iter().filter(|d| d.lod == LOD_MESH).count() as u32;
            let instances: u32 = merged.commands.iter().map(|c| c.instance_count).sum();
            let want = forestlod_shared::SelectCounters {
                commands: merged.commands.len() as u32,
                lod0_commands: lod0,
                lod1_commands: merged.commands.len() as u32 - lod0,
                ..raw.counters
            };
            prop_assert_eq!(merged.counters, want);
            prop_assert_eq!(instances, raw.counters.instances);
        }
    }
}

/// On `tiny` with each hierarchy (small cells, so the cut emits many sibling nodes) coalescing
/// merges commands, draws the same instances, and leaves the frame bit-identical (every fade
/// mode but `alpha`, whose blending order is also unchanged: the instance order is the same).
/// Mutation-checked: `coalesce` ignoring `off` (it then merges either way) fails the count.
#[test]
fn coalescing_merges_commands_on_tiny_and_keeps_the_frame() {
    use forestlod_reference::pipeline::prepare;
    let scene = forestlod_reference::scene::builtin::by_name("tiny").unwrap();
    for mode in [Mode::Quadtree, Mode::Octree, Mode::Kmeans] {
        let off = Params {
            coalesce: Coalesce::Off as u32,
            ..forestlod_tests::tiny_hierarchy_params(mode)
        };
        let on = Params {
            coalesce: Coalesce::On as u32,
            ..off
        };
        let prepared = prepare(scene.clone(), &off).unwrap();
        for fade in forestlod_shared::FadeMode::ALL {
            let (off, on) = (
                Params {
                    fade_mode: fade as u32,
                    ..off
                },
                Params {
                    fade_mode: fade as u32,
                    ..on
                },
            );
            let camera =
                forestlod_reference::cameras::named_camera("medium", &prepared.scene, 0.0, 96, 72)
                    .unwrap();
            let a = prepared.render(&camera, &off).unwrap();
            let b = prepared.render(&camera, &on).unwrap();
            println!(
                "{mode:?} {fade:?}: commands {} -> {}, instances {} -> {}",
                a.selection.commands.len(),
                b.selection.commands.len(),
                a.selection.counters.instances,
                b.selection.counters.instances
            );
            assert!(b.selection.commands.len() < a.selection.commands.len());
            assert_eq!(draws(&a.selection), draws(&b.selection));
            let (ta, tb) = (&a.drawn.target, &b.drawn.target);
            assert!(ta.color() == tb.color(), "{mode:?} {fade:?}: colour");
            assert!(
                ta.depth()
                    .iter()
                    .zip(tb.depth())
                    .all(|(x, y)| x.to_bits() == y.to_bits()),
                "{mode:?} {fade:?}: depth"
            );
            assert!(ta.aux() == tb.aux(), "{mode:?} {fade:?}: LOD ids");
        }
    }
}
