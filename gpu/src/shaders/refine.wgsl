// refine.wgsl: per-tree refinement of the selected commands, beyond the thesis (its future work,
// "tighter culling", E§7; grouped selection E§3.5). The GPU twin of reference/src/refine.rs
// (`refine_command` is split here over one invocation per chunk of 64 trees of a command), driven
// by gpu/src/refine.rs; common.wgsl is prepended.
//
// Command `slot < counters.commands` (as `select` wrote it: `first_instance` = its batch's offset
// `off`, `instance_count` = the batch's length `len`, `command_data[slot].lod` = L) is
// - refined when `u.tree_cull` refines L (TREE_CULL_ALL, or TREE_CULL_LOD0 and L = LOD_MESH): it
//   keeps the trees of its batch (read from the static copy of the batch indirection at
//   `2n + off`) whose own sphere is decided Draw with LOD L needed (`decide_sphere`, the
//   selection rule) and whose centre is within the draw distance (`within_draw_distance`), and
//   writes them IN BATCH ORDER to `L·n + off + k` (a stable compaction); the command becomes
//   `first_instance = L·n + off`, `instance_count = kept`;
// - otherwise pointed at the static copy: `first_instance = 2n + off`, count unchanged.
// Commands are never removed; base_vertex, the index range and the data stay as they are.
//
// Passes, in this order (gpu/src/refine.rs encodes them; every loop is bounded as noted, since
// llvmpipe stops any loop after 65,535 iterations):
// 1. `refine_prepare`, one invocation per slot: the largest chunk count `ceil(len / 64)` of the
//    refined commands (atomicMax into `dispatch.max_chunks`, cleared before).
// 2. `refine_args`, one invocation: the indirect grid of passes 3 and 5,
//    `(ceil(max_chunks / 64), y, z)` with `y·z >= counters.commands` slots (y capped at the
//    per-dimension limit `u.max_workgroups`); the driver copies it to the indirect-argument buffer.
// 3. `refine_count`, one invocation per (chunk `wid.x·64 + lid`, slot `wid.z·groups.y + wid.y`):
//    slots past the command count, unrefined commands and chunks past the command's own exit; the
//    others test their (up to) 64 trees in a loop of at most 64 iterations and store the chunk's
//    kept count in `chunk_counts[L·2n + 2·off + chunk]`. No workgroup memory and no barrier:
//    one workgroup per chunk with a workgroup scan measured 5-9x slower than the serial walk it
//    replaced under llvmpipe (not profiled; barriers appear to carry a high fixed cost there).
// 4. `refine_scan`, one invocation per slot: exclusive prefix over its `ceil(len / 64)` chunk
//    counts in place (a loop of at most 65,535 iterations: n <= MAX_REFINE_TREES = 65535·64), the
//    total after them at `L·2n + 2·off + chunks` (its `chunks + 1 <= 2·len` entries are the
//    command's own: the ranges of distinct (batch, LOD) pairs are disjoint).
// 5. `refine_write`, the grid of pass 3: the same tests in the same order, each kept tree written
//    to `L·n + off + chunk prefix + rank in chunk`.
// 6. `refine_finalize`, one invocation per slot: rewrites the command and adds to the counters.

// Keep in sync with forestlod_gpu::refine::RefineUniform (gpu/src/refine.rs): the shared view constants
// (common.wgsl `ViewUniform`, derived on the CPU by forestlod_shared::ViewUniform::new, the
// reference's own) plus this stage's sizes.
struct RefineUniform {
    view: ViewUniform,
    tree_count: u32,
    tree_cull: u32,
    max_workgroups: u32,
    _pad0: u32,
}

// Keep in sync with forestlod_gpu::refine::RefineCounters (gpu/src/refine.rs): the reference's
// `Refined::trees_tested` / `trees_kept`.
struct RefineCounters {
    trees_tested: atomic<u32>,
    trees_kept: atomic<u32>,
}

// The indirect grid of the count and write passes, and the largest chunk count it is derived
// from. Keep in sync with forestlod_gpu::refine::RefineDispatch (gpu/src/refine.rs).
struct RefineDispatch {
    x: u32,
    y: u32,
    z: u32,
    max_chunks: atomic<u32>,
}

