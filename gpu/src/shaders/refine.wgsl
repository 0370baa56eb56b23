// refine.wgsl: per-tree refinement of the selected commands, beyond the thesis (its future work,
// "tighter culling", E§7; grouped selection E§3.5). The GPU twin of reference/src/refine.rs
// (`refine_command` is the body of one workgroup here), driven by gpu/src/refine.rs; common.wgsl
// is prepended.
//
// One dispatch of one workgroup (REFINE_WORKGROUP_SIZE invocations) per command slot of the
// select buffers; slots at or past `counters.commands` exit at once. Command `slot` (as `select`
// wrote it: `first_instance` = its batch's offset `off`, `instance_count` = the batch's length,
// `command_data[slot].lod` = L) is
// - refined when `u.tree_cull` refines L (TREE_CULL_ALL, or TREE_CULL_LOD0 and L = LOD_MESH): the
//   workgroup walks the batch's trees in chunks of REFINE_WORKGROUP_SIZE (read from the static
//   copy of the batch indirection at `2n + off`), keeps those whose own sphere is decided Draw
//   with LOD L needed (`decide_sphere`, the selection rule) and whose centre is within the draw distance
//   (`within_draw_distance`), and writes them IN BATCH ORDER to `L·n + off + k` (a workgroup
//   exclusive scan of the keep flags per chunk plus a running carry: a stable compaction); then
//   invocation 0 rewrites the command: `first_instance = L·n + off`, `instance_count = kept`;
// - otherwise pointed at the static copy: `first_instance = 2n + off`, count unchanged.
// Commands are never removed; base_vertex, the index range and the data stay as they are.
//
// Loops: the chunk loop runs ceil(len / 64) times (a batch of 20k trees: ~300 iterations; llvmpipe
// stops any loop after 65,535 iterations, hence MAX_REFINE_TREES on the CPU side); the scan within
// a chunk is unrolled (log2(64) = 6 steps), so no loop's trip count grows with anything else.

// Keep in sync with forestlod_gpu::refine::RefineUniform (gpu/src/refine.rs). Derived on the CPU
// exactly as reference::select::SelectUniform::new derives its own.
struct RefineUniform {
    planes: array<vec4<f32>, 6>,
    eye: vec3<f32>,
    fade_start: f32,
    forward: vec3<f32>,
    fade_end: f32,
    draw_distance: f32,
    lod_levels: u32,
    tree_count: u32,
    tree_cull: u32,
}

// Keep in sync with forestlod_gpu::refine::RefineCounters (gpu/src/refine.rs): the reference's
// `Refined::trees_tested` / `trees_kept`.
struct RefineCounters {
    trees_tested: atomic<u32>,
    trees_kept: atomic<u32>,
}

// Keep in sync with REFINE_WORKGROUP_SIZE in gpu/src/refine.rs (the unrolled scan assumes 64).
const REFINE_WORKGROUP_SIZE: u32 = 64u;
// Keep in sync with forestlod_shared::TreeCull (shared/src/params.rs).
const TREE_CULL_NONE: u32 = 0u;
const TREE_CULL_LOD0: u32 = 1u;
const TREE_CULL_ALL: u32 = 2u;

@group(0) @binding(0) var<uniform> u: RefineUniform;
@group(0) @binding(1) var<storage, read> trees: array<CullTree>;
// 3n entries: [0, n) refined LOD0 lists, [n, 2n) refined LOD1 lists, [2n, 3n) the batch
// indirection (uploaded once, only read here).
@group(0) @binding(2) var<storage, read_write> indirection: array<u32>;
@group(0) @binding(3) var<storage, read_write> commands: array<DrawCommand>;
@group(0) @binding(4) var<storage, read> command_data: array<CommandData>;
@group(0) @binding(5) var<storage, read> counters: SelectCounters;
@group(0) @binding(6) var<storage, read_write> refine_counters: RefineCounters;

