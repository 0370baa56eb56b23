// far_bake.wgsl: the far level's bake (issue 32 item 2; G§2.2-2.4), the GPU twin of
// reference/src/far_bake.rs; driven by gpu/src/far_bake.rs; common.wgsl is prepended. The
// contract is forestlod_shared::far_bake's module docs.
//
// 1. `far_bake_vs` / `far_bake_fs`: one render pass per (leaf, side, slice) into one layer of a
//    (cs · FAR_BAKE_PIXELS)² Rgba8UnormSrgb array, cleared to transparent black, with a
//    Depth32Float attachment cleared to 1, depth test LESS with writes, no culling, blend
//    REPLACE. The vertex is `FarView::clip` of the world-space corner (computed on the CPU with
//    `forestlod_shared::far_bake::tree_point`, as the reference places its trees); the
//    fragment is the draw's LOD0 texel (trilinear, implicit level of detail, the mesh's layer of
//    the mesh texture array), discarded below the alpha cutoff, written opaque. Unlit.
// 2. `far_bake_reduce`: one invocation per (layer, pixel block): the sums over the block's
//    FAR_BAKE_PIXELS² pixels, row by row, of (alpha · linear colour, alpha), in the order of
//    `forestlod_shared::far_bake::far_block_colour`. Its two loops are FAR_BAKE_PIXELS long
//    whatever the input (64 iterations). The CPU packs the sums (`block_colour`).

// Keep in sync with forestlod_shared::far_bake::FarView. One per pass, dynamic offset.
struct FarView {
    right: u32,
    up: u32,
    axis: u32,
    cs: u32,
    center: vec2<f32>,
    inv_extent: vec2<f32>,
    near: f32,
    far: f32,
    depth_scale: f32,
    side: u32,
    slice: u32,
    alpha_cutoff: f32,
    _pad: vec2<u32>,
}

// Keep in sync with forestlod_gpu::far_bake::FarReduce.
struct FarReduce {
    // Blocks per image side (cs).
    cs: u32,
    // Layers of this dispatch.
    layers: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> view: FarView;
// Every mesh texture with its mips, one layer per mesh (the draw's).
@group(0) @binding(1) var mesh_textures: texture_2d_array<f32>;
// The draw's trilinear sampler (clamp-to-edge).
@group(0) @binding(2) var far_sampler: sampler;

@group(0) @binding(3) var<uniform> reduce: FarReduce;
@group(0) @binding(4) var slices: texture_2d_array<f32>;
@group(0) @binding(5) var<storage, read_write> sums: array<vec4<f32>>;

struct FarBakeOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
    @location(1) @interpolate(flat) mesh: u32,
}

// forestlod_shared::far_bake::FarView::clip.
@vertex
fn far_bake_vs(
    @location(0) position: vec3<f32>,
    @location(1) mesh: u32,
    @location(2) uv: vec2<f32>,
) -> FarBakeOut {
    let clip = vec4<f32>(
        (position[view.right] - view.center.x) * view.inv_extent.x,
        (position[view.up] - view.center.y) * view.inv_extent.y,
        (position[view.axis] - view.near) * view.depth_scale,
        1.0,
    );
    return FarBakeOut(clip, uv, mesh);
}

// The draw's LOD0 texel and alpha test (reference `far_bake::render_view`'s shader).
@fragment
fn far_bake_fs(v: FarBakeOut) -> @location(0) vec4<f32> {
    let texel = textureSample(mesh_textures, far_sampler, v.uv, v.mesh);
    if texel.a < view.alpha_cutoff {
        discard;
    }
    return vec4<f32>(texel.rgb, 1.0);
}

// forestlod_shared::far_bake::far_block_colour's sums, one block per invocation.
@compute @workgroup_size(FAR_REDUCE_WORKGROUP)
fn far_bake_reduce(@builtin(global_invocation_id) id: vec3<u32>) {
    let blocks = reduce.cs * reduce.cs;
    let i = id.x;
    if i >= blocks * reduce.layers {
        return;
    }
    let layer = i / blocks;
    let b = i % blocks;
    let bx = b % reduce.cs;
    let by = b / reduce.cs;
    var sum_c = vec3<f32>(0.0);
    var sum_a = 0.0;
    for (var y = 0u; y < FAR_BAKE_PIXELS; y++) {
        for (var x = 0u; x < FAR_BAKE_PIXELS; x++) {
            let t = textureLoad(
                slices,
                vec2<u32>(bx * FAR_BAKE_PIXELS + x, by * FAR_BAKE_PIXELS + y),
                layer,
                0,
            );
            sum_c = sum_c + t.a * t.rgb;
            sum_a = sum_a + t.a;
        }
    }
    sums[i] = vec4<f32>(sum_c, sum_a);
}
