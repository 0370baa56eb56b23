//! Per-tree refinement of the selected commands: the `refine` stage, beyond the thesis. The CPU
//! twin of `gpu/src/shaders/refine.wgsl`, shader-shaped on purpose: [`refine_command`] is the body
//! of one workgroup (one command slot), [`refine`] the dispatch.
//!
//! ## Why
//! Grouped selection (E§3.5, §4.3) decides per batch, so a command draws every tree of its batch.
//! Where a batch only touches the view, or straddles the fade band, most of its trees are drawn
//! for nothing: at 10x density with 500 m cells, `camera360` measured 145k (medium) and 488k
//! (close) trees drawn outside the view and 28k–113k in a LOD they do not need
//! (`experiments/results/README.md`), which is why grouped LOD lost to per-tree culling there.
//! The thesis lists tighter culling as future work (E§7). `refine` keeps the O(batches) selection
//! and adds a per-tree test only for the trees of the commands it is asked to refine
//! ([`TreeCull`]): `lod0` refines the mesh commands (near trees: few, and each costs a mesh),
//! `all` every command (then the trees drawn are exactly the per-tree oracle's).
//!
//! ## Contract
//! Input: a [`Selection`] as `select` wrote it (command `i` covers its batch's trees
//! `indirection[first_instance .. first_instance + instance_count]`), the batch indirection array
//! of `n` trees, every tree's bounding sphere ([`crate::scene::tree_sphere`]), camera, params.
//! Output: the commands rewritten in place, and an indirection array of `3n` entries:
//! - `[0, n)`: refined LOD0 lists, `[n, 2n)`: refined LOD1 lists. A refined command of LOD `L`
//!   whose batch starts at `off` keeps, **in batch order**, the trees whose own decision
//!   ([`SelectUniform::decide`] of the tree's sphere: the selection rule, the per-tree oracle's)
//!   is drawn and needs LOD `L`, and that pass the draw stage's per-tree draw-distance test
//!   ([`tree_within_draw_distance`]); they go to `L·n + off ..`, and the command becomes
//!   `first_instance = L·n + off`, `instance_count = kept`.
//! - `[2n, 3n)`: a copy of the batch indirection; a command that is not refined points there
//!   (`first_instance = 2n + off`, count unchanged).
//!
//! Commands are never removed (one may end with no instances), so the command count, the order
//! and `base_vertex` stay the selection's, and the draw stage needs no change beyond reading the
//! refined array. With [`TreeCull::None`] the stage does not run.
//!
//! ## Invariants (tested in `tests/tests/properties/refine_properties.rs` and `parity_refine.rs`)
//! - **Exact under `all`**: the (tree, LOD) pairs drawn equal the per-tree oracle's
//!   ([`crate::select::select_per_tree`]): selection is conservative, so no tree the oracle draws
//!   is in a culled batch.
//! - **Never adds**: a refined command's trees are a subsequence of its batch's.
//! - **Deterministic**: identical output for any thread count (commands are refined in parallel,
//!   each writing only its own range).

use forestlod_shared::{Camera, Params, TreeCull, coverage};
use rayon::prelude::*;

use crate::select::{Decision, SelectUniform, Selection, tree_within_draw_distance};

/// What `refine` produced for one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Refined {
    /// The `3n`-entry indirection the rewritten commands index (module docs).
    pub indirection: Vec<u32>,
    /// Trees tested one by one: the instances of the refined commands before refinement.
    pub trees_tested: u64,
    /// Trees kept by the refined commands.
    pub trees_kept: u64,
}

/// One workgroup: refines command `command` of `selection` in place, writing its kept trees into
/// `out` (the command's own range of the `3n` array, module docs). Returns `(tested, kept)`.
///
/// `band` is the command's band at unit scale (its `CommandData`'s); each tree decides on it
/// scaled by its own scale (`scales`, issue 29's per-tree band: the band itself under
/// `distance`).
#[allow(clippy::too_many_arguments)]
pub fn refine_command(
    u: &SelectUniform,
    mode: TreeCull,
    lod: u32,
    band: [f32; 2],
    command: &mut forestlod_shared::DrawCommand,
    batch_indirection: &[u32],
    (spheres, scales): (&[([f32; 3], f32)], &[f32]),
    out: &mut [u32],
) -> (u64, u64) {
    let n = batch_indirection.len() as u32;
    let off = command.first_instance;
    if !mode.refines(lod) {
        command.first_instance = 2 * n + off;
        return (0, 0);
    }
    let trees = &batch_indirection[off as usize..(off + command.instance_count) as usize];
    let mut kept = 0usize;
    for &tree in trees {
        let (center, radius) = spheres[tree as usize];
        let s = scales[tree as usize];
        let needed = match u
            .with_band(u.group_band(band, [s, s]))
            .decide(center, radius)
        {
            Decision::Draw(needs) => {
                if lod == forestlod_shared::LOD_MESH {
                    needs.lod0
                } else {
                    needs.lod1
                }
            }
            _ => false,
        };
        let kept_here = needed && tree_within_draw_distance(u, center);
        if coverage::enabled() {
            use coverage::{Threshold::*, hit};
            hit(RefineNeeded, needed);
            if needed {
                hit(RefineDrawDistance, kept_here);
            }
        }
        if kept_here {
            out[kept] = tree;
            kept += 1;
        }
    }
    let tested = command.instance_count as u64;
    command.first_instance = lod * n + off;
    command.instance_count = kept as u32;
    (tested, kept as u64)
}

/// Refines every command of `selection` in place (module docs). `params.tree_cull` must be valid;
/// with [`TreeCull::None`] the selection is left alone and the batch indirection returned as is
/// (so the draw stage reads the same trees either way).
pub fn refine(
    selection: &mut Selection,
    batch_indirection: &[u32],
    spheres: &[([f32; 3], f32)],
    scales: &[f32],
    camera: &Camera,
    params: &Params,
) -> Refined {
    assert_eq!(spheres.len(), scales.len(), "one scale per tree");
    let mode = params
        .tree_culling()
        .expect("parameters are validated before refine");
    if mode == TreeCull::None {
        return Refined {
            indirection: batch_indirection.to_vec(),
            ..Refined::default()
        };
    }
    let u = SelectUniform::new(camera, params);
    let n = batch_indirection.len();
    let mut indirection = vec![0u32; 3 * n];
    indirection[2 * n..].copy_from_slice(batch_indirection);
    // Each command writes only `L·n + off .. + len`, disjoint for distinct (batch, LOD) pairs:
    // hand every command its own scratch list and copy in command order (deterministic).
    let results: Vec<(u64, u64, Vec<u32>)> = selection
        .commands
        .par_iter_mut()
        .zip(selection.data.par_iter())
        .map(|(command, data)| {
            let mut out = vec![0u32; command.instance_count as usize];
            let (tested, kept) = refine_command(
                &u,
                mode,
                data.lod,
                [data.fade_start, data.fade_end],
                command,
                batch_indirection,
                (spheres, scales),
                &mut out,
            );
            out.truncate(kept as usize);
            (tested, kept, out)
        })
        .collect();
    let mut refined = Refined::default();
    for (command, (tested, kept, out)) in selection.commands.iter().zip(results) {
        refined.trees_tested += tested;
        refined.trees_kept += kept;
        // Unrefined commands kept nothing (`out` is empty) and point into the copy.
        let start = command.first_instance as usize;
        indirection[start..start + out.len()].copy_from_slice(&out);
    }
    refined.indirection = indirection;
    refined
}
