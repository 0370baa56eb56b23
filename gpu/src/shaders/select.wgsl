// select.wgsl: per-batch LOD selection and draw-command generation (E§3.5, §4.3; SPEC §5.4).
// The GPU twin of reference/src/select.rs, driven by gpu/src/select.rs; common.wgsl is prepended.
//
// Contract (the reference's module docs, repeated): for each batch, project its bounding sphere
// onto the view direction, `[d - r - m, d + r + m]` (E§3.5, Fig. 3.8); cull it when `lo` lies
// beyond the draw distance or the sphere lies wholly outside one frustum plane; otherwise emit one
// command per LOD the interval needs (`lod_needs`), both when it overlaps the fade band.
//
// Entry points:
// - stable compaction, equal to the reference bit for bit (three dispatches):
//   `select_decide` (one invocation per batch: decision, command count 0..2, counters),
//   `select_scan` (one workgroup: exclusive prefix sum of the counts, in place),
//   `select_write` (one invocation per batch: commands at the scanned offsets, LOD0 first);
// - atomic compaction as in the thesis (E§4.3), one dispatch: `select_atomic` reserves its slots
//   with one `atomicAdd` on the command counter, so the order of batches is arbitrary (LOD0 and
//   LOD1 of one batch stay adjacent).
// In both, command `slot` gets `base_vertex = slot << COMMAND_SHIFT`.

// Keep in sync with forestlod_gpu::select::SelectUniform (gpu/src/select.rs): the shared view constants
// (common.wgsl `ViewUniform`, derived on the CPU by forestlod_shared::ViewUniform::new, the
// reference's own) plus this stage's sizes.
struct SelectUniform {
    view: ViewUniform,
    batch_count: u32,
    mesh_count: u32,
    billboard_first_index: u32,
    billboard_index_count: u32,
}

// The atomic view of the counters buffer, SelectCountersAtomic, is in common.wgsl.

// Decision codes (DECISION_*) and `decide_sphere` live in common.wgsl (shared with cull.wgsl).

// SELECT_WORKGROUP_SIZE, SCAN_WORKGROUP_SIZE: generated from Rust (gpu/src/select.rs).

@group(0) @binding(0) var<uniform> u: SelectUniform;
@group(0) @binding(1) var<storage, read> batches: array<BatchMeta>;
@group(0) @binding(2) var<storage, read> meshes: array<MeshMeta>;
// Per batch: DECISION_* kind plus LOD bits (read back by parity tests to name differing batches).
@group(0) @binding(3) var<storage, read_write> decisions: array<u32>;
// Per batch: command count after `select_decide`, exclusive prefix sum after `select_scan`.
@group(0) @binding(4) var<storage, read_write> offsets: array<u32>;
@group(0) @binding(5) var<storage, read_write> commands: array<DrawCommand>;
@group(0) @binding(6) var<storage, read_write> command_data: array<CommandData>;
@group(0) @binding(7) var<storage, read_write> counters: SelectCountersAtomic;
// Per batch: its trees' scale range [min, max] (reference Batches::scales), what a scaled LOD
// metric widens the batch's band by (common.wgsl `group_band`, C§4.6).
@group(0) @binding(8) var<storage, read> scales: array<vec2<f32>>;

// Twin of reference select_batch's decision: the batch's sphere (common.wgsl `decide_sphere`)
// on its group band, its mesh's band widened by its trees' scale range (the frame's band under
// the distance metric).
fn decide(b: BatchMeta, index: u32) -> u32 {
    let center = vec3<f32>(b.center[0], b.center[1], b.center[2]);
    let band = group_band(u.view, mesh_band(u.view, meshes[b.mesh]), scales[index]);
    return decide_view(center, b.radius, with_band(u.view, band));
}

// How many of the batch's trees its commands draw: all, or its far-field subset's count from the
// near end of its view-depth interval (common.wgsl `subset_count`, issue 29, E§7).
fn batch_count(b: BatchMeta) -> u32 {
    let center = vec3<f32>(b.center[0], b.center[1], b.center[2]);
    let lo = view_interval(center, b.radius, u.view.eye, u.view.forward).lo;
    return subset_count(b.len, lo, u.view);
}

