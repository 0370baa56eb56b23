// occlude.wgsl: occlusion culling of the selected commands (issue 31), the GPU twin of
// reference/src/occlude.rs (`occlude_early`, `occlude_late`; its per-command loop is split here
// over one invocation per chunk of 64 trees of a command, as refine.wgsl splits refine's),
// driven by gpu/src/occlude.rs; common.wgsl is prepended (the formulas: forestlod_shared::
// occlusion's twins there).
//
// Input: the frame's commands (after every selection stage) over an indirection of `m` entries,
// copied by the driver into `indirection[4m, 5m)`; the commands of this phase's buffer are a
// copy of the frame's (`first_instance` = `off`, `instance_count` = `len`). Phase `u.phase`:
// - 0 (early): keeps, IN LIST ORDER, the trees of each command that are occluders (`is_occluder`
//   under the effective mode `u.mode`: their footprint's nearest view depth less `single`'s
//   nearest occluder depth, whether they passed the previous frame's test,
//   `history[u.history_read + tree]`, and a bound not off screen), at
//   `occlusion_slot(0, lod, m, off) + k`;
// - 1 (late): tests the trees against the pyramid (`occlusion_bounds`, `pyramid_level_for`, the
//   at most 2x2 texels, `occluded`; under `single` the early trees are not tested: they pass),
//   keeps those that pass (under `reorder` only those not drawn early: the final pass's lists,
//   forestlod_shared::final_includes_early) at `occlusion_slot(1, lod, m, off) + k`, counts, and
//   marks every tree that passed (early trees under `single` included) in
//   `history[u.history_write + tree]` (cleared by the driver first: a tree of two commands passes
//   when either passes).
// The command becomes `first_instance = slot`, `instance_count = kept`; commands are never
// removed, and base_vertex, the index range and the data stay the frame's.
//
// Passes, in this order (every loop bounded: llvmpipe stops any loop after 65,535 iterations):
// 1. `occlude_prepare`, one invocation per slot: the largest chunk count ceil(len / 64).
// 2. `occlude_args`, one invocation: the indirect grid of passes 3 and 5, (ceil(max_chunks / 64),
//    y, z) with y·z >= counters.commands slots.
// 2b. `occlude_nearest` (early phase only), the grid of pass 3: under `single` the min-reduction
//    of forestlod_shared::nearest_occluder_depth (an atomicMax of an order-reversing encoding of
//    non-negative depths, `state.nearest`), which both phases' early rule reads.
// 3. `occlude_count`, one invocation per (chunk, slot): the chunk's kept count (a loop of at most
//    64 trees) at `chunk_counts[min(lod, 1)·2m + 2·off + chunk]` (the command's own entries: the
//    commands of one LOD never overlap).
// 4. `occlude_scan`, one invocation per slot: the exclusive prefix of its chunk counts in place,
//    the total after them (a loop of ceil(len / 64) <= 65,535 iterations: len <= the tree count,
//    at most MAX_OCCLUDE_TREES).
// 5. `occlude_write`, the grid of pass 3: the same tests in the same order, each kept tree written
//    from the chunk's prefix on; in the late phase also the counters and the history.
// 6. `occlude_finalize`, one invocation per slot: the command rewritten, kept trees counted.

