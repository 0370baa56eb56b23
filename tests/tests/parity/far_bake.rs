//! Parity of the GPU far bake (`gpu/src/far_bake.rs`, `gpu/src/shaders/far_bake.wgsl`) with the
//! reference (`reference/src/far_bake.rs`), issue 32 item 2: `tiny`'s octree (its procedural
//! species, textures with mips and real transparency) at cluster sizes 1, 2 and 4, both parent
//! rules. The GPU renders and reduces the leaves; the parents are the shared code on its leaf
//! cells (`forestlod_shared::far_bake`, module docs there), so they agree exactly when the
//! leaves do.
//!
//! Judged per leaf cell side (every cell, kept or dropped) and on the whole levels by the
//! stage's judge (`forestlod_harness::stage::{far_tally, judge_far_level}`, its tolerances
//! named there): where both twins cover a side alike (the same alpha byte), its sRGB bytes within
//! ±1 but for a few percent of the sides (lavapipe's 8-bit filter weights and uvs interpolated
//! from unsnapped vertices move a few texels by a few bytes; two leaves at one depth may swap a
//! pixel); a side whose coverage differs (a pixel kept on one twin only: the bake's edge and
//! alpha-cutoff ambiguities) is counted, with its alpha difference bounded, its colour not
//! judged. The counts and largest differences are printed; measured on `tiny` (cluster size 1, 2,
//! 4): equally covered sides beyond ±1 3.1 %, 1.6 %, 0.24 % (largest 7, 42, 14); coverage
//! differing on 12 %, 7.8 %, 1.7 % of the sides (largest alpha difference 16, 24, 28 bytes: 4-7
//! pixels); kept cells in one level only 0.6 %, 0.25 %, 0.5 %.

use forestlod_gpu::GpuFarBake;
use forestlod_harness::bridge::{far_bake_vertices, mip_levels};
use forestlod_harness::context::gpu_context;
use forestlod_harness::stage::{far_tally, judge_far_level};
use forestlod_reference::far_bake::{far_bake, leaf_cells, placed_trees};
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::builtin;
use forestlod_shared::far_bake::FarBakeVertex;
use forestlod_shared::{Hierarchy, Params, ParentRule, SIDE_COUNT};

fn tiny(cs: u32, rule: ParentRule) -> (Prepared, Params) {
    let params = Params {
        hierarchy: Hierarchy::Octree as u32,
        nodes_per_node: 8,
        cluster_size: cs,
        parent_rule: rule as u32,
        texture_size: 16,
        angle_count: 2,
        ..Params::default()
    };
    (
        prepare(builtin::tiny(), &params).expect("tiny prepares"),
        params,
    )
}

#[test]
fn gpu_far_bake_matches_the_reference() {
    let Some(ctx) = gpu_context() else { return };
    let bake = GpuFarBake::new(ctx).expect("far_bake.wgsl compiles");
    for cs in [1, 2, 4] {
        for rule in [ParentRule::Average, ParentRule::Composite] {
            let (prepared, params) = tiny(cs, rule);
            let h = prepared.hierarchy.as_ref().unwrap();
            let textures: Vec<_> = prepared.mesh_textures.iter().collect();
            let mesh = forestlod_gpu::upload_texture_array(ctx, "far mesh", &mip_levels(&textures))
                .expect("mesh textures upload");
            let lists = far_bake_vertices(&prepared);
            let refs: Vec<&[FarBakeVertex]> = lists.iter().map(Vec::as_slice).collect();
            let gpu = bake
                .far_bake(&h.nodes, &refs, &mesh, &params)
                .expect("the GPU far bake runs");
            let cpu = far_bake(
                h,
                &prepared.scene,
                &prepared.geometry,
                &prepared.mesh_textures,
                &params,
            )
            .unwrap();
            // Leaf sides, every cell.
            let leaves: Vec<usize> = (0..h.nodes.len())
                .filter(|&i| h.nodes[i].child_count == 0)
                .collect();
            let inputs: Vec<forestlod_gpu::FarLeaf<'_>> = leaves
                .iter()
                .map(|&i| forestlod_gpu::FarLeaf {
                    center: h.nodes[i].box_center,
                    extent: h.nodes[i].extent,
                    vertices: &lists[i],
                })
                .collect();
            let gpu_leaves = bake
                .leaf_cells(&mesh, &inputs, cs, params.alpha_cutoff)
                .unwrap();
            let mut pairs = Vec::new();
            for (&i, g) in leaves.iter().zip(&gpu_leaves) {
                let n = &h.nodes[i];
                let trees = placed_trees(h, &prepared.scene, &prepared.geometry, i);
                let r = leaf_cells(
                    n.box_center,
                    n.extent,
                    &trees,
                    &prepared.mesh_textures,
                    &params,
                );
                for (gc, rc) in g.iter().zip(&r) {
                    pairs.extend((0..SIDE_COUNT).map(|s| (rc[s], gc[s])));
                }
            }
            let leaf = far_tally(pairs).verdict();
            let level = judge_far_level(&cpu, &gpu);
            eprintln!(
                "far bake parity cs {cs} {rule:?}: {} leaves: {}; whole level: {}",
                leaves.len(),
                match &leaf {
                    Ok(s) | Err(s) => s,
                },
                match &level {
                    Ok((s, _)) | Err(s) => s,
                },
            );
            leaf.unwrap_or_else(|e| panic!("cs {cs} {rule:?} leaves: {e}"));
            level.unwrap_or_else(|e| panic!("cs {cs} {rule:?} level: {e}"));
        }
    }
}

/// A cluster size out of range is a clear error naming the field.
#[test]
fn gpu_far_bake_refuses_a_bad_cluster_size() {
    let Some(ctx) = gpu_context() else { return };
    let bake = GpuFarBake::new(ctx).expect("far_bake.wgsl compiles");
    let (prepared, params) = tiny(1, ParentRule::Average);
    let textures: Vec<_> = prepared.mesh_textures.iter().collect();
    let mesh =
        forestlod_gpu::upload_texture_array(ctx, "far mesh", &mip_levels(&textures)).unwrap();
    let e = bake.leaf_cells(&mesh, &[], 13, 0.5).unwrap_err();
    assert!(format!("{e}").contains("cluster_size"), "{e}");
    let h = prepared.hierarchy.as_ref().unwrap();
    let empty: Vec<&[FarBakeVertex]> = vec![&[]; h.nodes.len()];
    let e = bake
        .far_bake(
            &h.nodes,
            &empty,
            &mesh,
            &Params {
                cluster_size: 0,
                ..params
            },
        )
        .unwrap_err();
    assert!(format!("{e}").contains("cluster_size"), "{e}");
}
