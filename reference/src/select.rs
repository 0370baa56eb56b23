//! Per-batch LOD selection and draw-command generation (E§3.5, §4.3; SPEC §5.4). The CPU twin of
//! `gpu/src/shaders/select.wgsl`, written shader-shaped on purpose: [`select_batch`] is the body of
//! one compute invocation, [`select`] is the dispatch plus the stable compaction.
//!
//! ## Contract
//! For each batch (E§4.3):
//! 1. project its bounding sphere onto the view direction, `[d - r, d + r]` (E§3.5, Fig. 3.8),
//!    widened by [`forestlod_shared::selection_margin`] for `f32` rounding;
//! 2. cull it when the interval lies wholly beyond the draw distance (`lo > draw_distance`), or
//!    when the sphere lies wholly outside one frustum plane;
//! 3. otherwise emit one command per LOD the interval needs ([`forestlod_shared::lod_needs`]):
//!    LOD0 when some point is nearer than the end of the fade band, LOD1 when some point is at or
//!    past its start, both when it overlaps the band ("the batch needs to be drawn twice", E§3.1).
//!
//! 4. draw, in each command, the batch's far-field subset ([`batch_count`], issue 29, E§7):
//!    every tree unless `subset_mode` thins batches past `subset_distance`
//!    (`forestlod_shared::subset`), the draw then fading each tree by its rank.
//!
//! Commands are compacted **stably**: in batch order, LOD0 before LOD1. Command `i` has
//! `base_vertex = i << COMMAND_SHIFT` and `first_instance = batch.offset` (see
//! [`forestlod_shared::DrawCommand`]). The GPU's atomic-counter variant may emit them in any order;
//! its output equals this one as a multiset once `base_vertex` is masked off.
//!
//! ## Invariants (property-tested in `tests/tests/properties/select_properties.rs`)
//! - **Conservative**: for every tree, every LOD that tree needs by its own interval has a command
//!   for its batch, and no tree that passes the per-tree frustum and draw-distance test has its
//!   batch culled.
//! - **Per-tree equality**: where every batch holds one tree, the grouped decisions equal
//!   [`select_per_tree`]'s.
//! - **Deterministic**: identical output for any rayon thread count.

use forestlod_shared::coverage;
use forestlod_shared::{
    BatchMeta, COMMAND_SHIFT, Camera, CommandData, DrawCommand, EmitGroup, LOD_BILLBOARD, LOD_MESH,
    MeshMeta, Params, SelectCounters, ViewUniform, count_command, emit_command, view_interval,
};
use rayon::prelude::*;

/// What selection emitted for one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Selection {
    /// Indexed indirect draw commands, stably compacted.
    pub commands: Vec<DrawCommand>,
    /// Per-command data, parallel to `commands`.
    pub data: Vec<CommandData>,
    /// Work counters.
    pub counters: SelectCounters,
}

/// The per-sphere decision ([`forestlod_shared::Decision`], with its `DECISION_*` codes): defined
/// in `forestlod-shared` next to the rule that makes it, re-exported here.
pub use forestlod_shared::Decision;

/// Per-frame constants of selection, derived once from the camera and parameters (the uniform of
/// the compute shader): [`forestlod_shared::ViewUniform`], whose [`ViewUniform::new`] is the one
/// place the fade band is derived and whose [`ViewUniform::decide`] is the selection rule (the
/// same for a batch and for a lone tree). The name is kept for the reference's users.
pub type SelectUniform = ViewUniform;

/// Whether one tree is drawn by the draw stage's per-tree draw-distance discard (E§4.4): its
/// bounding-sphere centre's view depth is within the draw distance.
pub fn tree_within_draw_distance(u: &SelectUniform, tree_center: [f32; 3]) -> bool {
    view_interval(tree_center, 0.0, u.eye, u.forward).d <= u.draw_distance
}

