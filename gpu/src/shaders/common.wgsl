// common.wgsl: the WGSL mirror of forestlod-shared (SPEC §2, §3), prepended to every stage's
// shader by gpu/src/shaders.rs (WGSL has no include).
//
// Structs mirror the `#[repr(C)]` Pod structs of shared/src/*.rs field for field and in order.
// Every member is a 4-byte scalar or an array / vector of them, so the WGSL storage layout equals
// the Rust layout; `gpu/tests/layout.rs` checks every member offset and every struct size with
// naga's reflection against `core::mem::offset_of!` / `size_of`. Storage-only structs use
// `array<f32, 3>` for Rust `[f32; 3]` (stride 4, no vec3 padding trap); `Camera`, which the draw
// stage binds as a uniform (where arrays need a 16-byte stride), uses `vec3<f32>` where each vec3
// sits at a 16-byte offset followed by an f32, which is the same layout.
//
// Formulas repeat shared/src/interval.rs and shared/src/camera.rs operation for operation, in the
// same order (separate multiplies and adds, left to right). The GPU compiler may still contract a
// multiply and an add into one fused multiply-add, which rounds once instead of twice; the parity
// tests classify decisions within a small ε of a threshold as ambiguous for that reason (SPEC §8).

// Keep in sync with forestlod_shared::COMMAND_SHIFT (shared/src/lib.rs).
const COMMAND_SHIFT: u32 = 8u;
// Keep in sync with forestlod_shared::LOD_MESH / LOD_BILLBOARD.
const LOD_MESH: u32 = 0u;
const LOD_BILLBOARD: u32 = 1u;
// f32::EPSILON, 2^-23.
const F32_EPSILON: f32 = 1.1920929e-7;

// Keep in sync with forestlod_shared::Params (shared/src/params.rs).
struct Params {
    grid_size: f32,
    angle_count: u32,
    texture_size: u32,
    lod_levels: u32,
    lod1_transition: f32,
    fade_width: f32,
    draw_distance: f32,
    fade_mode: u32,
    mip_mode: u32,
    angle_index_mode: u32,
    alpha_cutoff: f32,
    _pad0: u32,
}

// Keep in sync with forestlod_shared::Camera (shared/src/camera.rs).
struct Camera {
    eye: vec3<f32>,
    fov_y: f32,
    forward: vec3<f32>,
    near: f32,
    up: vec3<f32>,
    far: f32,
    width: u32,
    height: u32,
    _pad0: vec2<u32>,
}

// Keep in sync with forestlod_shared::BatchMeta (shared/src/types.rs).
struct BatchMeta {
    center: array<f32, 3>,
    radius: f32,
    extent: array<f32, 3>,
    mesh: u32,
    box_center: array<f32, 3>,
    len: u32,
    cell: array<i32, 2>,
    offset: u32,
    _pad0: u32,
}

// Keep in sync with forestlod_shared::DrawCommand (shared/src/types.rs), which is
// wgpu::util::DrawIndexedIndirectArgs / VkDrawIndexedIndirectCommand.
struct DrawCommand {
    index_count: u32,
    instance_count: u32,
    first_index: u32,
    base_vertex: i32,
    first_instance: u32,
}

// Keep in sync with forestlod_shared::CommandData (shared/src/types.rs).
struct CommandData {
    fade_start: f32,
    fade_end: f32,
    batch: u32,
    mesh: u32,
    lod: u32,
    billboard: u32,
    fading: u32,
    _pad0: u32,
}

// Keep in sync with forestlod_shared::MeshMeta (shared/src/types.rs).
struct MeshMeta {
    first_index: u32,
    index_count: u32,
    first_vertex: u32,
    vertex_count: u32,
    bbox_min: array<f32, 3>,
    billboard_half_width: f32,
    bbox_max: array<f32, 3>,
    sphere_radius: f32,
}

// Keep in sync with forestlod_shared::SelectCounters (shared/src/types.rs).
struct SelectCounters {
    batches_tested: u32,
    culled_distance: u32,
    culled_frustum: u32,
    commands: u32,
    lod0_commands: u32,
    lod1_commands: u32,
    transition_batches: u32,
    instances: u32,
}

// Keep in sync with forestlod_shared::ViewInterval (shared/src/interval.rs).
struct ViewInterval {
    d: f32,
    lo: f32,
    hi: f32,
}

// Keep in sync with forestlod_shared::LodNeeds (shared/src/interval.rs).
struct LodNeeds {
    lod0: bool,
    lod1: bool,
}

// forestlod_shared::selection_margin: `4 ε (|rel|₁ + r)`, summed left to right.
fn selection_margin(rel: vec3<f32>, radius: f32) -> f32 {
    let sum = abs(rel.x) + abs(rel.y) + abs(rel.z) + radius;
    return 4.0 * F32_EPSILON * sum;
}

// forestlod_shared::view_interval (E§3.5): `d = (c - e) · f`, `[d - r - m, d + r + m]`.
// The dot product is written out (not `dot()`) to keep Rust's order of operations.
fn view_interval(center: vec3<f32>, radius: f32, eye: vec3<f32>, forward: vec3<f32>) -> ViewInterval {
    let rel = vec3<f32>(center.x - eye.x, center.y - eye.y, center.z - eye.z);
    let d = rel.x * forward.x + rel.y * forward.y + rel.z * forward.z;
    let m = selection_margin(rel, radius);
    return ViewInterval(d, d - radius - m, d + radius + m);
}

// forestlod_shared::FrustumPlanes::sphere_visible: inside (or within the margin of) all six
// planes `n · (p - eye) + w >= -r - m`.
fn sphere_visible(planes: array<vec4<f32>, 6>, center: vec3<f32>, radius: f32, eye: vec3<f32>) -> bool {
    let rel = vec3<f32>(center.x - eye.x, center.y - eye.y, center.z - eye.z);
    let m = selection_margin(rel, radius);
    var visible = true;
    for (var i = 0u; i < 6u; i++) {
        let p = planes[i];
        visible = visible && (p.x * rel.x + p.y * rel.y + p.z * rel.z + p.w >= -radius - m);
    }
    return visible;
}

// forestlod_shared::lod_needs (E§4.3): LOD0 where some point is nearer than the band's end, LOD1
// where some point is at or past its start; one LOD level means meshes everywhere.
fn lod_needs(lo: f32, hi: f32, fade_start: f32, fade_end: f32, lod_levels: u32) -> LodNeeds {
    if lod_levels < 2u {
        return LodNeeds(true, false);
    }
    return LodNeeds((lo < fade_end), (hi >= fade_start));
}
