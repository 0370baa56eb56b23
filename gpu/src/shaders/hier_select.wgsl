// hier_select.wgsl: the hierarchical cut (issue 13; G§3 Fig. 4, C§4.5) as a parallel evaluation.
// The GPU twin of reference/src/hier_select.rs, driven by gpu/src/hier_select.rs; common.wgsl
// (NodeMeta, node_code) is prepended.
//
// Contract (the reference's module docs, repeated): per node `node_code` (decision on its bounds
// plus NODE_RECURSE); a node is visited when every ancestor recursed, emitted when visited, drawn
// and not recursing; emitted nodes become commands in node order, LOD0 before LOD1.
//
// Entry points, O(1) dispatches per frame whatever the hierarchy:
//   `hier_decide`  (one invocation per node): codes[i] = node_code;
//   `hier_resolve` (one invocation per node): walk the ancestors (at most MAX_HIERARCHY_DEPTH,
//                  far below llvmpipe's 65,535 iterations per loop), states[i], command count,
//                  counters;
//   `hier_scan`    (one workgroup): exclusive prefix sum of the counts (select.wgsl's scan);
//   `hier_write`   (one invocation per node): the emitted node's commands at its offset.

// Keep in sync with forestlod_gpu::hier_select::HierUniform (gpu/src/hier_select.rs).
struct HierUniform {
    view: ViewUniform,
    node_count: u32,
    mode: u32,
    max_cull_depth: u32,
    billboard_first_index: u32,
    billboard_index_count: u32,
    // The far level (issue 32, forestlod_shared::FarUniform): kind 0 = none, else 1 + FarLod.
    far_kind: u32,
    far_start: f32,
    far_ratio: f32,
    // First index of the packed geometry's far iota range.
    far_first_index: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// The atomic view of the counters buffer, SelectCountersAtomic, is in common.wgsl.

// NODE_VISITED, NODE_EMITTED (forestlod_shared::cut, gpu/src/shaders.rs), HIER_WORKGROUP_SIZE
// (gpu/src/hier_select.rs, SOURCE) and SCAN_WORKGROUP_SIZE (gpu/src/select.rs, SCAN): generated.

@group(0) @binding(0) var<uniform> u: HierUniform;
@group(0) @binding(1) var<storage, read> nodes: array<NodeMeta>;
@group(0) @binding(2) var<storage, read> meshes: array<MeshMeta>;
@group(0) @binding(3) var<storage, read_write> codes: array<u32>;
@group(0) @binding(4) var<storage, read_write> states: array<u32>;
@group(0) @binding(5) var<storage, read_write> offsets: array<u32>;
@group(0) @binding(6) var<storage, read_write> commands: array<DrawCommand>;
@group(0) @binding(7) var<storage, read_write> command_data: array<CommandData>;
@group(0) @binding(8) var<storage, read_write> counters: SelectCountersAtomic;
// Per node: its trees' scale range [min, max] (reference Hierarchy::scales), what a scaled LOD
// metric widens the node's band by (common.wgsl `group_band`, C§4.6).
@group(0) @binding(9) var<storage, read> scales: array<vec2<f32>>;
// Per node: its far level's cells and hull (issue 32); one zeroed record without a far level.
@group(0) @binding(10) var<storage, read> far_nodes: array<FarNode>;

// Kept cells of node `i` under a far level (0 without one: the buffer then holds one record).
fn far_cells(i: u32) -> u32 {
    if u.far_kind == 0u {
        return 0u;
    }
    return far_nodes[i].cell_count;
}

// Impostored strict descendants of node `i` under `far_lod = impostor` (issue 33 item 2, the far
// record's `hull_count`: forestlod_shared::impostor's per-node far data); 0 otherwise.
fn far_impostored_below(i: u32) -> u32 {
    if u.far_kind != 1u + FAR_LOD_IMPOSTOR {
        return 0u;
    }
    return far_nodes[i].hull_count;
}

fn node_index(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.y * (groups.x * HIER_WORKGROUP_SIZE) + gid.x;
}

// forestlod_shared::emitted_needs as (lod0, lod1) bits: the code's LODs, billboards only for an
// octree-euclidean interior unit.
fn emitted_bits(code: u32, n: NodeMeta) -> u32 {
    var bits = code & (DECISION_LOD0 | DECISION_LOD1);
    if u.mode == HIERARCHY_OCTREE_EUCLIDEAN && n.child_count > 0u && u.view.lod_levels >= 2u
        && (bits & DECISION_LOD1) != 0u {
        bits = DECISION_LOD1;
    }
    return bits;
}

@compute @workgroup_size(HIER_WORKGROUP_SIZE)
fn hier_decide(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = node_index(gid, groups);
    if i >= u.node_count {
        return;
    }
    // The node decides on its group band (the frame's band under the distance metric).
    let n = nodes[i];
    let band = group_band(u.view, mesh_band(u.view, meshes[n.mesh]), scales[i]);
    let banded = with_band(u.view, band);
    let code = node_code(n, u.mode, u.max_cull_depth, banded);
    codes[i] = far_code(
        code, n, u.mode, banded, u.far_kind, u.far_start, u.far_ratio, far_cells(i), far_impostored_below(i),
    );
}

@compute @workgroup_size(HIER_WORKGROUP_SIZE)
fn hier_resolve(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = node_index(gid, groups);
    if i >= u.node_count {
        return;
    }
    let n = nodes[i];
    var visited = true;
    var p = n.parent;
    for (var k = 0u; k < MAX_HIERARCHY_DEPTH && p != NO_PARENT; k++) {
        let c = codes[p];
        if (c & DECISION_KIND_MASK) != DECISION_DRAW || (c & NODE_RECURSE) == 0u {
            visited = false;
            break;
        }
        p = nodes[p].parent;
    }
    offsets[i] = 0u;
    if !visited {
        states[i] = 0u;
        return;
    }
    atomicAdd(&counters.batches_tested, 1u);
    let code = codes[i];
    let kind = code & DECISION_KIND_MASK;
    if kind == DECISION_CULLED_DISTANCE {
        atomicAdd(&counters.culled_distance, 1u);
    }
    if kind == DECISION_CULLED_FRUSTUM {
        atomicAdd(&counters.culled_frustum, 1u);
    }
    if kind != DECISION_DRAW || (code & NODE_RECURSE) != 0u {
        states[i] = NODE_VISITED;
        return;
    }
    states[i] = NODE_VISITED | NODE_EMITTED;
    if (code & NODE_FAR) != 0u {
        // forestlod_shared::emit_far_command's instances: the cells, or one hull.
        let f = far_nodes[i];
        var instances = f.cell_count;
        if u.far_kind == 1u + FAR_LOD_HULL {
            instances = 1u;
        }
        atomicAdd(&counters.instances, instances);
        atomicAdd(&counters.commands, 1u);
        offsets[i] = 1u;
        return;
    }
    let bits = emitted_bits(code, n);
    let lod0 = (bits & DECISION_LOD0) != 0u;
    let lod1 = (bits & DECISION_LOD1) != 0u;
    let count = u32(lod0) + u32(lod1);
    if lod0 && lod1 {
        atomicAdd(&counters.transition_batches, 1u);
    }
    if lod0 {
        atomicAdd(&counters.lod0_commands, 1u);
    }
    if lod1 {
        atomicAdd(&counters.lod1_commands, 1u);
    }
    atomicAdd(&counters.instances, n.len * count);
    atomicAdd(&counters.commands, count);
    offsets[i] = count;
}

// Exclusive prefix sum of the per-node command counts (scan.wgsl `scan_offsets`, as
// select.wgsl's `select_scan`).
@compute @workgroup_size(SCAN_WORKGROUP_SIZE)
fn hier_scan(@builtin(local_invocation_index) lid: u32) {
    scan_offsets(lid, u.node_count);
}

fn emit(slot: u32, i: u32, n: NodeMeta, lod: u32, fading: bool) {
    var first_index = u.billboard_first_index;
    var index_count = u.billboard_index_count;
    if lod == LOD_MESH {
        let m = meshes[n.mesh];
        first_index = m.first_index;
        index_count = m.index_count;
    }
    // Commands carry the mesh's band at unit scale; the draw scales it per tree.
    let view = with_band(u.view, mesh_band(u.view, meshes[n.mesh]));
    let e = emit_command(slot, i, n.mesh, n.len, n.offset, fading, lod, first_index, index_count, view, n.len);
    commands[slot] = e.command;
    command_data[slot] = e.data;
}

// forestlod_shared::emit_far_command: one instance per cell (under impostors the node's quad) over
// the primitive's iota range, or one hull instance (the node's index) over its vertices.
fn emit_far(slot: u32, i: u32, n: NodeMeta) {
    let f = far_nodes[i];
    var index_count = CUBE_VERTICES;
    var instances = f.cell_count;
    var first = f.cell_offset;
    // An impostor is one quad, the node's (issue 33 item 2), drawn as a sprite's.
    if u.far_kind == 1u + FAR_LOD_OCTANT_SPRITE || u.far_kind == 1u + FAR_LOD_IMPOSTOR {
        index_count = SPRITE_VERTICES;
    } else if u.far_kind == 1u + FAR_LOD_HULL {
        index_count = f.hull_count;
        instances = 1u;
        first = i;
    }
    commands[slot] = DrawCommand(index_count, instances, u.far_first_index, i32(slot << COMMAND_SHIFT), first);
    command_data[slot] = CommandData(0.0, 0.0, i, n.mesh, LOD_FAR, 0u, 0u, first, instances, 0u);
}

@compute @workgroup_size(HIER_WORKGROUP_SIZE)
fn hier_write(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = node_index(gid, groups);
    if i >= u.node_count || (states[i] & NODE_EMITTED) == 0u {
        return;
    }
    let n = nodes[i];
    let slot = offsets[i];
    if (codes[i] & NODE_FAR) != 0u {
        emit_far(slot, i, n);
        return;
    }
    let bits = emitted_bits(codes[i], n);
    let lod0 = (bits & DECISION_LOD0) != 0u;
    let lod1 = (bits & DECISION_LOD1) != 0u;
    if lod0 {
        emit(slot, i, n, LOD_MESH, lod0 && lod1);
    }
    if lod1 {
        emit(slot + u32(lod0), i, n, LOD_BILLBOARD, lod0 && lod1);
    }
}