var<workgroup> scan: array<u32, REFINE_WORKGROUP_SIZE>;
// The command's (first_instance, instance_count) as select wrote them, read by invocation 0.
var<workgroup> wg_range: vec2<u32>;
// Trees kept by the current chunk (its inclusive scan's last element).
var<workgroup> wg_chunk_kept: u32;

// forestlod_shared::TreeCull::refines.
fn refines(mode: u32, lod: u32) -> bool {
    return mode == TREE_CULL_ALL || (mode == TREE_CULL_LOD0 && lod == LOD_MESH);
}

// The reference's per-tree test in `refine_command`: the tree's own sphere is drawn and needs LOD
// `lod`, and its centre passes the draw stage's per-tree draw-distance discard.
fn tree_needs(tree: u32, lod: u32) -> bool {
    let t = trees[tree];
    let center = vec3<f32>(t.center[0], t.center[1], t.center[2]);
    let decision = decide_sphere(
        center, t.radius, u.planes, u.eye, u.forward, u.draw_distance, u.fade_start, u.fade_end,
        u.lod_levels,
    );
    if (decision & DECISION_KIND_MASK) != DECISION_DRAW {
        return false;
    }
    let bit = select(DECISION_LOD1, DECISION_LOD0, lod == LOD_MESH);
    return (decision & bit) != 0u
        && within_draw_distance(center, u.eye, u.forward, u.draw_distance);
}

// One Hillis-Steele step of the inclusive scan of `scan` (called in uniform control flow).
fn scan_step(lid: u32, step: u32) {
    var add = 0u;
    if lid >= step {
        add = scan[lid - step];
    }
    workgroupBarrier();
    scan[lid] = scan[lid] + add;
    workgroupBarrier();
}

@compute @workgroup_size(REFINE_WORKGROUP_SIZE)
fn refine(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    // Uniform across the workgroup: the slot, the count (read-only storage), the LOD and mode.
    let slot = wid.y * groups.x + wid.x;
    if slot >= counters.commands {
        return;
    }
    let n = u.tree_count;
    let lod = command_data[slot].lod;
    if !refines(u.tree_cull, lod) {
        if lid == 0u {
            commands[slot].first_instance = 2u * n + commands[slot].first_instance;
        }
        return;
    }
    if lid == 0u {
        let c = commands[slot];
        wg_range = vec2<u32>(c.first_instance, c.instance_count);
    }
    let range = workgroupUniformLoad(&wg_range);
    let off = range.x;
    let len = range.y;
    let src = 2u * n + off;
    let dst = lod * n + off;
    var kept = 0u;
    let chunks = (len + REFINE_WORKGROUP_SIZE - 1u) / REFINE_WORKGROUP_SIZE;
    for (var c = 0u; c < chunks; c++) {
        let j = c * REFINE_WORKGROUP_SIZE + lid;
        var tree = 0u;
        var keep = 0u;
        if j < len {
            tree = indirection[src + j];
            keep = u32(tree_needs(tree, lod));
        }
        scan[lid] = keep;
        workgroupBarrier();
        scan_step(lid, 1u);
        scan_step(lid, 2u);
        scan_step(lid, 4u);
        scan_step(lid, 8u);
        scan_step(lid, 16u);
        scan_step(lid, 32u);
        // scan[lid] is now the inclusive prefix: this tree's rank among the chunk's kept ones.
        if keep != 0u {
            indirection[dst + kept + scan[lid] - 1u] = tree;
        }
        if lid == REFINE_WORKGROUP_SIZE - 1u {
            wg_chunk_kept = scan[lid];
        }
        kept += workgroupUniformLoad(&wg_chunk_kept);
    }
    if lid == 0u {
        commands[slot].first_instance = dst;
        commands[slot].instance_count = kept;
        atomicAdd(&refine_counters.trees_tested, len);
        atomicAdd(&refine_counters.trees_kept, kept);
    }
}