/// One compute invocation: the up to two commands of batch `index` (without `base_vertex`, which
/// compaction assigns).
///
/// The batch decides on its group band (issue 29, [`SelectUniform::group_band`] of its mesh's band
/// and its trees' `scale` range: the frame's band under the `distance` metric); its commands
/// carry the mesh's band at unit scale, which the draw stage scales by each tree's own scale.
pub fn select_batch(
    u: &SelectUniform,
    index: u32,
    batch: &BatchMeta,
    scale: [f32; 2],
    meshes: &[MeshMeta],
    billboard: &MeshMeta,
) -> (Decision, [Option<(DrawCommand, CommandData)>; 2]) {
    let mesh_band = u.mesh_band(&meshes[batch.mesh as usize]);
    let ub = u.with_band(u.group_band(mesh_band, scale));
    let decision = ub.decide(batch.center, batch.radius);
    if coverage::enabled() {
        cover_select(&ub, batch, decision);
    }
    let needs = decision.needs();
    let group = EmitGroup {
        index,
        mesh: batch.mesh,
        len: batch.len,
        offset: batch.offset,
        fading: needs.both(),
        fade_start: mesh_band[0],
        fade_end: mesh_band[1],
        count: batch_count(u, batch),
    };
    // The slot (and so `base_vertex`) is assigned by the compaction.
    let emit = |lod| emit_command(0, &group, lod, &meshes[batch.mesh as usize], billboard);
    (
        decision,
        [
            needs.lod0.then(|| emit(LOD_MESH)),
            needs.lod1.then(|| emit(LOD_BILLBOARD)),
        ],
    )
}

/// How many of the batch's trees its commands draw: all, or its far-field subset's count from the
/// near end of its view-depth interval ([`forestlod_shared::subset_count`], issue 29, E§7). The
/// interval is the batch sphere's own, not the group band's: the subset is a distance rule.
pub fn batch_count(u: &SelectUniform, batch: &BatchMeta) -> u32 {
    let lo = view_interval(batch.center, batch.radius, u.eye, u.forward).lo;
    u.subset_count(batch.len, lo)
}

/// Threshold coverage (test-only, [`forestlod_shared::coverage`]): the sides of `select`'s
/// thresholds one batch's decision reached.
fn cover_select(u: &SelectUniform, batch: &BatchMeta, decision: Decision) {
    use coverage::{Threshold::*, hit};
    hit(SelectDrawDistance, decision == Decision::CulledDistance);
    if decision == Decision::CulledDistance {
        return;
    }
    hit(SelectFrustum, decision == Decision::CulledFrustum);
    let planes = [
        SelectPlaneLeft,
        SelectPlaneRight,
        SelectPlaneBottom,
        SelectPlaneTop,
        SelectPlaneNear,
        SelectPlaneFar,
    ];
    let outside = u
        .frustum
        .sphere_outside_planes(batch.center, batch.radius, u.eye);
    for (t, out) in planes.into_iter().zip(outside) {
        hit(t, out);
    }
    if let Decision::Draw(n) = decision {
        hit(SelectFadeEnd, n.lod0);
        hit(SelectFadeStart, n.lod1);
        if n.lod0 || n.lod1 {
            hit(SelectSubset, batch_count(u, batch) < batch.len);
        }
    }
}

/// Selection for one frame over all batches, stably compacted (see the module docs).
/// `meshes` must carry their packed index ranges ([`crate::geometry::pack_geometry`]); `scales`
/// is each batch's tree scale range ([`crate::batches::Batches::scales`]).
pub fn select(
    batches: &[BatchMeta],
    scales: &[[f32; 2]],
    meshes: &[MeshMeta],
    billboard: &MeshMeta,
    camera: &Camera,
    params: &Params,
) -> Selection {
    assert_eq!(batches.len(), scales.len(), "one scale range per batch");
    let u = SelectUniform::new(camera, params);
    let per_batch: Vec<_> = batches
        .par_iter()
        .zip(scales)
        .enumerate()
        .map(|(i, (b, &s))| select_batch(&u, i as u32, b, s, meshes, billboard))
        .collect();
    let mut out = Selection::default();
    out.counters.batches_tested = batches.len() as u32;
    for (decision, commands) in per_batch {
        match decision {
            Decision::CulledDistance => out.counters.culled_distance += 1,
            Decision::CulledFrustum => out.counters.culled_frustum += 1,
            Decision::Draw(n) => out.counters.transition_batches += n.both() as u32,
        }
        for (mut command, data) in commands.into_iter().flatten() {
            command.base_vertex = (out.commands.len() as i32) << COMMAND_SHIFT;
            count_command(&mut out.counters, &command, data.lod);
            out.commands.push(command);
            out.data.push(data);
        }
    }
    out.counters.commands = out.commands.len() as u32;
    out
}

