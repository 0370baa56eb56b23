// depth_copy.wgsl: reads a depth target back through a compute pass (`DrawTarget::read`, where a
// texture-to-buffer copy of the depth aspect is not available): one invocation per texel
// `textureLoad`s the depth (bound as an unfilterable float texture) into a storage buffer, row by
// row. Standalone (common.wgsl is not prepended); driven by gpu/src/draw.rs.

@group(0) @binding(0) var depth_texture: texture_2d<f32>;
@group(0) @binding(1) var<storage, read_write> out: array<f32>;

@compute @workgroup_size(8, 8)
fn copy_depth(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(depth_texture);
    if id.x < size.x && id.y < size.y {
        out[id.y * size.x + id.x] = textureLoad(depth_texture, vec2<i32>(id.xy), 0).x;
    }
}
