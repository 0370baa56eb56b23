//! Properties of the far level's cut (issue 32 item 1, `forestlod_shared::far`,
//! `reference/src/hier_select.rs`): with `lod_levels = 3`, random scenes (up to 300 trees of
//! three meshes), cameras, hierarchies and far settings, on a far level with one cell per node
//! (`forestlod_tests::far_fixture`: the cut reads only the cell counts).
//!
//! - **Each visible tree is represented exactly once**: by a mesh and/or a billboard exactly as
//!   the per-tree oracle asks (the fade band's two LODs are one representation, blended), or by
//!   its node's far level, never both, never twice. A far tree lies wholly beyond `far_start`
//!   (the chain mesh → billboard → far is conservative per tree) and needs no mesh.
//! - Far nodes are emitted, visited, and no ancestor of theirs is emitted (the antichain).
//! - The cut is the same with 1 and 2 threads.

use forestlod_reference::frame::cut;
use forestlod_reference::hier_select::{FarCut, NODE_EMITTED};
use forestlod_reference::hierarchy::Hierarchy;
use forestlod_reference::select::select_per_tree;
use forestlod_shared::{
    Coalesce, FarLod, FarUniform, Hierarchy as Mode, LOD_FAR, NO_PARENT, Params, view_interval,
};
use forestlod_tests::far_fixture::synthetic_far_level;
use forestlod_tests::{Packed, cameras, instances, params, property_config, with_threads};
use proptest::prelude::*;

/// Every grouping a far level runs on (the grid by its depth-1 hierarchy).
const MODES: [Mode; 5] = [
    Mode::Grid,
    Mode::GridAabb,
    Mode::Quadtree,
    Mode::Octree,
    Mode::Kmeans,
];

/// Three LOD levels, a far start at or beyond the transition, a pixel threshold from 0 to 10⁶
/// (log-uniform), each far primitive, no coalescing (one far command per node).
fn far_params() -> impl Strategy<Value = Params> {
    (
        params(),
        2u32..24,
        0u32..9,
        0.0f32..4000.0,
        -1.0f32..6.0,
        0u32..3,
    )
        .prop_map(|(p, npn, mcd, beyond, log_px, kind)| Params {
            lod_levels: 3,
            nodes_per_node: npn,
            max_cull_depth: mcd,
            grid_size: p.grid_size.min(400.0),
            far_start: p.lod1_transition + beyond,
            far_pixels: 10f32.powf(log_px),
            far_lod: kind,
            coalesce: Coalesce::Off as u32,
            ..p
        })
}

fn build(packed: &Packed, p: &Params, mode: Mode) -> Hierarchy {
    let p = Params {
        hierarchy: mode as u32,
        ..*p
    };
    Hierarchy::build(&packed.scene, &packed.geometry.meshes, &p)
        .expect("valid parameters build")
        .expect("a far level builds a hierarchy, the grid's too")
}

proptest! {
    #![proptest_config(property_config())]

    /// Exactly once, conservative, an antichain (module docs). Mutation-checked: a far node that
    /// also recursed (`DECISION_DRAW | NODE_FAR | NODE_RECURSE` in `far_code`) covers its trees
    /// twice; deciding far on the interval's far end (`hi` for `lo` in `far_code`) puts trees
    /// nearer than `far_start` into far nodes.
    #[test]
    fn each_visible_tree_is_represented_exactly_once(trees in instances(300), camera in cameras(), p in far_params()) {
        let packed = Packed::new(trees, p.grid_size);
        let oracle = select_per_tree(&packed.spheres, &camera, &p);
        let g = &packed.geometry;
        let u = FarUniform::new(&camera, &p);
        let kind = FarLod::from_id(p.far_lod).unwrap();
        let forward = camera.basis().forward.to_array();
        for mode in MODES {
            let h = build(&packed, &p, mode);
            let level = synthetic_far_level(&h, kind);
            let far = FarCut::new(Some(&level), g.far.first_index, &camera, &p);
            let (selection, trace) = cut(&h, &g.meshes, &g.billboard, far, &camera, &p);
            let states = &trace.cut.states;
            // Per tree: [mesh, billboard, far] representations.
            let mut covered = vec![[0u32; 3]; packed.spheres.len()];
            for (c, d) in selection.commands.iter().zip(&selection.data) {
                let n = &h.nodes[d.batch as usize];
                prop_assert!(states[d.batch as usize] & NODE_EMITTED != 0);
                let range = if d.lod == LOD_FAR {
                    let f = &level.nodes[d.batch as usize];
                    let first = if kind == FarLod::Hull { d.batch } else { f.cell_offset };
                    prop_assert_eq!(c.first_instance, first);
                    n.offset..n.offset + n.len
                } else {
                    c.first_instance..c.first_instance + c.instance_count
                };
                for &t in &h.indirection[range.start as usize..range.end as usize] {
                    covered[t as usize][d.lod.min(2) as usize] += 1;
                }
            }
            for (t, want) in oracle.iter().enumerate() {
                let need = want.needs();
                let [c0, c1, cf] = covered[t];
                prop_assert!(c0 <= 1 && c1 <= 1 && cf <= 1, "{:?}: tree {} represented {:?} times", mode, t, covered[t]);
                if cf == 1 {
                    prop_assert!(c0 == 0 && c1 == 0, "{:?}: tree {} both far and {:?}", mode, t, covered[t]);
                    prop_assert!(!need.lod0, "{:?}: far tree {} needs its mesh ({:?})", mode, t, want);
                    let (c, r) = packed.spheres[t];
                    let lo = view_interval(c, r, camera.eye, forward).lo;
                    let slack = 1e-5 * (lo.abs() + u.start.abs() + r);
                    prop_assert!(lo >= u.start - slack, "{:?}: far tree {} at view depth {} before far start {}", mode, t, lo, u.start);
                } else {
                    prop_assert!(!need.lod0 || c0 == 1, "{:?}: tree {} needs LOD0, uncovered ({:?})", mode, t, want);
                    prop_assert!(!need.lod1 || c1 == 1, "{:?}: tree {} needs LOD1, uncovered ({:?})", mode, t, want);
                }
            }
            for (i, n) in h.nodes.iter().enumerate() {
                if states[i] & NODE_EMITTED == 0 {
                    continue;
                }
                let mut a = n.parent;
                while a != NO_PARENT {
                    prop_assert!(states[a as usize] & NODE_EMITTED == 0, "{:?}: {} and its ancestor {} both emitted", mode, i, a);
                    a = h.nodes[a as usize].parent;
                }
            }
        }
    }

    /// The same cut with 1 and 2 rayon threads.
    #[test]
    fn the_far_cut_is_thread_count_independent(trees in instances(300), camera in cameras(), p in far_params()) {
        let packed = Packed::new(trees, p.grid_size);
        let g = &packed.geometry;
        let kind = FarLod::from_id(p.far_lod).unwrap();
        for mode in [Mode::Grid, Mode::Octree, Mode::Quadtree] {
            let h = build(&packed, &p, mode);
            let level = synthetic_far_level(&h, kind);
            let run = || {
                let far = FarCut::new(Some(&level), g.far.first_index, &camera, &p);
                cut(&h, &g.meshes, &g.billboard, far, &camera, &p).0
            };
            prop_assert_eq!(with_threads(1, run), with_threads(2, run));
        }
    }
}

