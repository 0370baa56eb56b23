// primitive.wgsl: the Primitive baseline of E§5 (SPEC §9), twin of reference/src/baselines.rs
// `render_primitive`; driven by gpu/src/primitive.rs; common.wgsl is prepended. The ground of the
// same pass is draw.wgsl's (gpu/src/draw.rs `terrain_pipeline`), not repeated here.
//
// ONE non-indexed `draw_indirect` of 6 vertices per visible tree, its instance count written by
// cull.wgsl: the vertex stage takes the tree from the compacted indirection
// (`indirection[instance_index]`) and places the camera-facing quad of `primitive_quad`; the
// fragment stage ray-casts the tree's proxy (a sphere on a cylinder) like `Proxy::intersect`,
// operation for operation, and writes the hit's depth (`@builtin(frag_depth)`, the
// `gl_FragDepth` of E§5), a flat colour and LOD_ID_MESH.

// Keep in sync with forestlod_shared::ProxyRecord (shared/src/types.rs).
struct ProxyRecord {
    crown_radius: f32,
    crown_z: f32,
    trunk_radius: f32,
    bottom_z: f32,
    color: array<f32, 3>,
    _pad0: u32,
}

// Keep in sync with forestlod_gpu::primitive::PrimitiveUniform (gpu/src/primitive.rs), derived
// on the CPU from the camera as the reference's `primitive_quad` and `render_primitive` derive
// their constants.
struct PrimitiveUniform {
    view_proj: mat4x4<f32>,
    eye: vec3<f32>,
    near: f32,
    // Unit camera basis (`Camera::basis`).
    forward: vec3<f32>,
    far: f32,
    right: vec3<f32>,
    // `NEAR_FALLBACK_FACTOR * near`: a proxy whose sphere comes nearer gets the full-screen quad.
    fallback_distance: f32,
    up: vec3<f32>,
    // `near * NEAR_FALLBACK_DEPTH`: the full-screen quad's view depth.
    fallback_depth: f32,
    // The full-screen quad's half-extents (`tan(fov_y / 2) * depth * NEAR_FALLBACK_MARGIN`, times
    // the aspect for x).
    fallback_half_x: f32,
    fallback_half_y: f32,
    // `PROXY_BOUND_SCALE` (reference `Proxy::bounding_radius`).
    bound_scale: f32,
    _pad0: u32,
}

// Keep in sync with gpu/src/draw.rs `DrawInstance` (and `struct DrawInstance` in draw.wgsl).
struct DrawInstance {
    position: array<f32, 3>,
    yaw: f32,
    scale: f32,
    mesh: u32,
}

// LOD_ID_MESH: generated from Rust (gpu/src/shaders.rs).

@group(0) @binding(0) var<uniform> u: PrimitiveUniform;
@group(0) @binding(1) var<storage, read> instances: array<DrawInstance>;
// The compacted visible trees of cull.wgsl.
@group(0) @binding(2) var<storage, read> indirection: array<u32>;
// One proxy per mesh.
@group(0) @binding(3) var<storage, read> proxies: array<ProxyRecord>;

struct PrimitiveVaryings {
    @builtin(position) clip: vec4<f32>,
    // World position on the quad (perspective-correct).
    @location(0) world: vec3<f32>,
    @location(1) @interpolate(flat) tree: u32,
}

struct PrimitiveOutput {
    @location(0) color: vec4<f32>,
    @location(1) lod_id: u32,
    @builtin(frag_depth) depth: f32,
}

// reference `Proxy::center_z`: the height of the proxy's bounding-box centre.
fn proxy_center_z(p: ProxyRecord) -> f32 {
    return 0.5 * (p.crown_z + p.crown_radius + p.bottom_z);
}

// reference `Proxy::bounding_radius`: the circumsphere of the proxy's bounding box, widened.
fn proxy_bounding_radius(p: ProxyRecord) -> f32 {
    let half_h = 0.5 * (p.crown_z + p.crown_radius - p.bottom_z);
    return sqrt(2.0 * p.crown_radius * p.crown_radius + half_h * half_h) * u.bound_scale;
}

// `dot3` (common.wgsl) is glam's `Vec3::dot`, written out to keep its order of operations.

// reference `primitive_vertex` of `render_primitive` and `primitive_quad`: corner `corner`
// (0..4: -x-y, +x-y, +x+y, -x+y) of the quad of the sphere `(center, radius)`.
fn primitive_quad_corner(center: vec3<f32>, radius: f32, corner: u32) -> vec3<f32> {
    let rel = center - u.eye;
    let d_c = dot3(rel, u.forward);
    var mid: vec3<f32>;
    var half_x: f32;
    var half_y: f32;
    if d_c - radius < u.fallback_distance {
        mid = u.eye + u.forward * u.fallback_depth;
        half_x = u.fallback_half_x;
        half_y = u.fallback_half_y;
    } else {
        let d_q = d_c - radius;
        let off = rel - u.forward * d_c;
        let lat = sqrt(dot3(off, off));
        let half = radius * (1.0 + lat / d_c);
        mid = u.eye + rel * (d_q / d_c);
        half_x = half;
        half_y = half;
    }
    // `mid ∓ right·hx ∓ up·hy` of the reference: negating a product is exact, so adding
    // `right·(±hx)` rounds exactly as subtracting `right·hx`.
    let sx = select(-1.0, 1.0, corner == 1u || corner == 2u);
    let sy = select(-1.0, 1.0, corner >= 2u);
    return mid + u.right * (sx * half_x) + u.up * (sy * half_y);
}