// REFINE_WORKGROUP_SIZE (also the trees per chunk; gpu/src/refine.rs, SOURCE) and the TREE_CULL_*
// ids (gpu/src/shaders.rs): generated from Rust.

@group(0) @binding(0) var<uniform> u: RefineUniform;
@group(0) @binding(1) var<storage, read> trees: array<CullTree>;
// 3n entries: [0, n) refined LOD0 lists, [n, 2n) refined LOD1 lists, [2n, 3n) the batch
// indirection (uploaded once, only read here).
@group(0) @binding(2) var<storage, read_write> indirection: array<u32>;
@group(0) @binding(3) var<storage, read_write> commands: array<DrawCommand>;
@group(0) @binding(4) var<storage, read> command_data: array<CommandData>;
@group(0) @binding(5) var<storage, read> counters: SelectCounters;
@group(0) @binding(6) var<storage, read_write> refine_counters: RefineCounters;
// 4n entries: per LOD L and command of batch offset `off`, `[L·2n + 2·off, + chunks]` the chunk
// counts (pass 3), then their exclusive prefixes and the total (pass 4).
@group(0) @binding(7) var<storage, read_write> chunk_counts: array<u32>;
@group(0) @binding(8) var<storage, read_write> dispatch: RefineDispatch;

// forestlod_shared::TreeCull::refines.
fn refines(mode: u32, lod: u32) -> bool {
    return mode == TREE_CULL_ALL || (mode == TREE_CULL_LOD0 && lod == LOD_MESH);
}

// The reference's per-tree test in `refine_command`: the tree's own sphere, on its own band (the
// command's band at unit scale, `band`, scaled by the tree's scale under a scaled LOD metric), is
// drawn and needs LOD `lod`, and its centre passes the draw stage's per-tree draw-distance discard.
fn tree_needs(tree: u32, lod: u32, band: vec2<f32>) -> bool {
    let t = trees[tree];
    let view = with_band(u.view, group_band(u.view, band, vec2<f32>(t.scale, t.scale)));
    let decision = decide_tree(t, view);
    let bit = select(DECISION_LOD1, DECISION_LOD0, lod == LOD_MESH);
    return (decision & DECISION_KIND_MASK) == DECISION_DRAW && (decision & bit) != 0u;
}

// Chunks of 64 trees of a batch of `len` trees.
fn chunk_count(len: u32) -> u32 {
    return (len + REFINE_WORKGROUP_SIZE - 1u) / REFINE_WORKGROUP_SIZE;
}

// Start of the command's entries in `chunk_counts` (module header).
fn chunk_base(lod: u32, off: u32) -> u32 {
    return lod * 2u * u.tree_count + 2u * off;
}

// The builtins every pass of a workgroup of REFINE_WORKGROUP_SIZE reads.
struct Invocation {
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
}

// The slot of a one-invocation-per-slot pass (`ceil(capacity / 64)` workgroups, spilling into y).
fn slot_of(inv: Invocation) -> u32 {
    return (inv.wid.y * inv.groups.x + inv.wid.x) * REFINE_WORKGROUP_SIZE + inv.lid;
}

// Pass 1: the largest chunk count of the refined commands.
@compute @workgroup_size(REFINE_WORKGROUP_SIZE)
fn refine_prepare(inv: Invocation) {
    let slot = slot_of(inv);
    if slot >= counters.commands || !refines(u.tree_cull, command_data[slot].lod) {
        return;
    }
    atomicMax(&dispatch.max_chunks, chunk_count(commands[slot].instance_count));
}

// Pass 2: the grid of the count and write passes (x: workgroups of 64 chunks, y·z: slots).
@compute @workgroup_size(1)
fn refine_args() {
    let chunks = atomicLoad(&dispatch.max_chunks);
    let slots = counters.commands;
    if chunks == 0u || slots == 0u {
        dispatch.x = 0u;
        dispatch.y = 0u;
        dispatch.z = 0u;
        return;
    }
    let y = min(slots, u.max_workgroups);
    dispatch.x = (chunks + REFINE_WORKGROUP_SIZE - 1u) / REFINE_WORKGROUP_SIZE;
    dispatch.y = y;
    dispatch.z = (slots + y - 1u) / y;
}