/// The per-batch decisions alone (for tests and experiments), on the frame's band: the
/// `distance` metric's (a scaled metric's group bands need [`select`]).
pub fn batch_decisions(batches: &[BatchMeta], camera: &Camera, params: &Params) -> Vec<Decision> {
    let u = SelectUniform::new(camera, params);
    batches
        .par_iter()
        .map(|b| u.decide(b.center, b.radius))
        .collect()
}

/// The per-batch decisions of [`select`] under any metric: each batch on its group band
/// (`scales`, `meshes` as [`select`] takes them).
pub fn batch_decisions_banded(
    batches: &[BatchMeta],
    scales: &[[f32; 2]],
    meshes: &[MeshMeta],
    camera: &Camera,
    params: &Params,
) -> Vec<Decision> {
    let u = SelectUniform::new(camera, params);
    batches
        .par_iter()
        .zip(scales)
        .map(|(b, &s)| {
            let band = u.group_band(u.mesh_band(&meshes[b.mesh as usize]), s);
            u.with_band(band).decide(b.center, b.radius)
        })
        .collect()
}

/// One tree's band under the frame's metric: its mesh's band scaled by its own scale (issue 29;
/// the frame's band under `distance`).
pub fn tree_band(u: &SelectUniform, mesh: &MeshMeta, scale: f32) -> [f32; 2] {
    u.group_band(u.mesh_band(mesh), [scale, scale])
}

/// Every tree's band ([`tree_band`]) for `camera` and `params`: the per-tree oracle's input
/// under a scaled metric ([`select_per_tree_banded`]).
pub fn tree_bands(
    scene: &crate::scene::Scene,
    meshes: &[MeshMeta],
    camera: &Camera,
    params: &Params,
) -> Vec<[f32; 2]> {
    let u = SelectUniform::new(camera, params);
    scene
        .instances
        .iter()
        .map(|t| tree_band(&u, &meshes[t.mesh as usize], t.scale))
        .collect()
}

/// The per-tree selection oracle: each tree decided alone, by its own bounding sphere, with the
/// same rule as a batch, plus the draw stage's per-tree draw-distance discard. `spheres[i]` is
/// tree `i`'s bounding sphere ([`crate::scene::tree_sphere`]).
pub fn select_per_tree(
    spheres: &[([f32; 3], f32)],
    camera: &Camera,
    params: &Params,
) -> Vec<Decision> {
    let u = SelectUniform::new(camera, params);
    let band = [u.fade_start, u.fade_end];
    select_per_tree_banded(spheres, &vec![band; spheres.len()], camera, params)
}

/// [`select_per_tree`] with each tree deciding on its own band (`bands[i]`, [`tree_bands`]):
/// the oracle of a scaled metric (issue 29). With every band the frame's it is
/// [`select_per_tree`].
pub fn select_per_tree_banded(
    spheres: &[([f32; 3], f32)],
    bands: &[[f32; 2]],
    camera: &Camera,
    params: &Params,
) -> Vec<Decision> {
    assert_eq!(spheres.len(), bands.len(), "one band per tree");
    let u = SelectUniform::new(camera, params);
    spheres
        .par_iter()
        .zip(bands)
        .map(|(&(c, r), &band)| {
            let d = u.with_band(band).decide(c, r);
            let d = if matches!(d, Decision::Draw(_)) && !tree_within_draw_distance(&u, c) {
                Decision::CulledDistance
            } else {
                d
            };
            if coverage::enabled() {
                use coverage::{Threshold::*, hit};
                hit(CullDrawDistance, d == Decision::CulledDistance);
                if d != Decision::CulledDistance {
                    hit(CullFrustum, d == Decision::CulledFrustum);
                }
                if let Decision::Draw(n) = d {
                    hit(CullFadeEnd, n.lod0);
                    hit(CullFadeStart, n.lod1);
                }
            }
            d
        })
        .collect()
}