/// Without a far level (`lod_levels = 2`) a far level passed to the cut changes nothing, and a
/// node without cells never goes far.
#[test]
fn no_far_level_no_far_commands() {
    let trees = (0..200)
        .map(|i| forestlod_tests::tree_at_x(i as f32 * 40.0))
        .collect();
    let p = Params {
        lod_levels: 3,
        hierarchy: Mode::Octree as u32,
        far_start: 1000.0,
        far_pixels: 1e9,
        ..Params::default()
    };
    let packed = Packed::new(trees, p.grid_size);
    let g = &packed.geometry;
    let camera =
        forestlod_shared::Camera::look_at([-3000.0, 0.0, 50.0], [0.0, 0.0, 0.0], 60.0, 320, 180);
    let h = build(&packed, &p, Mode::Octree);
    let level = synthetic_far_level(&h, FarLod::OctantCube);
    let far_count = |p: &Params, level: &forestlod_shared::FarLevel| {
        let far = FarCut::new(Some(level), g.far.first_index, &camera, p);
        let (s, _) = cut(&h, &g.meshes, &g.billboard, far, &camera, p);
        s.data.iter().filter(|d| d.lod == LOD_FAR).count()
    };
    assert!(far_count(&p, &level) > 0, "the case goes far");
    let two = Params { lod_levels: 2, ..p };
    assert_eq!(far_count(&two, &level), 0);
    let mut empty = level.clone();
    for n in &mut empty.nodes {
        n.cell_count = 0;
    }
    assert_eq!(far_count(&p, &empty), 0);
}

proptest! {
    #![proptest_config(property_config())]

    /// A sprite's colour (G§2.3, `forestlod_shared::side_mix`): its weights are a partition of
    /// unity, each in [0, 1]; each channel of the mix lies between the three chosen sides'; on an
    /// axis the mix is that side's colour exactly. Mutation-checked: choosing the side by the
    /// opposite sign (`side_of(a, v_a < 0)`) fails the axis case; weights `|v_a|` left unnormalised
    /// fail the partition.
    #[test]
    fn sprite_weights_are_a_partition_and_exact_on_the_axes(
        v in prop::array::uniform3(-1.0f32..1.0),
        colours in prop::array::uniform6(any::<u32>()),
        axis in 0usize..3,
        positive in any::<bool>(),
    ) {
        use forestlod_shared::{side_mix, side_normal, side_of, side_weights, unpack_far_colour};
        let (w, sides) = side_weights(v);
        let sum: f32 = w.iter().sum();
        prop_assert!((sum - 1.0).abs() <= 4.0 * f32::EPSILON, "weights {:?} sum to {}", w, sum);
        prop_assert!(w.iter().all(|&x| (0.0..=1.0).contains(&x)));
        let mix = side_mix(&colours, v);
        for (ch, &m) in mix.iter().enumerate() {
            let vals: Vec<f32> = sides.iter().map(|&s| unpack_far_colour(colours[s as usize])[ch]).collect();
            let lo = vals.iter().cloned().fold(f32::INFINITY, f32::min);
            let hi = vals.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
            prop_assert!(m >= lo - 1e-6 && m <= hi + 1e-6, "channel {} {} outside [{}, {}]", ch, m, lo, hi);
        }
        let s = side_of(axis, positive);
        prop_assert_eq!(side_mix(&colours, side_normal(s)), unpack_far_colour(colours[s]));
    }
}