// The batch's counter contributions (the reference's compaction loop, per batch); returns the
// first slot of a contiguous range of `command_count(decision)` slots reserved on the counter.
fn count(b: BatchMeta, decision: u32) -> u32 {
    atomicAdd(&counters.batches_tested, 1u);
    let kind = decision & DECISION_KIND_MASK;
    if kind == DECISION_CULLED_DISTANCE {
        atomicAdd(&counters.culled_distance, 1u);
        return 0u;
    }
    if kind == DECISION_CULLED_FRUSTUM {
        atomicAdd(&counters.culled_frustum, 1u);
        return 0u;
    }
    let lod0 = (decision & DECISION_LOD0) != 0u;
    let lod1 = (decision & DECISION_LOD1) != 0u;
    let n = u32(lod0) + u32(lod1);
    if lod0 && lod1 {
        atomicAdd(&counters.transition_batches, 1u);
    }
    if lod0 {
        atomicAdd(&counters.lod0_commands, 1u);
    }
    if lod1 {
        atomicAdd(&counters.lod1_commands, 1u);
    }
    if n == 0u {
        return 0u;
    }
    atomicAdd(&counters.instances, batch_count(b) * n);
    return atomicAdd(&counters.commands, n);
}

fn command_count(decision: u32) -> u32 {
    if (decision & DECISION_KIND_MASK) != DECISION_DRAW {
        return 0u;
    }
    return u32((decision & DECISION_LOD0) != 0u) + u32((decision & DECISION_LOD1) != 0u);
}

// The batch's command at `lod` in `slot` (common.wgsl `emit_command`, the twin of
// forestlod_shared::emit_command, which the reference's select_batch calls).
fn emit(slot: u32, index: u32, b: BatchMeta, lod: u32, fading: bool, count: u32) {
    var first_index = u.billboard_first_index;
    var index_count = u.billboard_index_count;
    if lod == LOD_MESH {
        let m = meshes[b.mesh];
        first_index = m.first_index;
        index_count = m.index_count;
    }
    // Commands carry the mesh's band at unit scale; the draw scales it per tree.
    let view = with_band(u.view, mesh_band(u.view, meshes[b.mesh]));
    let e = emit_command(slot, index, b.mesh, b.len, b.offset, fading, lod, first_index, index_count, view, count);
    commands[slot] = e.command;
    command_data[slot] = e.data;
}

// Writes the batch's commands from `slot` on: LOD0 first, then LOD1.
fn emit_all(slot: u32, index: u32, b: BatchMeta, decision: u32) {
    if (decision & DECISION_KIND_MASK) != DECISION_DRAW {
        return;
    }
    let lod0 = (decision & DECISION_LOD0) != 0u;
    let lod1 = (decision & DECISION_LOD1) != 0u;
    let fading = lod0 && lod1;
    // Both commands draw the same subset: its count once.
    let count = batch_count(b);
    if lod0 {
        emit(slot, index, b, LOD_MESH, fading, count);
    }
    if lod1 {
        emit(slot + u32(lod0), index, b, LOD_BILLBOARD, fading, count);
    }
}

// Batch index of an invocation of a (possibly 2D, for more than 65535 workgroups) dispatch.
fn batch_index(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.y * (groups.x * SELECT_WORKGROUP_SIZE) + gid.x;
}

// The batch's decision (`decide`), recorded in `decisions`.
fn decide_batch(index: u32) -> u32 {
    let decision = decide(batches[index], index);
    decisions[index] = decision;
    return decision;
}

// Stable, pass 1: decision, command count, counters.
@compute @workgroup_size(SELECT_WORKGROUP_SIZE)
fn select_decide(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let index = batch_index(gid, groups);
    if index >= u.batch_count {
        return;
    }
    let decision = decide_batch(index);
    count(batches[index], decision);
    offsets[index] = command_count(decision);
}

// Stable, pass 2: exclusive prefix sum of `offsets`, in place (scan.wgsl `scan_offsets`, one
// workgroup; plenty for the batch counts of E§5, tens of thousands).
@compute @workgroup_size(SCAN_WORKGROUP_SIZE)
fn select_scan(@builtin(local_invocation_index) lid: u32) {
    scan_offsets(lid, u.batch_count);
}

// Stable, pass 3: commands at the scanned offsets, in batch order, LOD0 before LOD1.
@compute @workgroup_size(SELECT_WORKGROUP_SIZE)
fn select_write(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let index = batch_index(gid, groups);
    if index >= u.batch_count {
        return;
    }
    emit_all(offsets[index], index, batches[index], decisions[index]);
}

// Atomic compaction (E§4.3): decide, reserve slots with one atomicAdd, write; one dispatch.
@compute @workgroup_size(SELECT_WORKGROUP_SIZE)
fn select_atomic(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let index = batch_index(gid, groups);
    if index >= u.batch_count {
        return;
    }
    let b = batches[index];
    let decision = decide_batch(index);
    let slot = count(b, decision);
    emit_all(slot, index, b, decision);
}