/// What batching did to the trees of one frame, tree by tree, against the per-tree oracle
/// [`select_per_tree`] (SPEC §6: "count how many trees get a LOD coarser or finer than per-tree
/// selection would give"). A tree's *commanded* LODs are those of the commands of its batch, kept
/// only when the tree passes the draw stage's per-tree draw-distance discard (as the draw stage
/// does); its *needed* LODs are the oracle's.
///
/// Because the fade weights are computed per fragment from its own view depth (E§4.4, SPEC §6),
/// an extra command costs work (triangles, fragments) but changes no pixel: the LOD a fragment
/// shows is the one its depth asks for. So these counts are the price of batching in **work**;
/// its price in accuracy is measured by the sweeps' image error (e.g. `grid_size.toml`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BatchingCounts {
    /// Trees the oracle draws (at least one LOD needed).
    pub trees_needed: u64,
    /// Trees drawn by the grouped selection (at least one LOD commanded).
    pub trees_commanded: u64,
    /// Trees the oracle draws, as billboards only, that get the full mesh (LOD0) too: drawn
    /// *finer* than needed.
    pub trees_finer: u64,
    /// Trees the oracle draws, as meshes only, that get a billboard (LOD1) too: drawn *coarser*
    /// than needed (hidden again by the per-fragment fade).
    pub trees_coarser: u64,
    /// Trees drawn although the oracle culls them (their batch's sphere reaches into the view or
    /// the draw distance), with whatever LODs their batch got.
    pub trees_outside_view: u64,
    /// Trees missing a LOD the oracle gives them. Conservative selection makes this 0.
    pub trees_missing_lod: u64,
}

/// Counts [`BatchingCounts`] for one frame. `spheres[i]` is tree `i`'s bounding sphere
/// ([`crate::scene::tree_sphere`]), `indirection` the batches' tree lists that the commands'
/// `first_instance .. + instance_count` ranges index.
pub fn batching_counts(
    spheres: &[([f32; 3], f32)],
    indirection: &[u32],
    selection: &Selection,
    camera: &Camera,
    params: &Params,
) -> BatchingCounts {
    let u = SelectUniform::new(camera, params);
    let bands = vec![[u.fade_start, u.fade_end]; spheres.len()];
    batching_counts_banded(spheres, &bands, indirection, selection, camera, params)
}

/// [`batching_counts`] against the per-tree oracle on each tree's own band (`bands[i]`,
/// [`tree_bands`]): the counts of a frame under a scaled LOD metric (issue 29), whose grouped
/// selection is conservative against that oracle, not against the frame band's. Under far-field
/// subsets a command's whole group counts as commanded: the trees past its subset count are
/// dropped by design (their price is in the image error and `trees_drawn`), not missed.
pub fn batching_counts_banded(
    spheres: &[([f32; 3], f32)],
    bands: &[[f32; 2]],
    indirection: &[u32],
    selection: &Selection,
    camera: &Camera,
    params: &Params,
) -> BatchingCounts {
    let u = SelectUniform::new(camera, params);
    // Bit 0: LOD0 commanded, bit 1: LOD1 commanded.
    let mut commanded = vec![0u8; spheres.len()];
    for (cmd, data) in selection.commands.iter().zip(&selection.data) {
        let bit = if data.lod == LOD_MESH { 1 } else { 2 };
        // Subsets need the grid and no refine (Params::validate): `first_instance` is the
        // group's first tree there.
        let len = if u.subset_mode != 0 {
            cmd.instance_count.max(data.group_len)
        } else {
            cmd.instance_count
        };
        let range = cmd.first_instance as usize..(cmd.first_instance + len) as usize;
        for &tree in &indirection[range] {
            if tree_within_draw_distance(&u, spheres[tree as usize].0) {
                commanded[tree as usize] |= bit;
            }
        }
    }
    let oracle = select_per_tree_banded(spheres, bands, camera, params);
    let mut c = BatchingCounts::default();
    for (got, want) in commanded.iter().zip(&oracle) {
        let need = want.needs();
        let (has0, has1) = (got & 1 != 0, got & 2 != 0);
        c.trees_needed += (need.lod0 || need.lod1) as u64;
        c.trees_commanded += (*got != 0) as u64;
        let drawn_by_oracle = matches!(want, Decision::Draw(_));
        c.trees_finer += (drawn_by_oracle && has0 && !need.lod0) as u64;
        c.trees_coarser += (drawn_by_oracle && has1 && !need.lod1) as u64;
        c.trees_outside_view += (*got != 0 && !drawn_by_oracle) as u64;
        c.trees_missing_lod += ((need.lod0 && !has0) || (need.lod1 && !has1)) as u64;
    }
    c
}

/// Per-tree selection as a baseline pipeline would run it (E§5's *Vegetation*: every tree tested
/// alone): the work the grouped selection saves. Returns the number of trees drawn per LOD.
pub fn count_per_tree(decisions: &[Decision]) -> [u32; 2] {
    decisions.iter().fold([0, 0], |mut acc, d| {
        let n = d.needs();
        acc[0] += n.lod0 as u32;
        acc[1] += n.lod1 as u32;
        acc
    })
}