@vertex
fn primitive_vertex(
    @builtin(vertex_index) vertex_index: u32,
    @builtin(instance_index) instance_index: u32,
) -> PrimitiveVaryings {
    // The reference's triangles [v0, v1, v2], [v0, v2, v3].
    var corners = array<u32, 6>(0u, 1u, 2u, 0u, 2u, 3u);
    let tree = indirection[instance_index];
    let t = instances[tree];
    let proxy = proxies[t.mesh];
    let base = vec3<f32>(t.position[0], t.position[1], t.position[2]);
    let center = vec3<f32>(base.x, base.y, base.z + proxy_center_z(proxy) * t.scale);
    let radius = proxy_bounding_radius(proxy) * t.scale;
    let p = primitive_quad_corner(center, radius, corners[min(vertex_index, 5u)]);
    var out: PrimitiveVaryings;
    out.clip = u.view_proj * vec4<f32>(p, 1.0);
    out.world = p;
    out.tree = tree;
    return out;
}

// Result of `proxy_intersect`: `hit` false for the reference's `None`.
struct ProxyHit {
    hit: bool,
    t: f32,
}

// reference `Proxy::intersect`'s `take`: keep `t` when at or past `t_min` and nearer than the best.
fn take(best: ProxyHit, t: f32, t_min: f32) -> ProxyHit {
    if t >= t_min && (!best.hit || t < best.t) {
        return ProxyHit(true, t);
    }
    return best;
}

// reference `Proxy::intersect`: nearest `t >= t_min` where `origin + t·dir` meets the proxy of a
// tree standing at `base` with `scale`. Same operations in the same order.
fn proxy_intersect(p: ProxyRecord, base: vec3<f32>, scale: f32, origin: vec3<f32>, dir: vec3<f32>, t_min: f32) -> ProxyHit {
    var best = ProxyHit(false, 0.0);
    // Sphere.
    let c = vec3<f32>(base.x, base.y, base.z + p.crown_z * scale);
    let r = p.crown_radius * scale;
    let oc = origin - c;
    let a = dot3(dir, dir);
    let b = dot3(oc, dir);
    let disc = b * b - a * (dot3(oc, oc) - r * r);
    if disc >= 0.0 {
        let s = sqrt(disc);
        best = take(best, (-b - s) / a, t_min);
        best = take(best, (-b + s) / a, t_min);
    }
    // Vertical cylinder from the bottom to the crown centre, no caps.
    let rt = p.trunk_radius * scale;
    let z0 = base.z + p.bottom_z * scale;
    let z1 = c.z;
    let ox = origin.x - base.x;
    let oy = origin.y - base.y;
    let a2 = dir.x * dir.x + dir.y * dir.y;
    if a2 > 0.0 {
        let b2 = ox * dir.x + oy * dir.y;
        let disc2 = b2 * b2 - a2 * (ox * ox + oy * oy - rt * rt);
        if disc2 >= 0.0 {
            let s2 = sqrt(disc2);
            let t0 = (-b2 - s2) / a2;
            let z_0 = origin.z + t0 * dir.z;
            if z_0 >= z0 && z_0 <= z1 {
                best = take(best, t0, t_min);
            }
            let t1 = (-b2 + s2) / a2;
            let z_1 = origin.z + t1 * dir.z;
            if z_1 >= z0 && z_1 <= z1 {
                best = take(best, t1, t_min);
            }
        }
    }
    return best;
}

// reference `render_primitive`'s fragment shader.
@fragment
fn primitive_fragment(in: PrimitiveVaryings) -> PrimitiveOutput {
    let t = instances[in.tree];
    let proxy = proxies[t.mesh];
    var dir = in.world - u.eye;
    let along = dot3(dir, u.forward);
    if along <= 0.0 {
        discard;
    }
    // Scale the ray so that t is the view depth, then clip to the near plane.
    dir = dir / along;
    let base = vec3<f32>(t.position[0], t.position[1], t.position[2]);
    let hit = proxy_intersect(proxy, base, t.scale, u.eye, dir, u.near);
    if !hit.hit || hit.t > u.far {
        discard;
    }
    var out: PrimitiveOutput;
    // wgpu depth of view depth t: far (t - near) / ((far - near) t).
    out.depth = u.far * (hit.t - u.near) / ((u.far - u.near) * hit.t);
    out.color = vec4<f32>(proxy.color[0], proxy.color[1], proxy.color[2], 1.0);
    out.lod_id = LOD_ID_MESH;
    return out;
}
