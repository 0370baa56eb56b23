//! Parity of the GPU far bake (`gpu/src/far_bake.rs`, `gpu/src/shaders/far_bake.wgsl`) with the
//! reference (`reference/src/far_bake.rs`), issue 32 item 2: `tiny`'s octree (its procedural
//! species, textures with mips and real transparency) at cluster sizes 1, 2 and 4, both parent
//! rules. The GPU renders and reduces the leaves; the parents are the shared code on its leaf
//! cells (`forestlod_shared::far_bake`, module docs there), so they agree exactly when the
//! leaves do.
//!
//! Judged per leaf cell side (every cell, kept or dropped): the largest byte difference over
//! sRGB colour (where either covers) and alpha. Most sides agree within [`CHANNEL_TOLERANCE`]
//! (the issue's ±1); a side whose block has a pixel covered on one twin and not on the other
//! (an edge within the 8-bit subpixel ambiguity, a texel at the alpha cutoff sampled at uvs a
//! rounding apart: `gpu/src/bake.rs` module docs) moves alpha by 4 bytes (`255/64`) per pixel
//! and the mean colour by up to the pixel's difference over the covered count: those are
//! counted, must stay under [`FLIPPED_SHARE_MAX`] of the sides and within
//! [`FLIPPED_CHANNEL_MAX`], and the largest difference is printed. The kept-cell sets of the
//! whole levels are compared and their differences counted the same way.

use forestlod_gpu::GpuFarBake;
use forestlod_harness::bridge::mip_levels;
use forestlod_harness::context::gpu_context;
use forestlod_reference::far_bake::{PlacedTree, far_bake, leaf_cells, placed_trees};
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::builtin;
use forestlod_shared::far_bake::FarBakeVertex;
use forestlod_shared::{FarLevel, Hierarchy, Params, ParentRule, SIDE_COUNT};

/// Largest byte difference of a side both twins cover alike (every pixel of the block kept or
/// discarded by both): the issue's ±1; the sRGB encodes and `f32` sums round apart.
const CHANNEL_TOLERANCE: i32 = 1;

/// Largest byte difference of a side with a flipped pixel: alpha moves by 4 per pixel (one of
/// 64), colour by up to the flipped pixel's difference from the mean over the covered count.
/// Two flips in one block on a one-pixel-covered block could move colour by far more; measured
/// maxima are printed.
const FLIPPED_CHANNEL_MAX: i32 = 64;

/// Largest share of sides (of every leaf cell's six) that may differ beyond
/// [`CHANNEL_TOLERANCE`]: the share of blocks with an ambiguous pixel. Measured and printed.
const FLIPPED_SHARE_MAX: f64 = 0.05;

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

fn vertices(trees: &[PlacedTree]) -> Vec<FarBakeVertex> {
    trees
        .iter()
        .flat_map(|t| {
            t.triangles.iter().flat_map(move |tri| {
                tri.iter().map(move |&(position, uv)| FarBakeVertex {
                    position,
                    mesh: t.mesh,
                    uv,
                })
            })
        })
        .collect()
}

fn byte_diff(x: u32, y: u32) -> i32 {
    let b = |w: u32, k: u32| ((w >> (8 * k)) & 255) as i32;
    let alpha = (b(x, 3) - b(y, 3)).abs();
    if b(x, 3) == 0 && b(y, 3) == 0 {
        return alpha;
    }
    (0..3)
        .map(|k| (b(x, k) - b(y, k)).abs())
        .max()
        .unwrap()
        .max(alpha)
}

fn gpu_level(
    bake: &GpuFarBake<'_>,
    prepared: &Prepared,
    params: &Params,
    mesh: &wgpu::Texture,
) -> (FarLevel, Vec<Vec<FarBakeVertex>>) {
    let h = prepared.hierarchy.as_ref().expect("an octree");
    let lists: Vec<Vec<FarBakeVertex>> = (0..h.nodes.len())
        .map(|i| {
            if h.nodes[i].child_count == 0 {
                vertices(&placed_trees(h, &prepared.scene, &prepared.geometry, i))
            } else {
                Vec::new()
            }
        })
        .collect();
    let refs: Vec<&[FarBakeVertex]> = lists.iter().map(Vec::as_slice).collect();
    let level = bake
        .far_bake(&h.nodes, &refs, mesh, params)
        .expect("the GPU far bake runs");
    (level, lists)
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
            let (gpu, lists) = gpu_level(&bake, &prepared, &params, &mesh);
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
            let (mut sides, mut flipped, mut max_flipped) = (0usize, 0usize, 0i32);
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
                    for s in 0..SIDE_COUNT {
                        sides += 1;
                        let d = byte_diff(gc[s], rc[s]);
                        if d > CHANNEL_TOLERANCE {
                            flipped += 1;
                            max_flipped = max_flipped.max(d);
                            assert!(
                                d <= FLIPPED_CHANNEL_MAX,
                                "cs {cs} leaf {i}: gpu {:08x} reference {:08x}",
                                gc[s],
                                rc[s]
                            );
                        }
                    }
                }
            }
            let share = flipped as f64 / sides.max(1) as f64;
            // Whole levels: node by node, the kept cells' boxes.
            let mut set_diff = 0usize;
            for i in 0..h.nodes.len() {
                let cells = |l: &FarLevel| {
                    let f = l.nodes[i];
                    l.cells[f.cell_offset as usize..(f.cell_offset + f.cell_count) as usize]
                        .iter()
                        .map(|c| (c.center.map(f32::to_bits), c.extent.map(f32::to_bits)))
                        .collect::<Vec<_>>()
                };
                let (a, b) = (cells(&gpu), cells(&cpu));
                set_diff += a.iter().filter(|c| !b.contains(c)).count()
                    + b.iter().filter(|c| !a.contains(c)).count();
            }
            eprintln!(
                "far bake parity cs {cs} {rule:?}: {} leaves, {sides} leaf sides, {flipped} beyond ±{CHANNEL_TOLERANCE} (share {share:.4}, largest {max_flipped}); kept cells {} GPU / {} reference, {set_diff} in one set only",
                leaves.len(),
                gpu.cells.len(),
                cpu.cells.len()
            );
            assert!(share <= FLIPPED_SHARE_MAX, "share {share}");
            assert!(
                (set_diff as f64) <= FLIPPED_SHARE_MAX * cpu.cells.len().max(1) as f64,
                "{set_diff} kept cells differ"
            );
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
