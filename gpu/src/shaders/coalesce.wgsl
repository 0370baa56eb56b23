// coalesce.wgsl: command coalescing of the hierarchical cut (issue 13; G§3's contiguous octant
// ranges drawn as one call), a segmented scan over the command list. The GPU twin of
// reference/src/coalesce.rs, driven by gpu/src/coalesce.rs; common.wgsl and scan.wgsl (which scans
// `offsets`) are added around it.
//
// Contract (the reference's module docs, repeated): command j of the cut's list (raw_*) starts a
// run unless it continues command j - 1 (`continues_run`: same geometry, mesh, LOD and fading
// flag, range starting where j - 1's ends; every command is a head when coalescing is off); run r
// is its head's command and data with base_vertex = r << COMMAND_SHIFT and its instances from the
// head's first_instance to the end of its last command's range. Counters: the cut's, with
// commands / lod0_commands / lod1_commands counting runs.
//
// Entry points, O(1) dispatches whatever the command count (every loop is bounded: the scan's
// chunk loop runs capacity / 256 times, within llvmpipe's 65,535 iterations per invocation):
//   `coalesce_heads`  (one invocation per slot): offsets[j] = head flag, run counters;
//   `coalesce_scan`   (one workgroup): exclusive prefix sum of the flags (scan.wgsl);
//   `coalesce_write`  (one invocation per slot): a head writes its run's command and data, the
//                     run's last command writes the run's end into instance_count;
//   `coalesce_finish` (one invocation per run): instance_count = end - first_instance.

// Keep in sync with forestlod_gpu::coalesce::CoalesceUniform (gpu/src/coalesce.rs).
struct CoalesceUniform {
    capacity: u32,
    mode: u32,
    _pad0: u32,
    _pad1: u32,
}

// The atomic view of the counters buffer, SelectCountersAtomic, is in common.wgsl.

@group(0) @binding(0) var<uniform> u: CoalesceUniform;
@group(0) @binding(1) var<storage, read> raw_commands: array<DrawCommand>;
@group(0) @binding(2) var<storage, read> raw_data: array<CommandData>;
@group(0) @binding(3) var<storage, read> raw_counters: SelectCounters;
@group(0) @binding(4) var<storage, read_write> offsets: array<u32>;
@group(0) @binding(5) var<storage, read_write> commands: array<DrawCommand>;
@group(0) @binding(6) var<storage, read_write> command_data: array<CommandData>;
@group(0) @binding(7) var<storage, read_write> counters: SelectCountersAtomic;

fn slot_index(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.y * (groups.x * COALESCE_WORKGROUP_SIZE) + gid.x;
}

// Twin of forestlod_shared::continues_run (shared/src/cut.rs).
fn continues_run(pc: DrawCommand, pd: CommandData, c: DrawCommand, d: CommandData) -> bool {
    return pc.first_index == c.first_index && pc.index_count == c.index_count && pd.mesh == d.mesh
        && pd.lod == d.lod && pd.fading == d.fading
        && pc.first_instance + pc.instance_count == c.first_instance;
}

// Twin of reference coalesce::is_head.
fn is_head(j: u32) -> bool {
    if j == 0u || u.mode == COALESCE_OFF {
        return true;
    }
    return !continues_run(raw_commands[j - 1u], raw_data[j - 1u], raw_commands[j], raw_data[j]);
}

@compute @workgroup_size(COALESCE_WORKGROUP_SIZE)
fn coalesce_heads(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let j = slot_index(gid, groups);
    if j == 0u {
        // The counters the merge does not change (the buffer was cleared before the pass).
        atomicStore(&counters.batches_tested, raw_counters.batches_tested);
        atomicStore(&counters.culled_distance, raw_counters.culled_distance);
        atomicStore(&counters.culled_frustum, raw_counters.culled_frustum);
        atomicStore(&counters.transition_batches, raw_counters.transition_batches);
        atomicStore(&counters.instances, raw_counters.instances);
    }
    if j >= u.capacity {
        return;
    }
    var head = 0u;
    if j < raw_counters.commands && is_head(j) {
        head = 1u;
        atomicAdd(&counters.commands, 1u);
        if raw_data[j].lod == LOD_MESH {
            atomicAdd(&counters.lod0_commands, 1u);
        } else if raw_data[j].lod == LOD_BILLBOARD {
            // Far commands (issue 32) are neither.
            atomicAdd(&counters.lod1_commands, 1u);
        }
    }
    offsets[j] = head;
}

@compute @workgroup_size(SCAN_WORKGROUP_SIZE)
fn coalesce_scan(@builtin(local_invocation_index) lid: u32) {
    scan_offsets(lid, u.capacity);
}

@compute @workgroup_size(COALESCE_WORKGROUP_SIZE)
fn coalesce_write(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let j = slot_index(gid, groups);
    let n = raw_counters.commands;
    if j >= n || j >= u.capacity {
        return;
    }
    let head = is_head(j);
    // offsets is the exclusive scan of the head flags: the run of j is the heads up to j, less one.
    let r = offsets[j] + u32(head) - 1u;
    let c = raw_commands[j];
    if head {
        commands[r].index_count = c.index_count;
        commands[r].first_index = c.first_index;
        commands[r].base_vertex = i32(r << COMMAND_SHIFT);
        commands[r].first_instance = c.first_instance;
        command_data[r] = raw_data[j];
    }
    // The run's last command: its range end, made a count by `coalesce_finish` (the head's
    // first_instance is written by another invocation of this dispatch).
    if j + 1u == n || is_head(j + 1u) {
        commands[r].instance_count = c.first_instance + c.instance_count;
    }
}

@compute @workgroup_size(COALESCE_WORKGROUP_SIZE)
fn coalesce_finish(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let r = slot_index(gid, groups);
    if r >= atomicLoad(&counters.commands) {
        return;
    }
    commands[r].instance_count = commands[r].instance_count - commands[r].first_instance;
}
