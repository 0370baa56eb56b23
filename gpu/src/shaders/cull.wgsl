// cull.wgsl: per-tree culling and compaction of the two baselines of E§5 (SPEC §9), twin of
// reference/src/baselines.rs (`visible_trees`, i.e. `select::select_per_tree`, and Vegetation's
// compaction `vegetation_commands`); driven by gpu/src/cull.rs; common.wgsl is prepended.
//
// Three dispatches per frame, whatever the tree count (the per-mesh counts are cleared first):
// - `cull_count`, one invocation per tree: the reference's `SelectUniform::decide` on the tree's
//   own bounding sphere (common.wgsl `decide_sphere`) plus the draw stage's per-tree draw-distance
//   discard (`within_draw_distance`); a visible tree reserves its slot within its mesh with one
//   `atomicAdd` on the mesh's count (so the order of trees within a mesh is arbitrary);
// - `cull_commands`, ONE invocation looping over the meshes (bounded by MAX_CULL_MESHES, never by
//   the tree count): the exclusive prefix of the counts (written back in place as each mesh's
//   first slot), one LOD0 command per mesh with visible trees in mesh order, the counters and the
//   Primitive's non-indexed indirect arguments;
// - `cull_scatter`, one invocation per tree: the visible tree's index at its mesh's first slot
//   plus its own slot.

// Keep in sync with forestlod_gpu::cull::CullUniform (gpu/src/cull.rs): the shared view constants
// (common.wgsl `ViewUniform`, derived on the CPU by forestlod_shared::ViewUniform::new, the
// reference's own) plus this stage's sizes.
struct CullUniform {
    view: ViewUniform,
    tree_count: u32,
    mesh_count: u32,
    _pad0: u32,
    _pad1: u32,
}

// Keep in sync with forestlod_gpu::cull::DrawIndirectArgs (wgpu::util::DrawIndirectArgs).
struct DrawIndirectArgs {
    vertex_count: u32,
    instance_count: u32,
    first_vertex: u32,
    first_instance: u32,
}

// CULL_WORKGROUP_SIZE: generated from Rust (gpu/src/cull.rs, SOURCE).
// A tree that is not drawn.
const NO_SLOT: u32 = 0xffffffffu;
// Vertices of one Primitive quad (two triangles).
const QUAD_VERTICES: u32 = 6u;

@group(0) @binding(0) var<uniform> u: CullUniform;
@group(0) @binding(1) var<storage, read> trees: array<CullTree>;
@group(0) @binding(2) var<storage, read> meshes: array<MeshMeta>;
// Per mesh: visible trees after `cull_count`; the mesh's first slot in `indirection` after
// `cull_commands`.
@group(0) @binding(3) var<storage, read_write> mesh_counts: array<atomic<u32>>;
// Per tree: its slot within its mesh, or NO_SLOT.
@group(0) @binding(4) var<storage, read_write> slots: array<u32>;
@group(0) @binding(5) var<storage, read_write> indirection: array<u32>;
@group(0) @binding(6) var<storage, read_write> commands: array<DrawCommand>;
@group(0) @binding(7) var<storage, read_write> command_data: array<CommandData>;
@group(0) @binding(8) var<storage, read_write> counters: SelectCounters;
@group(0) @binding(9) var<storage, read_write> draw_args: DrawIndirectArgs;

// Tree index of an invocation of a (possibly 2D, for more than 65535 workgroups) dispatch.
fn tree_index(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.y * (groups.x * CULL_WORKGROUP_SIZE) + gid.x;
}

// reference select::select_per_tree for one tree, reduced to "drawn or not" (any LOD): decide the
// tree's sphere alone, then discard it when its centre lies beyond the draw distance
// (common.wgsl `decide_tree`).
fn tree_visible(t: CullTree) -> bool {
    return (decide_tree(t, u.view) & DECISION_KIND_MASK) == DECISION_DRAW;
}

@compute @workgroup_size(CULL_WORKGROUP_SIZE)
fn cull_count(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let index = tree_index(gid, groups);
    if index >= u.tree_count {
        return;
    }
    let t = trees[index];
    var slot = NO_SLOT;
    if tree_visible(t) {
        slot = atomicAdd(&mesh_counts[t.mesh], 1u);
    }
    slots[index] = slot;
}

// reference baselines::vegetation_commands: one LOD0 command per mesh with visible trees, in mesh
// order, `base_vertex = slot << COMMAND_SHIFT`, `first_instance` the mesh's first slot.
@compute @workgroup_size(1)
fn cull_commands() {
    var offset = 0u;
    var n = 0u;
    for (var m = 0u; m < u.mesh_count; m++) {
        let count = atomicLoad(&mesh_counts[m]);
        atomicStore(&mesh_counts[m], offset);
        if count > 0u {
            let mesh = meshes[m];
            commands[n] = DrawCommand(mesh.index_count, count, mesh.first_index, i32(n << COMMAND_SHIFT), offset);
            command_data[n] = CommandData(u.view.fade_start, u.view.fade_end, 0u, m, LOD_MESH, 0u, 0u, 0u, 0u, 0u);
            n += 1u;
        }
        offset += count;
    }
    counters = SelectCounters(u.tree_count, 0u, 0u, n, n, 0u, 0u, offset);
    draw_args = DrawIndirectArgs(QUAD_VERTICES, offset, 0u, 0u);
}

@compute @workgroup_size(CULL_WORKGROUP_SIZE)
fn cull_scatter(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let index = tree_index(gid, groups);
    if index >= u.tree_count {
        return;
    }
    let slot = slots[index];
    if slot == NO_SLOT {
        return;
    }
    indirection[atomicLoad(&mesh_counts[trees[index].mesh]) + slot] = index;
}
