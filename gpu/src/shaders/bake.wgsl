// bake.wgsl: the billboard bake (E Alg. 3.1, E§4.1; SPEC §5.1). The GPU twin of
// reference/src/bake.rs (`bake_clip`, `bake_layer`), driven by gpu/src/bake.rs; common.wgsl is
// prepended.
//
// Contract (the reference's module docs, repeated): layer `mesh * K + k` of the billboard array
// texture holds mesh `mesh` seen from the fixed azimuth +X at elevation e_k = 90° / (K - 1) · k
// (with J azimuth views, issue 30/E§7: layer `mesh·K·J + k·J + j` holds it seen from the
// mesh-local azimuth φ_j = 2π·j/J, the mesh first turned into that view's frame by common.wgsl
// `azimuth_to_view`, the identity for j = 0),
// through an orthographic projection fitted to the mesh's bounding box: `[-W, W]` along the
// billboard's right vector R = +Y and `[bottom, bottom + height]` along its tilted up vector
// U_k = Z cos e - X sin e (forestlod_shared::billboard_extent), depth 0 at the near side of the
// bounding sphere and 1 at the far side. Unlit: the fragment is the mesh texture's level 0,
// sampled bilinearly with clamp-to-edge (the sRGB texture decodes before filtering), discarded
// when its alpha is 0; the pipeline state does the rest (depth test LESS with writes into a
// Depth32Float attachment cleared to 1, colour REPLACE into an Rgba8UnormSrgb layer cleared to
// transparent black, no culling), as the reference rasterizer does (reference/src/raster.rs).
//
// `bake_vs` is reference `bake_clip_view` operation for operation, in the same order. The
// per-layer constants that need transcendental functions (sin and cos of the elevation and the
// azimuth) or come from the
// shared extent formula are computed once on the CPU with the very calls the reference makes
// (`bake_elevation(k, K).sin_cos()`, `billboard_extent`) and passed in `BakeLayer`: WGSL's sin
// and cos have implementation-defined precision, so recomputing them here would move vertices.

// Keep in sync with forestlod_gpu::bake::BakeLayer (gpu/src/bake.rs). One per layer, bound with a
// dynamic offset.
struct BakeLayer {
    // MeshMeta::bbox_min.
    bbox_min: vec3<f32>,
    // MeshMeta::sphere_radius.
    sphere_radius: f32,
    // MeshMeta::bbox_max.
    bbox_max: vec3<f32>,
    // sin of the layer's elevation (f32 `sin_cos`, as the reference).
    sin_e: f32,
    // cos of the layer's elevation.
    cos_e: f32,
    // billboard_extent(meta, elevation).half_width.
    half_width: f32,
    // billboard_extent(meta, elevation).bottom.
    bottom: f32,
    // billboard_extent(meta, elevation).height.
    height: f32,
    // sin and cos of the view's azimuth (f32 `sin_cos` of forestlod_shared::bake_azimuth).
    sin_a: f32,
    cos_a: f32,
    _pad0: f32,
    _pad1: f32,
    // Octahedral frames (issue 32): the frame's basis and direction (computed on the CPU as the
    // reference computes them) and whether this layer is one.
    frame_right: vec3<f32>,
    octahedral: u32,
    frame_up: vec3<f32>,
    _pad2: f32,
    frame_dir: vec3<f32>,
    _pad3: f32,
}

// f32::MIN_POSITIVE, the floor of every divisor of bake_clip.
const F32_MIN_POSITIVE: f32 = 1.17549435e-38;

@group(0) @binding(0) var<uniform> layer: BakeLayer;
// The mesh's texture, level 0 only, Rgba8UnormSrgb.
@group(0) @binding(1) var mesh_texture: texture_2d<f32>;
// Bilinear, clamp-to-edge.
@group(0) @binding(2) var mesh_sampler: sampler;

struct BakeVertex {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

// reference `bake_clip_view`: orthographic clip-space position of mesh-local point `p_mesh`.
fn bake_clip(p_mesh: vec3<f32>) -> vec4<f32> {
    let p = azimuth_to_view(p_mesh, layer.sin_a, layer.cos_a);
    let s = layer.sin_e;
    let c = layer.cos_e;
    // h = +X, R = Z × h = +Y, U = Z cos e - h sin e, V = h cos e + Z sin e (toward the viewer).
    let right = p.y;
    let up = p.z * c - p.x * s;
    let toward_viewer = p.x * c + p.z * s;
    let half_width = max(layer.half_width, F32_MIN_POSITIVE);
    let height = max(layer.height, F32_MIN_POSITIVE);
    // Depth 0 at the nearest point of the bounding sphere, 1 at the farthest.
    let center = azimuth_to_view(
        vec3<f32>(
            (layer.bbox_min.x + layer.bbox_max.x) * 0.5,
            (layer.bbox_min.y + layer.bbox_max.y) * 0.5,
            (layer.bbox_min.z + layer.bbox_max.z) * 0.5,
        ),
        layer.sin_a,
        layer.cos_a,
    );
    let center_toward = center.x * c + center.z * s;
    let radius = max(layer.sphere_radius, F32_MIN_POSITIVE);
    let depth = (center_toward + radius - toward_viewer) / (2.0 * radius);
    return vec4<f32>(
        right / half_width,
        (up - layer.bottom) / height * 2.0 - 1.0,
        depth,
        1.0,
    );
}

// reference `octahedral_clip` (issue 32): the frame's square [-S, S]² about the bounding-box
// centre on its basis, depth 0 at the sphere's point nearest the viewer.
fn octahedral_clip(p: vec3<f32>) -> vec4<f32> {
    let c = vec3<f32>(
        (layer.bbox_min.x + layer.bbox_max.x) * 0.5,
        (layer.bbox_min.y + layer.bbox_max.y) * 0.5,
        (layer.bbox_min.z + layer.bbox_max.z) * 0.5,
    );
    let o = vec3<f32>(p.x - c.x, p.y - c.y, p.z - c.z);
    let s = max(layer.sphere_radius, F32_MIN_POSITIVE);
    let r = layer.frame_right;
    let u = layer.frame_up;
    let d = layer.frame_dir;
    let dr = o.x * r.x + o.y * r.y + o.z * r.z;
    let du = o.x * u.x + o.y * u.y + o.z * u.z;
    let dd = o.x * d.x + o.y * d.y + o.z * d.z;
    return vec4<f32>(dr / s, du / s, (s - dd) / (2.0 * s), 1.0);
}

@vertex
fn bake_vs(@location(0) position: vec3<f32>, @location(1) uv: vec2<f32>) -> BakeVertex {
    if layer.octahedral != 0u {
        return BakeVertex(octahedral_clip(position), uv);
    }
    return BakeVertex(bake_clip(position), uv);
}

// reference `bake_layer`'s shader: level 0, bilinear; alpha exactly 0 is discarded.
@fragment
fn bake_fs(v: BakeVertex) -> @location(0) vec4<f32> {
    let texel = textureSampleLevel(mesh_texture, mesh_sampler, v.uv, 0.0);
    if !(texel.a > 0.0) {
        discard;
    }
    return texel;
}

// The octahedral impostors' depth channel (issue 32; reference `bake_depth_view`): the same
// render writing the kept fragment's depth in red and the texel's alpha.
@fragment
fn bake_depth_fs(v: BakeVertex) -> @location(0) vec4<f32> {
    let texel = textureSampleLevel(mesh_texture, mesh_sampler, v.uv, 0.0);
    if !(texel.a > 0.0) {
        discard;
    }
    return vec4<f32>(v.clip.z, 0.0, 0.0, texel.a);
}