// Keep in sync with forestlod_gpu::occlude::OccludeUniform (gpu/src/occlude.rs).
struct OccludeUniform {
    view_proj: mat4x4<f32>,
    // The pyramid's levels, (width, height, offset, 0) each; `level_count` of them are used.
    levels: array<vec4<u32>, 16>,
    eye: vec3<f32>,
    near: f32,
    forward: vec3<f32>,
    occluder_depth: f32,
    mode: u32,
    phase: u32,
    m: u32,
    tree_count: u32,
    fade_mode: u32,
    subset_mode: u32,
    width: u32,
    height: u32,
    level_count: u32,
    history_read: u32,
    history_write: u32,
    max_workgroups: u32,
    // 1 when the final pass's lists hold the early trees too (forestlod_shared::
    // final_includes_early of `params.occlusion_order`: `exact`), 0 under `reorder`.
    final_with_early: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// The grid of the count and write passes and the largest chunk count. Keep in sync with
// forestlod_gpu::occlude::OccludeDispatch.
struct OccludeDispatch {
    x: u32,
    y: u32,
    z: u32,
    max_chunks: atomic<u32>,
}

// The stage's counters (forestlod_shared::OcclusionCounters, cleared per frame) and the grid
// (cleared per phase). Keep in sync with forestlod_gpu::occlude::OccludeState.
struct OccludeState {
    counters: OcclusionCountersAtomic,
    dispatch: OccludeDispatch,
    // `single`'s nearest occluder depth (forestlod_shared::nearest_occluder_depth) as
    // `NEAREST_NONE_BITS - bits`: 0 (cleared) is none, a larger value a nearer depth, so that an
    // atomicMax of non-negative depths is their minimum.
    nearest: atomic<u32>,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// The bits of +infinity: `nearest`'s encoding (above) and no depth.
const NEAREST_NONE_BITS: u32 = 0x7f800000u;

// OCCLUDE_WORKGROUP_SIZE (also the trees per chunk; gpu/src/occlude.rs, SOURCE), the OCCLUSION_*
// mode ids and the slacks: generated from Rust.

@group(0) @binding(0) var<uniform> u: OccludeUniform;
// Per tree: its footprint sphere (base position, footprint radius).
@group(0) @binding(1) var<storage, read> footprints: array<vec4<f32>>;
// 5m entries: [0, 4m) the early and late lists (occlusion_slot), [4m, 5m) the frame's
// indirection (copied in by the driver, only read here).
@group(0) @binding(2) var<storage, read_write> indirection: array<u32>;
@group(0) @binding(3) var<storage, read_write> commands: array<DrawCommand>;
@group(0) @binding(4) var<storage, read> command_data: array<CommandData>;
@group(0) @binding(5) var<storage, read> counters: SelectCounters;
@group(0) @binding(6) var<storage, read_write> state: OccludeState;
// 4m entries: per LOD L and command of input offset `off`, `[min(L, 1)·2m + 2·off, + chunks]`.
@group(0) @binding(7) var<storage, read_write> chunk_counts: array<u32>;
@group(0) @binding(8) var<storage, read> pyramid: array<f32>;
// 2n entries: two halves, read (the previous frame's) and written (this frame's).
@group(0) @binding(9) var<storage, read_write> history: array<u32>;

// A tree's footprint's nearest view depth and bound (reference occlude.rs
// `EarlyRule::depth_and_bound`).
struct DepthAndBound {
    near: f32,
    bound: OcclusionBound,
}

fn depth_and_bound(tree: u32) -> DepthAndBound {
    let fp = footprints[tree];
    let near = view_interval(fp.xyz, fp.w, u.eye, u.forward).lo;
    let bound = occlusion_bounds(u.view_proj, u.near, fp.xyz, fp.w, u.width, u.height);
    return DepthAndBound(near, bound);
}

// `single`'s nearest occluder depth of this frame (pass 0), 0 when none.
fn nearest_depth() -> f32 {
    let s = atomicLoad(&state.nearest);
    if s == 0u {
        return 0.0;
    }
    return bitcast<f32>(NEAREST_NONE_BITS - s);
}

// reference occlude.rs `EarlyRule::early`: whether the tree is an occluder of a command with
// `data` (forestlod_shared::is_occluder, under the effective mode `u.mode`), with its bound.
struct Early {
    early: bool,
    bound: OcclusionBound,
}

fn early_tree(data: CommandData, tree: u32) -> Early {
    let d = depth_and_bound(tree);
    let before = history[u.history_read + tree] != 0u;
    let early = is_occluder(
        u.mode, data, u.fade_mode, u.subset_mode, u.occluder_depth, d.near - nearest_depth(), before,
        d.bound.kind,
    );
    return Early(early, d.bound);
}

// reference pyramid.rs `Pyramid::max_under`: the largest texel at pyramid_level_for's level under
// `rect` (forestlod_shared::pyramid_texels_max; at most 2x2 iterations).
fn pyramid_max_under(rect: vec4<u32>) -> f32 {
    let level = pyramid_level_for(rect, u.level_count);
    let l = u.levels[level];
    let i0 = rect.x >> level;
    let i1 = rect.z >> level;
    let j0 = rect.y >> level;
    let j1 = rect.w >> level;
    var m = -bitcast<f32>(0x7f7fffffu);
    for (var j = j0; j <= j1; j++) {
        for (var i = i0; i <= i1; i++) {
            m = max(m, pyramid[l.z + j * l.x + i]);
        }
    }
    return m;
}

// Outcome codes of one tree's late test (shader-private).
const LATE_EARLY_UNTESTED: u32 = 0u;
const LATE_UNBOUNDED: u32 = 1u;
const LATE_OFFSCREEN: u32 = 2u;
const LATE_OCCLUDED: u32 = 3u;
const LATE_VISIBLE: u32 = 4u;

// One tree of a command in this phase: whether it is kept in the phase's list, and (late phase)
// the test's outcome and whether it passed.
struct TreeOutcome {
    keep: bool,
    passed: bool,
    outcome: u32,
}

fn tree_outcome(data: CommandData, tree: u32) -> TreeOutcome {
    let e = early_tree(data, tree);
    let early = e.early;
    if u.phase == 0u {
        return TreeOutcome(early, false, LATE_EARLY_UNTESTED);
    }
    let with_early = u.final_with_early != 0u;
    if early && u.mode == OCCLUSION_SINGLE {
        return TreeOutcome(with_early, true, LATE_EARLY_UNTESTED);
    }
    let b = e.bound;
    var outcome = LATE_UNBOUNDED;
    if b.kind == BOUND_OFFSCREEN {
        outcome = LATE_OFFSCREEN;
    } else if b.kind == BOUND_RECT {
        outcome = select(LATE_VISIBLE, LATE_OCCLUDED, occluded(b.z_min, pyramid_max_under(b.rect)));
    }
    let passed = outcome == LATE_UNBOUNDED || outcome == LATE_VISIBLE;
    return TreeOutcome(passed && (with_early || !early), passed, outcome);
}

fn chunk_count(len: u32) -> u32 {
    return (len + OCCLUDE_WORKGROUP_SIZE - 1u) / OCCLUDE_WORKGROUP_SIZE;
}

// Start of the command's entries in `chunk_counts` (module header).
fn chunk_base(lod: u32, off: u32) -> u32 {
    return min(lod, 1u) * 2u * u.m + 2u * off;
}

struct Invocation {
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
}

// The slot of a one-invocation-per-slot pass (ceil(capacity / 64) workgroups, spilling into y).
fn slot_of(inv: Invocation) -> u32 {
    return (inv.wid.y * inv.groups.x + inv.wid.x) * OCCLUDE_WORKGROUP_SIZE + inv.lid;
}

// Pass 1: the largest chunk count of the commands.
@compute @workgroup_size(OCCLUDE_WORKGROUP_SIZE)
fn occlude_prepare(inv: Invocation) {
    let slot = slot_of(inv);
    if slot >= counters.commands {
        return;
    }
    atomicMax(&state.dispatch.max_chunks, chunk_count(commands[slot].instance_count));
}

// Pass 2: the grid of the count and write passes (x: workgroups of 64 chunks, y·z: slots).
@compute @workgroup_size(1)
fn occlude_args() {
    let chunks = atomicLoad(&state.dispatch.max_chunks);
    let slots = counters.commands;
    if chunks == 0u || slots == 0u {
        state.dispatch.x = 0u;
        state.dispatch.y = 0u;
        state.dispatch.z = 0u;
        return;
    }
    let y = min(slots, u.max_workgroups);
    state.dispatch.x = (chunks + OCCLUDE_WORKGROUP_SIZE - 1u) / OCCLUDE_WORKGROUP_SIZE;
    state.dispatch.y = y;
    state.dispatch.z = (slots + y - 1u) / y;
}

// The invocation's chunk of a command, or `ok = false` when it has nothing to do.
struct Chunk {
    ok: bool,
    data: CommandData,
    off: u32,
    chunk: u32,
    src: u32,
    first: u32,
    end: u32,
}

fn invocation_chunk(inv: Invocation) -> Chunk {
    var c: Chunk;
    c.ok = false;
    c.chunk = inv.wid.x * OCCLUDE_WORKGROUP_SIZE + inv.lid;
    let slot = inv.wid.z * inv.groups.y + inv.wid.y;
    if slot >= counters.commands {
        return c;
    }
    c.data = command_data[slot];
    let command = commands[slot];
    c.off = command.first_instance;
    let len = command.instance_count;
    c.ok = c.chunk < chunk_count(len);
    c.src = 4u * u.m + c.off;
    c.first = c.chunk * OCCLUDE_WORKGROUP_SIZE;
    c.end = min(c.first + OCCLUDE_WORKGROUP_SIZE, len);
    return c;
}

// Pass 0 (early phase, effective mode `single`): the min-reduction of
// forestlod_shared::nearest_occluder_depth over the chunk's trees of mesh commands that may
// occlude, whose bound is not off screen (a loop of at most 64 iterations).
@compute @workgroup_size(OCCLUDE_WORKGROUP_SIZE)
fn occlude_nearest(inv: Invocation) {
    let c = invocation_chunk(inv);
    if !c.ok || u.mode != OCCLUSION_SINGLE || c.data.lod != LOD_MESH
        || !may_occlude(c.data, u.fade_mode, u.subset_mode) {
        return;
    }
    var best = 0u;
    for (var j = c.first; j < c.end; j++) {
        let d = depth_and_bound(indirection[c.src + j]);
        if d.bound.kind != BOUND_OFFSCREEN {
            // max(near, 0), without a negative zero.
            let bits = select(bitcast<u32>(d.near), 0u, d.near <= 0.0);
            best = max(best, NEAREST_NONE_BITS - bits);
        }
    }
    if best != 0u {
        atomicMax(&state.nearest, best);
    }
}

// Pass 3: each chunk's kept count (a loop of at most 64 iterations).
@compute @workgroup_size(OCCLUDE_WORKGROUP_SIZE)
fn occlude_count(inv: Invocation) {
    let c = invocation_chunk(inv);
    if !c.ok {
        return;
    }
    var kept = 0u;
    for (var j = c.first; j < c.end; j++) {
        kept += u32(tree_outcome(c.data, indirection[c.src + j]).keep);
    }
    chunk_counts[chunk_base(c.data.lod, c.off) + c.chunk] = kept;
}

// Pass 4: per command, the exclusive prefix of its chunk counts and their total.
@compute @workgroup_size(OCCLUDE_WORKGROUP_SIZE)
fn occlude_scan(inv: Invocation) {
    let slot = slot_of(inv);
    if slot >= counters.commands {
        return;
    }
    let command = commands[slot];
    let chunks = chunk_count(command.instance_count);
    if chunks == 0u {
        return;
    }
    let base = chunk_base(command_data[slot].lod, command.first_instance);
    var sum = 0u;
    for (var k = 0u; k < chunks; k++) {
        let count = chunk_counts[base + k];
        chunk_counts[base + k] = sum;
        sum += count;
    }
    chunk_counts[base + chunks] = sum;
}

// Pass 5: the kept trees in list order (the same loop as pass 3); the late phase's counters and
// history.
@compute @workgroup_size(OCCLUDE_WORKGROUP_SIZE)
fn occlude_write(inv: Invocation) {
    let c = invocation_chunk(inv);
    if !c.ok {
        return;
    }
    var k = occlusion_slot(u.phase, c.data.lod, u.m, c.off)
        + chunk_counts[chunk_base(c.data.lod, c.off) + c.chunk];
    var tested = 0u;
    var unbounded = 0u;
    var offscreen = 0u;
    var hidden = 0u;
    for (var j = c.first; j < c.end; j++) {
        let tree = indirection[c.src + j];
        let t = tree_outcome(c.data, tree);
        if t.keep {
            indirection[k] = tree;
            k++;
        }
        tested += u32(t.outcome != LATE_EARLY_UNTESTED);
        unbounded += u32(t.outcome == LATE_UNBOUNDED);
        offscreen += u32(t.outcome == LATE_OFFSCREEN);
        hidden += u32(t.outcome == LATE_OCCLUDED);
        if t.passed {
            history[u.history_write + tree] = 1u;
        }
    }
    if u.phase == 1u {
        atomicAdd(&state.counters.tested, tested);
        atomicAdd(&state.counters.unbounded, unbounded);
        atomicAdd(&state.counters.offscreen, offscreen);
        atomicAdd(&state.counters.occluded, hidden);
    }
}

// Pass 6: the commands rewritten, the early or late trees counted.
@compute @workgroup_size(OCCLUDE_WORKGROUP_SIZE)
fn occlude_finalize(inv: Invocation) {
    let slot = slot_of(inv);
    if slot >= counters.commands {
        return;
    }
    let lod = command_data[slot].lod;
    let off = commands[slot].first_instance;
    let len = commands[slot].instance_count;
    var kept = 0u;
    if len != 0u {
        kept = chunk_counts[chunk_base(lod, off) + chunk_count(len)];
    }
    commands[slot].first_instance = occlusion_slot(u.phase, lod, u.m, off);
    commands[slot].instance_count = kept;
    if u.phase == 0u {
        atomicAdd(&state.counters.early, kept);
    } else {
        atomicAdd(&state.counters.late, kept);
    }
}
