// pyramid.wgsl: the depth pyramid of occlusion culling (issue 31), the GPU twin of
// reference/src/pyramid.rs; driven by gpu/src/pyramid.rs; common.wgsl is prepended. Layout and
// reduction: forestlod_shared::occlusion (`pyramid_levels`, `pyramid_reduce`).
//
// One flat storage buffer of f32 holds every level, one after the other, rows top-down: level L
// is ceil(W / 2^L) x ceil(H / 2^L) texels from its `offset` on, down to 1x1. Dispatches, in
// order, one invocation per texel of the level written (8x8 workgroups, no loop):
// 1. `pyramid_copy`: level 0 is the depth texture, texel for texel (`textureLoad`, exact).
// 2. `pyramid_reduce_level`, once per level L + 1 >= 1: the largest of the up to 2x2 texels of
//    level L that exist (`pyramid_reduce_texels` clamps the second column and row to the level),
//    so texel (i, j) of level L is the exact maximum of its 2^L x 2^L block of pixels clipped to
//    the frame, at every size (odd and non-power-of-two included). `max` rounds nothing, so the
//    GPU's pyramid equals the reference's bit for bit.

// The levels one dispatch reads and writes: (width, height, offset, 0) each. Keep in sync with
// forestlod_gpu::pyramid::PyramidStep (gpu/src/pyramid.rs); one slot per dispatch, picked by a
// dynamic offset.
struct PyramidStep {
    below: vec4<u32>,
    level: vec4<u32>,
}

@group(0) @binding(0) var<uniform> step: PyramidStep;
// The depth target (its depth aspect, bound as an unfilterable float texture, as
// depth_copy.wgsl reads it), or an R32Float texture of the same values (tests).
@group(0) @binding(1) var depth_texture: texture_2d<f32>;
@group(0) @binding(2) var<storage, read_write> texels: array<f32>;

// Level 0: the depth buffer (`step.level` is level 0).
@compute @workgroup_size(PYRAMID_WORKGROUP_SIDE, PYRAMID_WORKGROUP_SIDE)
fn pyramid_copy(@builtin(global_invocation_id) id: vec3<u32>) {
    let level = step.level;
    if id.x < level.x && id.y < level.y {
        texels[level.z + id.y * level.x + id.x] = textureLoad(depth_texture, vec2<i32>(id.xy), 0).x;
    }
}

// Level `step.level` from `step.below` (forestlod_shared::pyramid_reduce).
@compute @workgroup_size(PYRAMID_WORKGROUP_SIDE, PYRAMID_WORKGROUP_SIDE)
fn pyramid_reduce_level(@builtin(global_invocation_id) id: vec3<u32>) {
    let level = step.level;
    let below = step.below;
    if id.x >= level.x || id.y >= level.y {
        return;
    }
    let s = pyramid_reduce_texels(below.xy, id.x, id.y);
    let row0 = below.z + s.y * below.x;
    let row1 = below.z + s.w * below.x;
    texels[level.z + id.y * level.x + id.x] = pyramid_reduce_max(
        texels[row0 + s.x],
        texels[row0 + s.z],
        texels[row1 + s.x],
        texels[row1 + s.z],
    );
}