// The invocation's chunk of a refined command: `(off, len)`, the chunk index and the chunk's
// trees (`indirection[src + j]` for `j` in `[first, end)`, at most 64), or `ok = false` when the
// invocation has nothing to do.
struct Chunk {
    ok: bool,
    lod: u32,
    // The command's band at unit scale (its CommandData's fade_start, fade_end).
    band: vec2<f32>,
    off: u32,
    len: u32,
    chunk: u32,
    src: u32,
    first: u32,
    end: u32,
}

fn invocation_chunk(inv: Invocation) -> Chunk {
    var c = Chunk(false, 0u, vec2<f32>(0.0, 0.0), 0u, 0u, inv.wid.x * REFINE_WORKGROUP_SIZE + inv.lid, 0u, 0u, 0u);
    let slot = inv.wid.z * inv.groups.y + inv.wid.y;
    if slot >= counters.commands {
        return c;
    }
    let data = command_data[slot];
    c.lod = data.lod;
    c.band = vec2<f32>(data.fade_start, data.fade_end);
    if !refines(u.tree_cull, c.lod) {
        return c;
    }
    let command = commands[slot];
    c.off = command.first_instance;
    c.len = command.instance_count;
    c.ok = c.chunk < chunk_count(c.len);
    c.src = 2u * u.tree_count + c.off;
    c.first = c.chunk * REFINE_WORKGROUP_SIZE;
    c.end = min(c.first + REFINE_WORKGROUP_SIZE, c.len);
    return c;
}

// Pass 3: each chunk's kept count (a loop of at most 64 iterations).
@compute @workgroup_size(REFINE_WORKGROUP_SIZE)
fn refine_count(inv: Invocation) {
    let c = invocation_chunk(inv);
    if !c.ok {
        return;
    }
    var kept = 0u;
    for (var j = c.first; j < c.end; j++) {
        kept += u32(tree_needs(indirection[c.src + j], c.lod, c.band));
    }
    chunk_counts[chunk_base(c.lod, c.off) + c.chunk] = kept;
}

// Pass 4: per refined command, the exclusive prefix of its chunk counts and their total.
@compute @workgroup_size(REFINE_WORKGROUP_SIZE)
fn refine_scan(inv: Invocation) {
    let slot = slot_of(inv);
    if slot >= counters.commands {
        return;
    }
    let lod = command_data[slot].lod;
    if !refines(u.tree_cull, lod) {
        return;
    }
    let command = commands[slot];
    let chunks = chunk_count(command.instance_count);
    if chunks == 0u {
        return;
    }
    let base = chunk_base(lod, command.first_instance);
    var sum = 0u;
    for (var k = 0u; k < chunks; k++) {
        let count = chunk_counts[base + k];
        chunk_counts[base + k] = sum;
        sum += count;
    }
    chunk_counts[base + chunks] = sum;
}

// Pass 5: the kept trees, in batch order (the same loop as pass 3).
@compute @workgroup_size(REFINE_WORKGROUP_SIZE)
fn refine_write(inv: Invocation) {
    let c = invocation_chunk(inv);
    if !c.ok {
        return;
    }
    var k = c.lod * u.tree_count + c.off + chunk_counts[chunk_base(c.lod, c.off) + c.chunk];
    for (var j = c.first; j < c.end; j++) {
        let tree = indirection[c.src + j];
        if tree_needs(tree, c.lod, c.band) {
            indirection[k] = tree;
            k++;
        }
    }
}

// Pass 6: the commands rewritten, the counters.
@compute @workgroup_size(REFINE_WORKGROUP_SIZE)
fn refine_finalize(inv: Invocation) {
    let slot = slot_of(inv);
    if slot >= counters.commands {
        return;
    }
    let n = u.tree_count;
    let lod = command_data[slot].lod;
    let off = commands[slot].first_instance;
    if !refines(u.tree_cull, lod) {
        commands[slot].first_instance = 2u * n + off;
        return;
    }
    let len = commands[slot].instance_count;
    var kept = 0u;
    if len != 0u {
        kept = chunk_counts[chunk_base(lod, off) + chunk_count(len)];
    }
    commands[slot].first_instance = lod * n + off;
    commands[slot].instance_count = kept;
    atomicAdd(&refine_counters.trees_tested, len);
    atomicAdd(&refine_counters.trees_kept, kept);
}
