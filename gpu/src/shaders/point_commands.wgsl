// point_commands.wgsl: the point LOD's command expansion (issue 33 item 1; C§4.4, §4.6.3;
// forestlod_shared::points, "the point command path"), driven by gpu/src/draw.rs before the draw
// pass under `lod1 = points`. Prepended by common.wgsl.
//
// The draw reads a per-frame COPY of the selection's commands; this pass rewrites, in that copy,
// every point command (a LOD1 command: `billboard != 0`, not the far level) of a mesh with `n`
// records into `trees × n` instances of one quad over the 6-index iota range:
// `instance_count *= n`, `first_instance *= n`. `draw.wgsl` decodes instance index `i` as
// indirection entry `i / n` (the batch's tree, in the command's tree order) and record rank
// `i % n` (in the mode's order), so the instances run tree by tree and, per tree, record by
// record: the reference's draw order. `base_vertex` (the slot) is untouched. One invocation per
// slot, no loop.

// Keep in sync with gpu/src/draw.rs `PointCommandUniform`.
struct PointCommandUniform {
    // First word of the point header in `words` (gpu/src/draw.rs `point_words`).
    point_base: u32,
    // First index of an iota range of at least 6 indices (the far level's, 0..6).
    quad_first_index: u32,
    // Command slots in the buffers.
    capacity: u32,
    // Meshes in the point header.
    mesh_count: u32,
}

@group(0) @binding(0) var<uniform> pc: PointCommandUniform;
@group(0) @binding(1) var<storage, read> command_data: array<CommandData>;
@group(0) @binding(2) var<storage, read> counters: SelectCounters;
@group(0) @binding(3) var<storage, read> words: array<u32>;
@group(0) @binding(4) var<storage, read_write> commands: array<DrawCommand>;

@compute @workgroup_size(256)
fn expand_point_commands(@builtin(global_invocation_id) id: vec3<u32>) {
    let slot = id.x;
    if slot >= pc.capacity || slot >= counters.commands {
        return;
    }
    let data = command_data[slot];
    if data.billboard == 0u || data.lod == LOD_FAR {
        return;
    }
    var cmd = commands[slot];
    var n = 0u;
    if data.mesh < pc.mesh_count {
        n = words[pc.point_base + 3u * data.mesh + 1u];
    }
    cmd.index_count = 6u;
    cmd.first_index = pc.quad_first_index;
    cmd.first_instance = cmd.first_instance * n;
    cmd.instance_count = cmd.instance_count * n;
    commands[slot] = cmd;
}
