// command_order.wgsl: distance-sorted commands, front to back (issue 13; E§7 "distance-sorted
// commands"). The GPU twin of reference/src/command_order.rs, driven by gpu/src/command_order.rs;
// common.wgsl is added before it.
//
// Contract (the reference's module docs, repeated): run r (a coalesced command) has the key
// min over its raw commands j of command_depth_key(node_near_depth(node of j)); the runs are
// sorted by (key, r) ascending; output command i is run pairs[i].r's command and data with
// base_vertex = i << COMMAND_SHIFT. Counters are unchanged.
//
// Two bind-group layouts from this one module, because one would need 10 storage buffers and a
// stage may bind 8: the *keys* layout (bindings 0, 2..8) and the *sort* layout (0, 1, 7, 9..13).
// Entry points (every loop is bounded: there are none; the sort is one dispatch per merge step):
//   `order_init`   (keys; one invocation per pair slot): pairs[i] = (u32::MAX, i); invocation 0
//                  writes the sort steps' indirect dispatch (n_pow2 / 2 invocations);
//   `order_keys`   (keys; one invocation per raw command): atomicMin of its node's key into its
//                  run's pair (run = offsets[j + 1] - 1, the coalescing's exclusive scan of head
//                  flags, or the run count - 1 for the last raw command);
//   `order_step`   (sort; indirect, one invocation per compared pair): one bitonic merge step
//                  (k, j) over the first n_pow2 pairs, skipped when k > n_pow2 (the list is
//                  sorted already); padding pairs (u32::MAX, slot >= n) stay behind every run;
//   `order_gather` (sort; one invocation per slot): the permuted commands and data.

// Keep in sync with forestlod_gpu::command_order::OrderUniform (gpu/src/command_order.rs).
struct OrderUniform {
    view: ViewUniform,
    // Command slots of the buffers (raw and coalesced).
    capacity: u32,
    // Pair slots: the power of two >= capacity.
    pair_capacity: u32,
    _pad0: u32,
    _pad1: u32,
}

// Keep in sync with forestlod_gpu::command_order::OrderStep. One per dynamic-offset slot.
struct OrderStep {
    k: u32,
    j: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> u: OrderUniform;
@group(0) @binding(1) var<uniform> sort_step: OrderStep;
// Keys layout.
@group(0) @binding(2) var<storage, read> nodes: array<NodeMeta>;
@group(0) @binding(3) var<storage, read> raw_data: array<CommandData>;
@group(0) @binding(4) var<storage, read> raw_counters: SelectCounters;
@group(0) @binding(5) var<storage, read> run_offsets: array<u32>;
@group(0) @binding(6) var<storage, read_write> key_pairs: array<atomic<u32>>;
// Both layouts: the coalesced counters (the run count).
@group(0) @binding(7) var<storage, read> counters: SelectCounters;
@group(0) @binding(8) var<storage, read_write> step_args: array<u32>;
// Sort layout (pairs is the buffer bound as key_pairs above).
@group(0) @binding(9) var<storage, read_write> pairs: array<u32>;
@group(0) @binding(10) var<storage, read> src_commands: array<DrawCommand>;
@group(0) @binding(11) var<storage, read> src_data: array<CommandData>;
@group(0) @binding(12) var<storage, read_write> commands: array<DrawCommand>;
@group(0) @binding(13) var<storage, read_write> command_data: array<CommandData>;

fn slot_index(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.y * (groups.x * COMMAND_ORDER_WORKGROUP_SIZE) + gid.x;
}

// The smallest power of two >= n (1 for n <= 1).
fn pow2_at_least(n: u32) -> u32 {
    if n <= 1u {
        return 1u;
    }
    return 1u << (32u - countLeadingZeros(n - 1u));
}

@compute @workgroup_size(COMMAND_ORDER_WORKGROUP_SIZE)
fn order_init(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = slot_index(gid, groups);
    if i == 0u {
        // n_pow2 / 2 invocations for every step, as an (x, y, 1) grid of at most 65,535 x.
        let n = counters.commands;
        var wg = 0u;
        if n > 1u {
            wg = (pow2_at_least(n) / 2u + COMMAND_ORDER_WORKGROUP_SIZE - 1u) / COMMAND_ORDER_WORKGROUP_SIZE;
        }
        let x = min(wg, 65535u);
        step_args[0] = x;
        step_args[1] = select(0u, (wg + x - 1u) / max(x, 1u), wg > 0u);
        step_args[2] = 1u;
    }
    if i >= u.pair_capacity {
        return;
    }
    atomicStore(&key_pairs[2u * i], 0xffffffffu);
    atomicStore(&key_pairs[2u * i + 1u], i);
}

@compute @workgroup_size(COMMAND_ORDER_WORKGROUP_SIZE)
fn order_keys(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let j = slot_index(gid, groups);
    let n = raw_counters.commands;
    if j >= n || j >= u.capacity {
        return;
    }
    // run_offsets[j + 1] counts the heads in 0..=j (exclusive scan); the last command is in the
    // last run.
    var run = counters.commands - 1u;
    if j + 1u < n {
        run = run_offsets[j + 1u] - 1u;
    }
    let key = command_depth_key(node_near_depth(nodes[raw_data[j].batch], u.view));
    atomicMin(&key_pairs[2u * run], key);
}

// Pair a precedes pair b: (key, index) lexicographically.
fn pair_less(ka: u32, ia: u32, kb: u32, ib: u32) -> bool {
    return ka < kb || (ka == kb && ia < ib);
}

@compute @workgroup_size(COMMAND_ORDER_WORKGROUP_SIZE)
fn order_step(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let t = slot_index(gid, groups);
    let n2 = pow2_at_least(counters.commands);
    if sort_step.k > n2 || t >= n2 / 2u {
        return;
    }
    // The t-th pair (a, a + j) of the step: a has bit j clear.
    let a = 2u * sort_step.j * (t / sort_step.j) + t % sort_step.j;
    let b = a + sort_step.j;
    let ascending = (a & sort_step.k) == 0u;
    let ka = pairs[2u * a];
    let ia = pairs[2u * a + 1u];
    let kb = pairs[2u * b];
    let ib = pairs[2u * b + 1u];
    if pair_less(kb, ib, ka, ia) == ascending {
        pairs[2u * a] = kb;
        pairs[2u * a + 1u] = ib;
        pairs[2u * b] = ka;
        pairs[2u * b + 1u] = ia;
    }
}

@compute @workgroup_size(COMMAND_ORDER_WORKGROUP_SIZE)
fn order_gather(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = slot_index(gid, groups);
    if i >= counters.commands || i >= u.capacity {
        return;
    }
    let r = pairs[2u * i + 1u];
    var c = src_commands[r];
    c.base_vertex = i32(i << COMMAND_SHIFT);
    commands[i] = c;
    command_data[i] = src_data[r];
}
