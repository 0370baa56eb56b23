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

// COMMAND_SHIFT, LOD_MESH, LOD_BILLBOARD, the DECISION_* codes (low two bits the kind, plus LOD
// bits for DECISION_DRAW), and the FADE_* and ANGLE_INDEX_* mode ids: generated from Rust
// (gpu/src/shaders.rs).
// f32::EPSILON, 2^-23.
const F32_EPSILON: f32 = 1.1920929e-7;

// No WGSL mirror of forestlod_shared::Params: no shader binds it. Each stage's uniform carries
// the fields it reads (ViewUniform for the selection rule, the stage's own modes), so a new
// parameter costs no WGSL field, layout entry or padding here (issue 27).

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
    tile: vec2<u32>,
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
    first_tree: u32,
    group_len: u32,
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
    area_size: f32,
    error_size: f32,
    _pad0: u32,
    _pad1: u32,
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

// SelectCounters with atomic members, the same layout (8 x u32; `gpu/tests/layout.rs` checks it):
// how select.wgsl, hier_select.wgsl and coalesce.wgsl write the one counters buffer the draw stage
// reads. `nodes_visited` of the hierarchical cut is `batches_tested`.
struct SelectCountersAtomic {
    batches_tested: atomic<u32>,
    culled_distance: atomic<u32>,
    culled_frustum: atomic<u32>,
    commands: atomic<u32>,
    lod0_commands: atomic<u32>,
    lod1_commands: atomic<u32>,
    transition_batches: atomic<u32>,
    instances: atomic<u32>,
}

// One tree's bounding sphere and mesh, the per-tree input of cull.wgsl and refine.wgsl (not in
// forestlod-shared: the GPU crate's own). Keep in sync with forestlod_gpu::cull::CullTree
// (gpu/src/cull.rs).
struct CullTree {
    center: array<f32, 3>,
    radius: f32,
    mesh: u32,
    // The tree's scale: what a scaled LOD metric scales its band by (refine.wgsl `tree_needs`).
    scale: f32,
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


// Keep in sync with forestlod_shared::FrustumPlanes (shared/src/camera.rs).
struct FrustumPlanes {
    planes: array<vec4<f32>, 6>,
}

// Keep in sync with forestlod_shared::ViewUniform (shared/src/view.rs): the per-frame view
// constants every selection-like stage's uniform embeds as its first member (select, cull,
// refine), derived on the CPU once by `ViewUniform::new`.
struct ViewUniform {
    frustum: FrustumPlanes,
    eye: vec3<f32>,
    fade_start: f32,
    forward: vec3<f32>,
    fade_end: f32,
    draw_distance: f32,
    lod_levels: u32,
    metric: u32,
    metric_factor: f32,
    band_ratio: f32,
    subset_mode: u32,
    subset_distance: f32,
    subset_min: f32,
}

// forestlod_shared::ViewUniform::mesh_band (shared/src/metric.rs): the band of a tree of mesh
// `m` at unit scale; the size the metric scales is forestlod_shared::mesh_size.
fn mesh_band(v: ViewUniform, m: MeshMeta) -> vec2<f32> {
    if v.metric == LOD_METRIC_DISTANCE {
        return vec2<f32>(v.fade_start, v.fade_end);
    }
    let size = select(m.area_size, m.error_size, v.metric == LOD_METRIC_SCREEN_ERROR);
    let end = size * v.metric_factor;
    return vec2<f32>(end * v.band_ratio, end);
}

// forestlod_shared::ViewUniform::group_band: a group's band from its mesh band and its trees'
// scale range [min, max].
fn group_band(v: ViewUniform, band: vec2<f32>, scale: vec2<f32>) -> vec2<f32> {
    if v.metric == LOD_METRIC_DISTANCE {
        return band;
    }
    return vec2<f32>(scale.x * band.x, scale.y * band.y);
}

// forestlod_shared::ViewUniform::with_band.
fn with_band(v: ViewUniform, band: vec2<f32>) -> ViewUniform {
    var out = v;
    out.fade_start = band.x;
    out.fade_end = band.y;
    return out;
}

// Twin of forestlod_shared::ViewUniform::decide: the same rule for a batch
// (select.wgsl) and for a lone tree (cull.wgsl). Cull beyond the draw distance (`lo`), then
// outside a frustum plane, else draw with the LODs the interval needs (E§3.5, §4.3).
fn decide_sphere(
    center: vec3<f32>,
    radius: f32,
    planes: array<vec4<f32>, 6>,
    eye: vec3<f32>,
    forward: vec3<f32>,
    draw_distance: f32,
    fade_start: f32,
    fade_end: f32,
    lod_levels: u32,
) -> u32 {
    let i = view_interval(center, radius, eye, forward);
    if i.lo > draw_distance {
        return DECISION_CULLED_DISTANCE;
    }
    if !sphere_visible(planes, center, radius, eye) {
        return DECISION_CULLED_FRUSTUM;
    }
    let n = lod_needs(i.lo, i.hi, fade_start, fade_end, lod_levels);
    return DECISION_DRAW | select(0u, DECISION_LOD0, n.lod0) | select(0u, DECISION_LOD1, n.lod1);
}

// `decide_sphere` under the view constants `v` (forestlod_shared::ViewUniform::decide).
fn decide_view(center: vec3<f32>, radius: f32, v: ViewUniform) -> u32 {
    return decide_sphere(
        center, radius, v.frustum.planes, v.eye, v.forward, v.draw_distance, v.fade_start,
        v.fade_end, v.lod_levels,
    );
}

// reference/src/select.rs `tree_within_draw_distance` (E§4.4's per-tree discard): the view depth
// of a tree's bounding-sphere centre is within the draw distance.
fn within_draw_distance(center: vec3<f32>, eye: vec3<f32>, forward: vec3<f32>, draw_distance: f32) -> bool {
    return view_interval(center, 0.0, eye, forward).d <= draw_distance;
}

// A lone tree's decision under `v` (cull.wgsl, refine.wgsl): `decide_view` on the tree's own
// sphere, then DECISION_CULLED_DISTANCE instead of DECISION_DRAW where its centre fails the draw
// stage's per-tree draw-distance discard (`within_draw_distance`).
fn decide_tree(t: CullTree, v: ViewUniform) -> u32 {
    let center = vec3<f32>(t.center[0], t.center[1], t.center[2]);
    let decision = decide_view(center, t.radius, v);
    if (decision & DECISION_KIND_MASK) == DECISION_DRAW
        && !within_draw_distance(center, v.eye, v.forward, v.draw_distance) {
        return DECISION_CULLED_DISTANCE;
    }
    return decision;
}

// forestlod_shared::lod_needs (E§4.3): LOD0 where some point is nearer than the band's end, LOD1
// where some point is at or past its start; one LOD level means meshes everywhere.
fn lod_needs(lo: f32, hi: f32, fade_start: f32, fade_end: f32, lod_levels: u32) -> LodNeeds {
    if lod_levels < 2u {
        return LodNeeds(true, false);
    }
    return LodNeeds((lo < fade_end), (hi >= fade_start));
}

// ---------------------------------------------------------------------------------------------
// Twins of shared/src/angle.rs, shared/src/billboard.rs and shared/src/fade.rs, used by
// draw.wgsl (E§3.3.1, §4.4; G§4; SPEC §6). Same operations in the same order as the Rust; where
// Rust relies on `f32::max`/`min` returning the non-NaN operand, the WGSL spells the NaN case out
// with comparisons (WGSL's `max`/`min` leave NaN implementation-defined).

// π/2 and π as f32 (core::f32::consts::FRAC_PI_2, PI).
const F32_FRAC_PI_2: f32 = 1.5707963705062866;
const F32_PI: f32 = 3.1415927410125732;



// `x.max(lo).min(hi)` of Rust: NaN maps to `lo`.
fn clamp_nan_low(x: f32, lo: f32, hi: f32) -> f32 {
    if !(x >= lo) {
        return lo;
    }
    if x > hi {
        return hi;
    }
    return x;
}

// forestlod_shared::angle_index_eq31: E Eq. 3.1 as written, `a - floor((2a/π) acos(V·U))`.
fn angle_index_eq31(v_dot_u: f32, a: u32) -> f32 {
    let af = f32(a);
    return af - floor((2.0 * af / F32_PI) * acos(v_dot_u));
}

// forestlod_shared::bake_elevation: `90° / (K - 1) · k`, K = 1 the level view, k clamped.
fn bake_elevation(k: u32, k_count: u32) -> f32 {
    if k_count <= 1u {
        return 0.0;
    }
    let kk = min(k, k_count - 1u);
    return F32_FRAC_PI_2 / f32(k_count - 1u) * f32(kk);
}

// forestlod_shared::angle_index: nearest baked elevation, clamped, NaN-free (ties round up).
fn angle_index(v_dot_u: f32, k_count: u32) -> u32 {
    if k_count <= 1u {
        return 0u;
    }
    let s = clamp_nan_low(v_dot_u, 0.0, 1.0);
    let elevation = asin(s);
    let step = F32_FRAC_PI_2 / f32(k_count - 1u);
    let i = floor(elevation / step + 0.5);
    return min(u32(i), k_count - 1u);
}

// forestlod_shared::angle_index_eq31_clamped: Eq. 3.1 clamped into 0..K-1, NaN-free.
fn angle_index_eq31_clamped(v_dot_u: f32, k_count: u32) -> u32 {
    let s = clamp_nan_low(v_dot_u, -1.0, 1.0);
    let i = angle_index_eq31(s, k_count);
    if i != i {
        return 0u;
    }
    return u32(clamp_nan_low(i, 0.0, f32(max(k_count, 1u) - 1u)));
}

// forestlod_shared::angle_index_for.
fn angle_index_for(mode: u32, v_dot_u: f32, k_count: u32) -> u32 {
    if mode == ANGLE_INDEX_EQ31_CLAMPED {
        return angle_index_eq31_clamped(v_dot_u, k_count);
    }
    return angle_index(v_dot_u, k_count);
}

// Keep in sync with forestlod_shared::BillboardExtent (shared/src/billboard.rs).
struct BillboardExtent {
    half_width: f32,
    bottom: f32,
    height: f32,
}

// forestlod_shared::billboard_extent: the layer's rectangle in the billboard frame.
fn billboard_extent(mesh: MeshMeta, elevation: f32) -> BillboardExtent {
    let s = sin(elevation);
    let c = cos(elevation);
    let w = mesh.billboard_half_width;
    let z0 = mesh.bbox_min[2];
    let z1 = mesh.bbox_max[2];
    return BillboardExtent(w, z0 * c - w * s, (z1 - z0) * c + 2.0 * w * s);
}

// forestlod_shared::dither_threshold: PCG-style integer hash of the pixel, 24 bits as a fraction.
// u32 arithmetic wraps in WGSL exactly as `wrapping_*` in Rust.
fn dither_threshold(x: u32, y: u32) -> f32 {
    var v = x * 1664525u + y * 1013904223u + 0x9E3779B9u;
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    v = (word >> 22u) ^ word;
    return f32(v >> 8u) * (1.0 / 16777216.0);
}

// forestlod_shared::fade_progress: 0 before the band, 1 past it, linear inside; a step at
// `fade_end` for an empty band; NaN depth gives 0.
fn fade_progress(d: f32, fade_start: f32, fade_end: f32) -> f32 {
    let width = fade_end - fade_start;
    if width > 0.0 {
        return clamp_nan_low((d - fade_start) / width, 0.0, 1.0);
    } else if d >= fade_end {
        return 1.0;
    }
    return 0.0;
}

// Keep in sync with forestlod_shared::LodWeights (shared/src/fade.rs).
struct LodWeights {
    lod0: f32,
    lod1: f32,
}

// forestlod_shared::LodWeights::of.
fn lod_weight_of(w: LodWeights, lod: u32) -> f32 {
    if lod == 0u {
        return w.lod0;
    }
    return w.lod1;
}

// forestlod_shared::lod_weights: the weight of each LOD of a fragment at view depth `d` with
// per-pixel threshold `dither`.
fn lod_weights(mode: u32, d: f32, fade_start: f32, fade_end: f32, dither: f32) -> LodWeights {
    let t = fade_progress(d, fade_start, fade_end);
    return weights_at(mode, t, d >= fade_end, dither);
}

// forestlod_shared::weights_at (shared/src/fade.rs): the fade modes' schedules at progress `t`;
// `past_end` is where `none` switches (a fragment's depth at or past the band's end, a tree's
// `t >= 1`).
fn weights_at(mode: u32, t: f32, past_end: bool, dither: f32) -> LodWeights {
    if mode == FADE_NONE {
        let one = select(0.0, 1.0, past_end);
        return LodWeights(1.0 - one, one);
    }
    if mode == FADE_ALPHA {
        return LodWeights(1.0 - t, t);
    }
    if mode == FADE_DITHER {
        let in1 = dither < t;
        return LodWeights(select(1.0, 0.0, in1), select(0.0, 1.0, in1));
    }
    // FADE_DITHER_SEQUENTIAL
    let cover1 = min(2.0 * t, 1.0);
    let cover0 = min(2.0 - 2.0 * t, 1.0);
    return LodWeights(select(0.0, 1.0, dither < cover0), select(0.0, 1.0, dither < cover1));
}

// ---------------------------------------------------------------------------------------------
// The texture-space noise of G§4's blend (issue 30): twins of shared/src/noise.rs. Integer
// arithmetic on the bits, so both twins choose the same level and texel from the same `uv` and
// derivatives; only the derivatives themselves may differ (dpdxCoarse against the reference
// rasterizer's coarse differences).

// forestlod_shared::noise pcg_unit: the last step of dither_threshold, 24 bits as a fraction.
fn pcg_unit(v0: u32) -> f32 {
    let state = v0 * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    let v = (word >> 22u) ^ word;
    return f32(v >> 8u) * (1.0 / 16777216.0);
}

// forestlod_shared::noise_texel: texel (i, j) of noise level `level`, re-hashed per level.
fn noise_texel(level: u32, i: u32, j: u32) -> f32 {
    return pcg_unit(i * 1664525u + j * 1013904223u + level * 0x632BE5ABu + 0x85EBCA6Bu);
}

// forestlod_shared::noise_level_of: the least k with rho2 <= 2^(2k+1), from the bits.
fn noise_level_of(rho2: f32) -> u32 {
    let bits = bitcast<u32>(rho2) & 0x7FFFFFFFu;
    let exponent = bits >> 23u;
    if exponent < 127u {
        return 0u;
    }
    let above = select(0u, 1u, (bits & 0x7FFFFFu) != 0u);
    return (exponent - 127u + above) / 2u;
}

// forestlod_shared::noise scaled_length2: |d · size|².
fn noise_length2(d: vec2<f32>, size: f32) -> f32 {
    let a = d.x * size;
    let b = d.y * size;
    return a * a + b * b;
}

// forestlod_shared::noise_level: Vulkan's nearest mip of log2(max(|ddx|, |ddy|) · size),
// clamped to log2(size).
fn noise_level(ddx: vec2<f32>, ddy: vec2<f32>, size: u32) -> u32 {
    let q = firstLeadingBit(max(size, 1u));
    let s = f32(size);
    return min(max(noise_level_of(noise_length2(ddx, s)), noise_level_of(noise_length2(ddy, s))), q);
}

// forestlod_shared::noise_index: the texel under `uv` at `level`, repeat addressing.
fn noise_index(uv: vec2<f32>, level: u32, size: u32) -> vec2<u32> {
    let side = max(size >> level, 1u);
    let s = f32(side);
    let mask = side - 1u;
    let i = bitcast<u32>(i32(floor(uv.x * s))) & mask;
    let j = bitcast<u32>(i32(floor(uv.y * s))) & mask;
    return vec2<u32>(i, j);
}

// forestlod_shared::texture_noise: the noise at `uv` at its explicit level.
fn texture_noise(uv: vec2<f32>, ddx: vec2<f32>, ddy: vec2<f32>, size: u32) -> f32 {
    let level = noise_level(ddx, ddy, size);
    let ij = noise_index(uv, level, size);
    return noise_texel(level, ij.x, ij.y);
}

// ---------------------------------------------------------------------------------------------
// Hierarchies (issue 13): twins of forestlod_shared::NodeMeta (shared/src/types.rs), the AABB
// interval and plane tests (shared/src/interval.rs, shared/src/camera.rs) and the per-node rule of
// the cut (shared/src/cut.rs), used by hier_select.wgsl.

// Keep in sync with forestlod_shared::NodeMeta (shared/src/types.rs).
struct NodeMeta {
    center: array<f32, 3>,
    radius: f32,
    extent: array<f32, 3>,
    mesh: u32,
    box_center: array<f32, 3>,
    len: u32,
    offset: u32,
    parent: u32,
    depth: u32,
    child_count: u32,
}

// NO_PARENT, NODE_RECURSE, MAX_HIERARCHY_DEPTH and the HIERARCHY_* mode ids are generated from
// forestlod_shared (gpu/src/shaders.rs).

// forestlod_shared::aabb_margin: `16 ε (|rel|₁ + e_x + e_y + e_z)`, summed left to right.
fn aabb_margin(rel: vec3<f32>, extent: vec3<f32>) -> f32 {
    let sum = abs(rel.x) + abs(rel.y) + abs(rel.z) + extent.x + extent.y + extent.z;
    return 16.0 * F32_EPSILON * sum;
}

// forestlod_shared::aabb_view_interval: `d ± Σ|f_k| e_k ± m`.
fn aabb_view_interval(center: vec3<f32>, extent: vec3<f32>, eye: vec3<f32>, forward: vec3<f32>) -> ViewInterval {
    let rel = vec3<f32>(center.x - eye.x, center.y - eye.y, center.z - eye.z);
    let d = rel.x * forward.x + rel.y * forward.y + rel.z * forward.z;
    let r = abs(forward.x) * extent.x + abs(forward.y) * extent.y + abs(forward.z) * extent.z;
    let m = aabb_margin(rel, extent);
    return ViewInterval(d, d - r - m, d + r + m);
}

// forestlod_shared::FrustumPlanes::aabb_visible (inside = false) and aabb_inside (inside = true):
// per plane `n · rel + w >= -r_eff - m`, resp. `>= r_eff + m`, with `r_eff = Σ|n_k| e_k`.
fn aabb_planes(planes: array<vec4<f32>, 6>, center: vec3<f32>, extent: vec3<f32>, eye: vec3<f32>, inside: bool) -> bool {
    let rel = vec3<f32>(center.x - eye.x, center.y - eye.y, center.z - eye.z);
    let m = aabb_margin(rel, extent);
    var ok = true;
    for (var i = 0u; i < 6u; i++) {
        let p = planes[i];
        let r = abs(p.x) * extent.x + abs(p.y) * extent.y + abs(p.z) * extent.z;
        let s = p.x * rel.x + p.y * rel.y + p.z * rel.z + p.w;
        if inside {
            ok = ok && (s >= r + m);
        } else {
            ok = ok && (s >= -r - m);
        }
    }
    return ok;
}

// forestlod_shared::aabb_distance: Euclidean distance from the eye to the box (G§3 dist_to).
fn aabb_distance(center: vec3<f32>, extent: vec3<f32>, eye: vec3<f32>) -> f32 {
    let g = max(abs(center - eye) - extent, vec3<f32>(0.0));
    var s = 0.0;
    s += g.x * g.x;
    s += g.y * g.y;
    s += g.z * g.z;
    return sqrt(s);
}

// forestlod_shared::decide_node: the sphere rule for `grid`, the sphere ∩ box rule otherwise.
fn decide_node(n: NodeMeta, mode: u32, v: ViewUniform) -> u32 {
    let center = vec3<f32>(n.center[0], n.center[1], n.center[2]);
    if mode == HIERARCHY_GRID {
        return decide_view(center, n.radius, v);
    }
    let bc = vec3<f32>(n.box_center[0], n.box_center[1], n.box_center[2]);
    let e = vec3<f32>(n.extent[0], n.extent[1], n.extent[2]);
    let s = view_interval(center, n.radius, v.eye, v.forward);
    let b = aabb_view_interval(bc, e, v.eye, v.forward);
    let lo = max(s.lo, b.lo);
    let hi = min(s.hi, b.hi);
    if lo > v.draw_distance {
        return DECISION_CULLED_DISTANCE;
    }
    if !sphere_visible(v.frustum.planes, center, n.radius, v.eye)
        || !aabb_planes(v.frustum.planes, bc, e, v.eye, false) {
        return DECISION_CULLED_FRUSTUM;
    }
    let needs = lod_needs(lo, hi, v.fade_start, v.fade_end, v.lod_levels);
    return DECISION_DRAW | select(0u, DECISION_LOD0, needs.lod0) | select(0u, DECISION_LOD1, needs.lod1);
}

// forestlod_shared::node_near_depth: the lower end of decide_node's sphere ∩ box interval.
fn node_near_depth(n: NodeMeta, v: ViewUniform) -> f32 {
    let center = vec3<f32>(n.center[0], n.center[1], n.center[2]);
    let bc = vec3<f32>(n.box_center[0], n.box_center[1], n.box_center[2]);
    let e = vec3<f32>(n.extent[0], n.extent[1], n.extent[2]);
    let s = view_interval(center, n.radius, v.eye, v.forward);
    let b = aabb_view_interval(bc, e, v.eye, v.forward);
    return max(s.lo, b.lo);
}

// forestlod_shared::command_depth_key: the f32 bits of a positive depth, else 0.
fn command_depth_key(near_depth: f32) -> u32 {
    return select(0u, bitcast<u32>(near_depth), near_depth > 0.0);
}

// forestlod_shared::node_code: the decision plus NODE_RECURSE for a drawn interior node whose
// children decide.
fn node_code(n: NodeMeta, mode: u32, max_cull_depth: u32, v: ViewUniform) -> u32 {
    let code = decide_node(n, mode, v);
    if (code & DECISION_KIND_MASK) != DECISION_DRAW || n.child_count == 0u {
        return code;
    }
    let bc = vec3<f32>(n.box_center[0], n.box_center[1], n.box_center[2]);
    let e = vec3<f32>(n.extent[0], n.extent[1], n.extent[2]);
    let partial = n.depth < max_cull_depth && !aabb_planes(v.frustum.planes, bc, e, v.eye, true);
    var recurse = false;
    if mode == HIERARCHY_QUADTREE {
        recurse = true;
    } else if mode == HIERARCHY_OCTREE {
        recurse = (code & DECISION_LOD0) != 0u || partial;
    } else if mode == HIERARCHY_OCTREE_EUCLIDEAN {
        recurse = v.lod_levels < 2u || aabb_distance(bc, e, v.eye) < v.fade_end || partial;
    }
    return code | select(0u, NODE_RECURSE, recurse);
}

// forestlod_shared::far (issue 32): the far level's records (layouts checked by
// gpu/tests/layout.rs) and its rules.
struct FarCell {
    center: array<f32, 3>,
    extent: array<f32, 3>,
    colours: array<u32, 6>,
}

struct FarNode {
    cell_offset: u32,
    cell_count: u32,
    hull_offset: u32,
    hull_count: u32,
}

struct FarVertex {
    position: array<f32, 3>,
    colour: u32,
}

// forestlod_shared::node_interval: the sphere's view-depth interval for `grid`, the sphere's ∩
// the box's otherwise.
fn node_interval(n: NodeMeta, mode: u32, v: ViewUniform) -> ViewInterval {
    let center = vec3<f32>(n.center[0], n.center[1], n.center[2]);
    let s = view_interval(center, n.radius, v.eye, v.forward);
    if mode == HIERARCHY_GRID {
        return s;
    }
    let bc = vec3<f32>(n.box_center[0], n.box_center[1], n.box_center[2]);
    let e = vec3<f32>(n.extent[0], n.extent[1], n.extent[2]);
    let b = aabb_view_interval(bc, e, v.eye, v.forward);
    return ViewInterval(s.d, max(s.lo, b.lo), min(s.hi, b.hi));
}

// forestlod_shared::box_area_along: the box's area projected along the unit direction `v`.
fn box_area_along(e: vec3<f32>, v: vec3<f32>) -> f32 {
    return 4.0 * (abs(v.x) * e.y * e.z + abs(v.y) * e.x * e.z + abs(v.z) * e.x * e.y);
}

// forestlod_shared::far_eligible, with FarUniform's fields `kind`, `start`, `ratio`.
fn far_eligible(kind: u32, start: f32, ratio: f32, lo: f32, bc: vec3<f32>, e: vec3<f32>, eye: vec3<f32>, cells: u32) -> bool {
    if kind == 0u || cells == 0u || !(lo >= start) || !(lo > 0.0) {
        return false;
    }
    let d = eye - bc;
    let len = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    if !(len > 0.0) {
        return false;
    }
    let v = vec3<f32>(d.x / len, d.y / len, d.z / len);
    return box_area_along(e, v) / (lo * lo) < ratio;
}

// forestlod_shared::far_code: a drawn node that needs no mesh and is far-eligible goes far
// (DECISION_DRAW | NODE_FAR); an interior node whose interval reaches the far start recurses.
// Under `far_lod = impostor` the node's impostor state decides (`impostor_code`;
// `impostored_below` is read only there).
fn far_code(
    code: u32, n: NodeMeta, mode: u32, v: ViewUniform, kind: u32, start: f32, ratio: f32, cells: u32,
    impostored_below: u32,
) -> u32 {
    if kind == 0u || (code & DECISION_KIND_MASK) != DECISION_DRAW {
        return code;
    }
    if kind == 1u + FAR_LOD_IMPOSTOR {
        return impostor_code(code, n, cells, impostored_below);
    }
    let i = node_interval(n, mode, v);
    let bc = vec3<f32>(n.box_center[0], n.box_center[1], n.box_center[2]);
    let e = vec3<f32>(n.extent[0], n.extent[1], n.extent[2]);
    if (code & DECISION_LOD0) == 0u && far_eligible(kind, start, ratio, i.lo, bc, e, v.eye, cells) {
        return DECISION_DRAW | NODE_FAR;
    }
    if n.child_count > 0u && i.hi >= start {
        return code | NODE_RECURSE;
    }
    return code;
}

// forestlod_shared::impostor_code (issue 33 item 2, C§4.6.3): an impostored node (`cells` > 0)
// goes far whatever its trees' LODs; a drawn interior node with impostored descendants recurses;
// any other node keeps `code`.
fn impostor_code(code: u32, n: NodeMeta, cells: u32, impostored_below: u32) -> u32 {
    if cells > 0u {
        return DECISION_DRAW | NODE_FAR;
    }
    if n.child_count > 0u && impostored_below > 0u {
        return code | NODE_RECURSE;
    }
    return code;
}

// One emitted command and its data (EmittedCommand): twin of forestlod_shared::emit_command
// (shared/src/emit.rs), the one command emission of the flat selection (select.wgsl) and the cut
// (hier_select.wgsl). A group (batch or node) of `len` trees at `offset` in the indirection, at
// `lod`, over the index range (`first_index`, `index_count`) of its mesh (LOD_MESH) or of the
// billboard quad (LOD_BILLBOARD), in output slot `slot` (base_vertex = slot << COMMAND_SHIFT).
struct EmittedCommand {
    command: DrawCommand,
    data: CommandData,
}

fn emit_command(
    slot: u32, index: u32, mesh: u32, len: u32, offset: u32, fading: bool, lod: u32,
    first_index: u32, index_count: u32, view: ViewUniform, count: u32,
) -> EmittedCommand {
    return EmittedCommand(
        DrawCommand(index_count, count, first_index, i32(slot << COMMAND_SHIFT), offset),
        CommandData(view.fade_start, view.fade_end, index, mesh, lod, u32(lod == LOD_BILLBOARD), u32(fading), offset, len, 0u),
    );
}

// forestlod_shared::subset (shared/src/subset.rs): far-field subsets (issue 29, E§7). The
// SUBSET_MODE_* ids, SUBSET_WEIGHT_STEPS and SUBSET_FADE_BITS are generated from Rust.
// forestlod_shared::SUBSET_FADE, from its bits (naga takes no bitcast in a const).
fn subset_fade() -> f32 {
    return bitcast<f32>(SUBSET_FADE_BITS);
}

// forestlod_shared::subset_density.
fn subset_density(d: f32, d_sub: f32, rho_min: f32) -> f32 {
    if !(d > d_sub) {
        return 1.0;
    }
    let r = d_sub / d;
    return max(r * r, rho_min);
}

// forestlod_shared::subset_count.
fn subset_count(len: u32, lo: f32, v: ViewUniform) -> u32 {
    if v.subset_mode == SUBSET_MODE_OFF {
        return len;
    }
    let rho = subset_density(lo, v.subset_distance, v.subset_min);
    if rho >= 1.0 {
        return len;
    }
    let want = u32(ceil(rho * (1.0 + subset_fade()) * f32(len)));
    return min(want + 1u, len);
}

// forestlod_shared::subset_weight_code.
fn subset_weight_code(rank: u32, len: u32, d: f32, v: ViewUniform) -> u32 {
    if v.subset_mode == SUBSET_MODE_OFF || len == 0u {
        return SUBSET_WEIGHT_STEPS;
    }
    let rho = subset_density(d, v.subset_distance, v.subset_min);
    if rho >= 1.0 {
        return SUBSET_WEIGHT_STEPS;
    }
    let q = (f32(rank) + 0.5) / f32(len);
    let w = clamp((rho * (1.0 + subset_fade()) - q) / (rho * subset_fade()), 0.0, 1.0);
    return u32(w * f32(SUBSET_WEIGHT_STEPS) + 0.5);
}

// forestlod_shared::subset_scale.
fn subset_scale(d: f32, v: ViewUniform) -> f32 {
    if v.subset_mode != SUBSET_MODE_THIN_SCALE || !(d > v.subset_distance) {
        return 1.0;
    }
    let r = v.subset_distance / d;
    if r * r > v.subset_min {
        return d / v.subset_distance;
    }
    return 1.0 / sqrt(v.subset_min);
}

// forestlod_shared::subset_pack.
fn subset_pack(rank: u32, code: u32) -> u32 {
    return (((rank * 0x9E3779B9u) >> 16u) << 8u) | (code & 0xFFu);
}

// forestlod_shared::subset_fragment_weight.
fn subset_fragment_weight(packed: u32, fade_mode: u32, x: u32, y: u32) -> f32 {
    let code = packed & 0xFFu;
    if code >= SUBSET_WEIGHT_STEPS {
        return 1.0;
    }
    let w = f32(code) * (1.0 / f32(SUBSET_WEIGHT_STEPS));
    if fade_mode == FADE_ALPHA {
        return w;
    }
    let h = dither_threshold(x + (packed >> 8u), y);
    return select(0.0, 1.0, h < w);
}

// ---- Sun-depth shading (issue 30, G§5): twin of forestlod_shared::light. SHADING_* ids and
// MIN_CROWN_RADIUS_BITS are generated from Rust.

// forestlod_shared::crown_radii.
fn crown_radii(mesh: MeshMeta, scale: f32) -> vec2<f32> {
    return vec2<f32>(mesh.billboard_half_width * scale, (mesh.bbox_max[2] - mesh.bbox_min[2]) * 0.5 * scale);
}

// forestlod_shared::sun_depth: the same operations in the same order; clamped, NaN to -1
// (`max` then `min`, as the reference's `max(-1).min(1)`).
fn sun_depth(p: vec3<f32>, centre: vec3<f32>, radii: vec2<f32>, sun: vec3<f32>) -> f32 {
    let dx = p.x - centre.x;
    let dy = p.y - centre.y;
    let dz = p.z - centre.z;
    let along = dx * sun.x + dy * sun.y + dz * sun.z;
    let min_radius = bitcast<f32>(MIN_CROWN_RADIUS_BITS);
    let rh = max(radii.x, min_radius);
    let rv = max(radii.y, min_radius);
    let sh = sqrt(sun.x * sun.x + sun.y * sun.y) * rh;
    let sv = sun.z * rv;
    let extent = sqrt(sh * sh + sv * sv);
    return min(max(along / extent, -1.0), 1.0);
}

// forestlod_shared::lightness.
fn lightness(delta: f32, ambient: f32) -> f32 {
    return ambient + (1.0 - ambient) * ((delta + 1.0) * 0.5);
}

// forestlod_shared::light_point: the projection onto the lighting plane.
fn light_point(
    p: vec3<f32>, billboard: bool, shading: u32, toward_eye: vec3<f32>, centre: vec3<f32>, r_h: f32,
) -> vec3<f32> {
    if !billboard || shading != SHADING_SUN_DEPTH_PLANE {
        return p;
    }
    let along = (p.x - centre.x) * toward_eye.x + (p.y - centre.y) * toward_eye.y
        + (p.z - centre.z) * toward_eye.z;
    let o = 0.5 * r_h - along;
    return vec3<f32>(p.x + o * toward_eye.x, p.y + o * toward_eye.y, p.z + o * toward_eye.z);
}

// forestlod_shared::vertex_lightness.
fn vertex_lightness(
    shading: u32, p: vec3<f32>, billboard: bool, toward_eye: vec3<f32>, centre: vec3<f32>,
    radii: vec2<f32>, sun: vec3<f32>, ambient: f32,
) -> f32 {
    if shading != SHADING_SUN_DEPTH && shading != SHADING_SUN_DEPTH_PLANE {
        return 1.0;
    }
    let q = light_point(p, billboard, shading, toward_eye, centre, radii.x);
    return lightness(sun_depth(q, centre, radii, sun), ambient);
}

// forestlod_shared::azimuth (shared/src/azimuth.rs): billboard azimuth views (issue 30, E§7).
// The AZIMUTH_MODE_* ids, AZIMUTH_WEIGHT_STEPS, AZIMUTH_LAYER_BITS and the bits of AZIMUTH_TURN
// and AZIMUTH_WEIGHT_SCALE are generated from Rust.

// forestlod_shared::view_layer: layer `(mesh·K + k)·J + j`.
fn view_layer(mesh: u32, k: u32, k_count: u32, j: u32, j_count: u32) -> u32 {
    return (mesh * k_count + k) * j_count + j;
}

// forestlod_shared::azimuth_to_view: a mesh-local point in the frame of the view baked from the
// azimuth whose sine and cosine are given; the identity for the azimuth 0.
fn azimuth_to_view(p: vec3<f32>, sin_a: f32, cos_a: f32) -> vec3<f32> {
    if sin_a == 0.0 && cos_a == 1.0 {
        return p;
    }
    return vec3<f32>(cos_a * p.x + sin_a * p.y, cos_a * p.y - sin_a * p.x, p.z);
}

// forestlod_shared::azimuth_position: the eye's azimuth position `t` in [0, J), 0 for J <= 1 and
// NaN.
fn azimuth_position(h_x: f32, h_y: f32, yaw: f32, j_count: u32) -> f32 {
    if j_count <= 1u {
        return 0.0;
    }
    let turns = (atan2(h_y, h_x) - yaw) * bitcast<f32>(AZIMUTH_TURN_BITS);
    let j = f32(j_count);
    let t = (turns - floor(turns)) * j;
    if t >= 0.0 && t < j {
        return t;
    }
    return 0.0;
}

// forestlod_shared::azimuth_index: the nearest view, round(t) mod J, NaN-free.
fn azimuth_index(t: f32, j_count: u32) -> u32 {
    if j_count <= 1u {
        return 0u;
    }
    let tc = clamp_nan_low(t, 0.0, f32(j_count));
    return u32(floor(tc + 0.5)) % j_count;
}

// Keep in sync with forestlod_shared::AzimuthView.
struct AzimuthView {
    j: u32,
    code: u32,
}

// forestlod_shared::azimuth_view.
fn azimuth_view(mode: u32, t: f32, j_count: u32) -> AzimuthView {
    if j_count <= 1u {
        return AzimuthView(0u, 0u);
    }
    if mode != AZIMUTH_MODE_BLEND {
        return AzimuthView(azimuth_index(t, j_count), 0u);
    }
    let tc = clamp_nan_low(t, 0.0, f32(j_count));
    let lo = floor(tc);
    let w = tc - lo;
    return AzimuthView(u32(lo) % j_count, u32(w * f32(AZIMUTH_WEIGHT_STEPS) + 0.5));
}

// forestlod_shared::azimuth_pack: `layer | code << AZIMUTH_LAYER_BITS`.
fn azimuth_pack(layer: u32, code: u32) -> u32 {
    return (layer & ((1u << AZIMUTH_LAYER_BITS) - 1u))
        | (min(code, AZIMUTH_WEIGHT_STEPS) << AZIMUTH_LAYER_BITS);
}

// forestlod_shared::azimuth_second_layer: the layer of view `j + 1 mod J`.
fn azimuth_second_layer(layer: u32, j_count: u32) -> u32 {
    if j_count <= 1u {
        return layer;
    }
    let j = layer % j_count;
    return layer - j + (j + 1u) % j_count;
}

// forestlod_shared::azimuth_mix: premultiplied mix of two straight-alpha texels; code 0 is the
// first texel.
fn azimuth_mix(first: vec4<f32>, second: vec4<f32>, code: u32) -> vec4<f32> {
    if code == 0u {
        return first;
    }
    let w = f32(min(code, AZIMUTH_WEIGHT_STEPS)) * bitcast<f32>(AZIMUTH_WEIGHT_SCALE_BITS);
    let v = 1.0 - w;
    let a0 = first.a * v;
    let a1 = second.a * w;
    let alpha = a0 + a1;
    if alpha > 0.0 {
        return vec4<f32>((first.rgb * a0 + second.rgb * a1) / alpha, alpha);
    }
    return vec4<f32>(first.rgb * v + second.rgb * w, alpha);
}

// ---- Octahedral impostors (issue 32): twins of shared/src/octahedral.rs, read by draw.wgsl
// (the frames, the re-projection and the mix) and by gpu/src/bake.rs's per-layer constants (the
// frame bases are computed on the CPU there, as the reference computes them). OCTAHEDRAL_* and
// VIEW_SPHERE_* are generated from Rust.

// `sgn 0 = +1` (WGSL's `sign(0.0)` is 0).
fn octahedral_sgn(x: f32) -> f32 {
    return select(1.0, -1.0, x < 0.0);
}

fn octahedral_clamp01(v: f32) -> f32 {
    return min(max(v * 0.5 + 0.5, 0.0), 1.0);
}

// forestlod_shared::octahedral_encode.
fn octahedral_encode(d: vec3<f32>, hemi: bool) -> vec2<f32> {
    var z = d.z;
    if hemi {
        z = max(d.z, 0.0);
    }
    let l1 = abs(d.x) + abs(d.y) + abs(z);
    // `l1 > 0` and finite (f32::MAX = 0x7f7fffff); NaN fails both.
    if !(l1 > 0.0 && l1 <= bitcast<f32>(0x7f7fffffu)) {
        return vec2<f32>(0.5, 0.5);
    }
    var px = d.x / l1;
    var py = d.y / l1;
    if hemi {
        let a = px + py;
        let b = px - py;
        px = a;
        py = b;
    } else if z < 0.0 {
        let ax = abs(px);
        let ay = abs(py);
        px = (1.0 - ay) * octahedral_sgn(px);
        py = (1.0 - ax) * octahedral_sgn(py);
    }
    return vec2<f32>(octahedral_clamp01(px), octahedral_clamp01(py));
}

// forestlod_shared::octahedral_decode.
fn octahedral_decode(uv: vec2<f32>, hemi: bool) -> vec3<f32> {
    let ax = uv.x * 2.0 - 1.0;
    let ay = uv.y * 2.0 - 1.0;
    var x = ax;
    var y = ay;
    if hemi {
        x = (ax + ay) * 0.5;
        y = (ax - ay) * 0.5;
    }
    var z = 1.0 - abs(x) - abs(y);
    if !hemi && z < 0.0 {
        let bx = abs(x);
        let by = abs(y);
        x = (1.0 - by) * octahedral_sgn(x);
        y = (1.0 - bx) * octahedral_sgn(y);
    }
    if hemi {
        z = max(z, 0.0);
    }
    let len = sqrt(x * x + y * y + z * z);
    return vec3<f32>(x / len, y / len, z / len);
}

// forestlod_shared::frame_direction.
fn octahedral_frame_direction(f: u32, grid: u32, hemi: bool) -> vec3<f32> {
    let n = max(grid, MIN_OCTAHEDRAL_GRID);
    let last = f32(n - 1u);
    let i = f32(f % n);
    let j = f32(min(f / n, n - 1u));
    return octahedral_decode(vec2<f32>(i / last, j / last), hemi);
}

struct FrameBasis {
    right: vec3<f32>,
    up: vec3<f32>,
}

// forestlod_shared::frame_basis.
fn octahedral_frame_basis(d: vec3<f32>) -> FrameBasis {
    let len2 = d.x * d.x + d.y * d.y;
    var r = vec3<f32>(0.0, 1.0, 0.0);
    if !(len2 < 1e-12) {
        let len = sqrt(len2);
        r = vec3<f32>(-d.y / len, d.x / len, 0.0);
    }
    let u = vec3<f32>(
        d.y * r.z - d.z * r.y,
        d.z * r.x - d.x * r.z,
        d.x * r.y - d.y * r.x,
    );
    return FrameBasis(r, u);
}

// forestlod_shared::OctahedralView.
struct OctahedralView {
    cell: u32,
    qx: u32,
    qy: u32,
}

fn octahedral_grid_axis(t_in: f32, n: u32) -> vec2<u32> {
    let last = f32(n - 1u);
    let t = min(max(t_in, 0.0), last);
    let i0 = min(u32(floor(t)), n - 2u);
    let f = t - f32(i0);
    let q = min(u32(floor(f * f32(OCTAHEDRAL_STEPS) + 0.5)), OCTAHEDRAL_STEPS);
    return vec2<u32>(i0, q);
}

// forestlod_shared::octahedral_view.
fn octahedral_view(d: vec3<f32>, grid: u32, hemi: bool) -> OctahedralView {
    let n = max(grid, MIN_OCTAHEDRAL_GRID);
    let uv = octahedral_encode(d, hemi);
    let last = f32(n - 1u);
    let x = octahedral_grid_axis(uv.x * last, n);
    let y = octahedral_grid_axis(uv.y * last, n);
    return OctahedralView(y.x * n + x.x, x.y, y.y);
}

// forestlod_shared::OctahedralFrames.
struct OctahedralFrames {
    frames: vec3<u32>,
    weights: vec3<f32>,
    nearest: u32,
}

// forestlod_shared::octahedral_frames.
fn octahedral_frames(view: OctahedralView, grid: u32) -> OctahedralFrames {
    let n = max(grid, MIN_OCTAHEDRAL_GRID);
    let s = OCTAHEDRAL_STEPS;
    let qx = min(view.qx, s);
    let qy = min(view.qy, s);
    let f0 = view.cell;
    var frames = vec3<u32>(f0, f0 + 1u, f0 + n);
    var w = vec3<u32>(s - qx - qy, qx, qy);
    if qx + qy > s {
        frames = vec3<u32>(f0 + n + 1u, f0 + 1u, f0 + n);
        w = vec3<u32>(qx + qy - s, s - qy, s - qx);
    }
    var nearest = 0u;
    if w.y > w.x {
        nearest = 1u;
    }
    if w.z > w[nearest] {
        nearest = 2u;
    }
    let step = 1.0 / f32(OCTAHEDRAL_STEPS);
    return OctahedralFrames(frames, vec3<f32>(w) * step, nearest);
}

// forestlod_shared::octahedral_pack.
fn octahedral_pack(cell_layer: u32, view: OctahedralView) -> u32 {
    let q = min(view.qx, OCTAHEDRAL_STEPS) * (OCTAHEDRAL_STEPS + 1u) + min(view.qy, OCTAHEDRAL_STEPS);
    return (cell_layer & ((1u << OCTAHEDRAL_LAYER_BITS) - 1u)) | (q << OCTAHEDRAL_LAYER_BITS);
}

// forestlod_shared::octahedral_unpack's view (the cell's first layer is the word's low bits).
fn octahedral_unpack_view(word: u32, grid: u32) -> OctahedralView {
    let n = max(grid, MIN_OCTAHEDRAL_GRID);
    let layer = word & ((1u << OCTAHEDRAL_LAYER_BITS) - 1u);
    let q = word >> OCTAHEDRAL_LAYER_BITS;
    return OctahedralView(
        layer % (n * n),
        min(q / (OCTAHEDRAL_STEPS + 1u), OCTAHEDRAL_STEPS),
        q % (OCTAHEDRAL_STEPS + 1u),
    );
}

// forestlod_shared::quad_fit.
fn octahedral_quad_fit(half: vec3<f32>, q: FrameBasis, s: f32) -> vec2<f32> {
    let d = max(s, 1.17549435e-38);
    let rr = abs(q.right.x) * half.x + abs(q.right.y) * half.y + abs(q.right.z) * half.z;
    let ru = abs(q.up.x) * half.x + abs(q.up.y) * half.y + abs(q.up.z) * half.z;
    return vec2<f32>(min(max(rr / d, 0.0), 1.0), min(max(ru / d, 0.0), 1.0));
}

// forestlod_shared::reproject_uv.
fn octahedral_reproject(uv: vec2<f32>, src: FrameBasis, dst: FrameBasis) -> vec2<f32> {
    let a = uv.x * 2.0 - 1.0;
    let b = 1.0 - uv.y * 2.0;
    let p = vec3<f32>(
        src.right.x * a + src.up.x * b,
        src.right.y * a + src.up.y * b,
        src.right.z * a + src.up.z * b,
    );
    let pr = p.x * dst.right.x + p.y * dst.right.y + p.z * dst.right.z;
    let pu = p.x * dst.up.x + p.y * dst.up.y + p.z * dst.up.z;
    return vec2<f32>(0.5 + pr * 0.5, 0.5 - pu * 0.5);
}

// forestlod_shared::depth_offset (issue 32, the depth channel): the surface's offset along the
// nearest frame's direction in sphere radii, 0 (the plane) where the texel is transparent.
fn octahedral_depth_offset(z: f32, alpha: f32) -> f32 {
    return select(0.0, 1.0 - 2.0 * z, alpha > 0.0);
}

// forestlod_shared::view_direction: the eye's mesh-local direction at the packed view's
// quantised place in its cell.
fn octahedral_view_direction(view: OctahedralView, n_in: u32, hemi: bool) -> vec3<f32> {
    let n = max(n_in, MIN_OCTAHEDRAL_GRID);
    let last = f32(n - 1u);
    let i0 = f32(view.cell % n);
    let j0 = f32(view.cell / n);
    return octahedral_decode(
        vec2<f32>(
            (i0 + f32(view.qx) * (1.0 / f32(OCTAHEDRAL_STEPS))) / last,
            (j0 + f32(view.qy) * (1.0 / f32(OCTAHEDRAL_STEPS))) / last,
        ),
        hemi,
    );
}

// glam's `Vec3::dot` and the reference's `dot3`, written out to keep the order of operations.
fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

// forestlod_shared::quad_point: the quad-plane point over the nearest frame's uv (same operation
// order as the reference).
fn octahedral_quad_point(uv: vec2<f32>, e: vec3<f32>, src: FrameBasis, d0: vec3<f32>) -> vec3<f32> {
    let a = uv.x * 2.0 - 1.0;
    let b = 1.0 - uv.y * 2.0;
    let de = dot3(d0, e);
    var c = 0.0;
    if de > 1e-3 {
        c = -(a * dot3(src.right, e) + b * dot3(src.up, e)) / de;
    }
    return vec3<f32>(
        src.right.x * a + src.up.x * b + d0.x * c,
        src.right.y * a + src.up.y * b + d0.y * c,
        src.right.z * a + src.up.z * b + d0.z * c,
    );
}

// forestlod_shared::parallax_uv: one parallax step along the eye's ray in frame (dst, d).
fn octahedral_parallax_uv(q: vec3<f32>, e: vec3<f32>, t: f32, dst: FrameBasis, d: vec3<f32>) -> vec2<f32> {
    let ed = dot3(e, d);
    var s = 0.0;
    if ed > 1e-3 {
        s = (t - dot3(q, d)) / ed;
    }
    let p = vec3<f32>(q.x + e.x * s, q.y + e.y * s, q.z + e.z * s);
    return vec2<f32>(0.5 + dot3(p, dst.right) * 0.5, 0.5 - dot3(p, dst.up) * 0.5);
}

// forestlod_shared::octahedral_mix.
fn octahedral_mix(t0: vec4<f32>, t1: vec4<f32>, t2: vec4<f32>, w: vec3<f32>) -> vec4<f32> {
    if w.x == 1.0 {
        return t0;
    }
    if w.y == 1.0 {
        return t1;
    }
    if w.z == 1.0 {
        return t2;
    }
    let a0 = t0.a * w.x;
    let a1 = t1.a * w.y;
    let a2 = t2.a * w.z;
    let alpha = a0 + a1 + a2;
    if alpha > 0.0 {
        return vec4<f32>((t0.rgb * a0 + t1.rgb * a1 + t2.rgb * a2) / alpha, alpha);
    }
    return vec4<f32>(t0.rgb * w.x + t1.rgb * w.y + t2.rgb * w.z, alpha);
}

// ---- Occlusion culling (issue 31): twins of shared/src/occlusion.rs, read by pyramid.wgsl and
// occlude.wgsl. The OCCLUSION_*_BITS slacks and MAX_PYRAMID_LEVELS are generated from Rust.

// Keep in sync with forestlod_shared::OcclusionCounters (shared/src/occlusion.rs), with atomic
// members (the same layout, 8 x u32; `gpu/tests/layout.rs` checks it against the Rust struct).
struct OcclusionCountersAtomic {
    early: atomic<u32>,
    tested: atomic<u32>,
    occluded: atomic<u32>,
    offscreen: atomic<u32>,
    late: atomic<u32>,
    unbounded: atomic<u32>,
    _pad0: array<u32, 2>,
}

// forestlod_shared::pyramid_reduce: the largest of texels (x0, y0), (x1, y0), (x0, y1), (x1, y1)
// of the level below, read in that order (`max` is exact: the order changes no bit).
fn pyramid_reduce_max(t00: f32, t10: f32, t01: f32, t11: f32) -> f32 {
    return max(max(max(t00, t10), t01), t11);
}

// forestlod_shared::pyramid_reduce's source texels of texel (i, j) of the level above a level of
// `below_size`: (x0, y0, x1, y1), the second column and row clamped to the level.
fn pyramid_reduce_texels(below_size: vec2<u32>, i: u32, j: u32) -> vec4<u32> {
    let x0 = 2u * i;
    let y0 = 2u * j;
    let x1 = min(x0 + 1u, below_size.x - 1u);
    let y1 = min(y0 + 1u, below_size.y - 1u);
    return vec4<u32>(x0, y0, x1, y1);
}

// forestlod_shared::OcclusionBound as a kind code (shader-private), with its rectangle.
const BOUND_UNBOUNDED: u32 = 0u;
const BOUND_OFFSCREEN: u32 = 1u;
const BOUND_RECT: u32 = 2u;

// forestlod_shared::OcclusionBound: `kind`, and for BOUND_RECT the inclusive pixel rectangle
// (x0, y0, x1, y1) and the nearest depth (forestlod_shared::OcclusionRect).
struct OcclusionBound {
    kind: u32,
    rect: vec4<u32>,
    z_min: f32,
}

// Whether `x` is neither infinite nor NaN (Rust `f32::is_finite`).
fn f32_is_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

// Corner `corner` (bit 0: +x, bit 1: +y, bit 2: +z) of the cube of half-side `r` about `c`, in
// clip space, projected as `raster` projects (`view_proj * p` as glam sums it: column 0 first).
fn occlusion_corner(view_proj: mat4x4<f32>, c: vec3<f32>, r: f32, corner: u32) -> vec4<f32> {
    let p = vec3<f32>(
        c.x + select(-r, r, (corner & 1u) != 0u),
        c.y + select(-r, r, (corner & 2u) != 0u),
        c.z + select(-r, r, (corner & 4u) != 0u),
    );
    return ((view_proj[0] * p.x + view_proj[1] * p.y) + view_proj[2] * p.z) + view_proj[3];
}

// forestlod_shared::occlusion_bounds: the eight corners of the cube around the widened footprint
// sphere (`occlusion_corner`); off screen when all lie nearer than half the near distance, else
// unbounded when one does; their screen box widened by OCCLUSION_SLACK_PX and their least NDC
// depth less OCCLUSION_Z_SLACK.
fn occlusion_bounds(
    view_proj: mat4x4<f32>,
    near: f32,
    center: vec3<f32>,
    radius: f32,
    width: u32,
    height: u32,
) -> OcclusionBound {
    var out = OcclusionBound(BOUND_UNBOUNDED, vec4<u32>(0u, 0u, 0u, 0u), 0.0);
    let slack_rel = bitcast<f32>(OCCLUSION_SLACK_REL_BITS);
    let slack_px = bitcast<f32>(OCCLUSION_SLACK_PX_BITS);
    let c = center;
    let r = radius * (1.0 + slack_rel) + max(abs(c.x), max(abs(c.y), abs(c.z))) * slack_rel;
    if !(f32_is_finite(r) && f32_is_finite(c.x) && f32_is_finite(c.y) && f32_is_finite(c.z)) {
        return out;
    }
    let half_w = f32(width) * 0.5;
    let half_h = f32(height) * 0.5;
    let f32_max = bitcast<f32>(0x7f7fffffu);
    var x_lo = f32_max;
    var x_hi = -f32_max;
    var y_lo = f32_max;
    var y_hi = -f32_max;
    var z_lo = f32_max;
    // Wholly nearer than half the near distance (behind the eye included): clipped away.
    var all_near = true;
    for (var corner = 0u; corner < 8u; corner++) {
        all_near = all_near && occlusion_corner(view_proj, c, r, corner).w < 0.5 * near;
    }
    if all_near {
        out.kind = BOUND_OFFSCREEN;
        return out;
    }
    for (var corner = 0u; corner < 8u; corner++) {
        let clip = occlusion_corner(view_proj, c, r, corner);
        let finite = f32_is_finite(clip.x) && f32_is_finite(clip.y) && f32_is_finite(clip.z)
            && f32_is_finite(clip.w);
        if !finite || clip.w <= 0.5 * near {
            return out;
        }
        let x = (clip.x / clip.w) * half_w + half_w;
        let y = half_h - (clip.y / clip.w) * half_h;
        x_lo = min(x_lo, x);
        x_hi = max(x_hi, x);
        y_lo = min(y_lo, y);
        y_hi = max(y_hi, y);
        z_lo = min(z_lo, clip.z / clip.w);
    }
    x_lo = x_lo - slack_px;
    x_hi = x_hi + slack_px;
    y_lo = y_lo - slack_px;
    y_hi = y_hi + slack_px;
    if x_hi < 0.0 || y_hi < 0.0 || x_lo >= f32(width) || y_lo >= f32(height) {
        out.kind = BOUND_OFFSCREEN;
        return out;
    }
    let w_max = f32(width - 1u);
    let h_max = f32(height - 1u);
    out.kind = BOUND_RECT;
    out.rect = vec4<u32>(
        u32(clamp(floor(x_lo), 0.0, w_max)),
        u32(clamp(floor(y_lo), 0.0, h_max)),
        u32(clamp(floor(x_hi), 0.0, w_max)),
        u32(clamp(floor(y_hi), 0.0, h_max)),
    );
    out.z_min = z_lo - bitcast<f32>(OCCLUSION_Z_SLACK_BITS);
    return out;
}

// forestlod_shared::pyramid_level_for: the smallest level at which `rect` (x0, y0, x1, y1) spans
// at most 2x2 texels, among `levels` levels (at most MAX_PYRAMID_LEVELS iterations).
fn pyramid_level_for(rect: vec4<u32>, levels: u32) -> u32 {
    var level = 0u;
    while level + 1u < levels
        && ((rect.z >> level) - (rect.x >> level) > 1u
            || (rect.w >> level) - (rect.y >> level) > 1u) {
        level++;
    }
    return level;
}

// forestlod_shared::occluded: the nearest depth lies strictly behind the pyramid's maximum.
fn occluded(z_min: f32, pyramid_max: f32) -> bool {
    return z_min > pyramid_max;
}

// forestlod_shared::may_occlude: every command in a dithered fade mode; under alpha only commands
// that never blend.
fn may_occlude(data: CommandData, fade_mode: u32, subset_mode: u32) -> bool {
    return fade_mode != FADE_ALPHA
        || (data.fading == 0u && (data.billboard == 0u || subset_mode == SUBSET_MODE_OFF));
}

// forestlod_shared::is_early: whether a tree of a command with `data` is drawn in the early pass.
fn is_early(
    mode: u32,
    data: CommandData,
    fade_mode: u32,
    subset_mode: u32,
    occluder_depth: f32,
    depth_near: f32,
    visible_before: bool,
) -> bool {
    if !may_occlude(data, fade_mode, subset_mode) {
        return false;
    }
    if mode == OCCLUSION_SINGLE {
        return data.lod == LOD_MESH && depth_near <= occluder_depth;
    } else if mode == OCCLUSION_TWO_PHASE {
        return visible_before;
    }
    return false;
}

// forestlod_shared::effective_mode: `two-phase` without a history (a path's first frame) is
// `single`.
fn effective_mode(mode: u32, has_history: bool) -> u32 {
    if mode == OCCLUSION_TWO_PHASE && !has_history {
        return OCCLUSION_SINGLE;
    }
    return mode;
}

// forestlod_shared::is_occluder: `is_early`, for a tree whose rectangle is not wholly off screen.
fn is_occluder(
    mode: u32,
    data: CommandData,
    fade_mode: u32,
    subset_mode: u32,
    occluder_depth: f32,
    depth_near: f32,
    visible_before: bool,
    bound_kind: u32,
) -> bool {
    return is_early(mode, data, fade_mode, subset_mode, occluder_depth, depth_near, visible_before)
        && bound_kind != BOUND_OFFSCREEN;
}

// forestlod_shared::occlusion_slot: where a command's kept trees go in the 4m indirection.
fn occlusion_slot(phase: u32, lod: u32, m: u32, first_instance: u32) -> u32 {
    return (2u * phase + min(lod, 1u)) * m + first_instance;
}

// The far level's colours and primitives (issue 32, forestlod_shared::far).

// forestlod_shared::srgb_to_linear, evaluated in f32 (the reference reads an f64-exact table:
// the two differ by ulps, far below half an 8-bit step, so a decoded byte encodes back to itself).
fn srgb_decode(b: u32) -> f32 {
    let c = f32(b & 255u) / 255.0;
    if c <= 0.04045 {
        return c / 12.92;
    }
    return pow((c + 0.055) / 1.055, 2.4);
}

// forestlod_shared::linear_to_srgb in f32 (NaN to 0).
fn srgb_encode8(l: f32) -> u32 {
    let x = min(max(l, 0.0), 1.0);
    var s: f32;
    if x <= 0.0031308 {
        s = x * 12.92;
    } else {
        s = 1.055 * pow(x, 1.0 / 2.4) - 0.055;
    }
    return u32(floor(s * 255.0 + 0.5));
}

// forestlod_shared::unpack_far_colour.
fn unpack_far_colour(c: u32) -> vec4<f32> {
    return vec4<f32>(srgb_decode(c), srgb_decode(c >> 8u), srgb_decode(c >> 16u), f32((c >> 24u) & 255u) / 255.0);
}

// forestlod_shared::pack_far_colour.
fn pack_far_colour(c: vec4<f32>) -> u32 {
    let a = u32(floor(min(max(c.w, 0.0), 1.0) * 255.0 + 0.5));
    return srgb_encode8(c.x) | (srgb_encode8(c.y) << 8u) | (srgb_encode8(c.z) << 16u) | (a << 24u);
}

// forestlod_shared::side_weights and side_mix over six RGBA8 side colours.
fn side_mix(colours: array<u32, 6>, v: vec3<f32>) -> vec4<f32> {
    let sq = vec3<f32>(v.x * v.x, v.y * v.y, v.z * v.z);
    let sum = sq.x + sq.y + sq.z;
    var w = vec3<f32>(0.0, 0.0, 1.0);
    if sum > 0.0 {
        w = vec3<f32>(sq.x / sum, sq.y / sum, sq.z / sum);
    }
    let sides = vec3<u32>(select(1u, 0u, v.x >= 0.0), select(3u, 2u, v.y >= 0.0), select(5u, 4u, v.z >= 0.0));
    var out = vec4<f32>(0.0);
    out = out + w.x * unpack_far_colour(colours[sides.x]);
    out = out + w.y * unpack_far_colour(colours[sides.y]);
    out = out + w.z * unpack_far_colour(colours[sides.z]);
    return out;
}

// The six corners of the two triangles on a square (forestlod_shared::sprite_corner's QUAD).
fn far_quad_corner(k: u32) -> vec2<f32> {
    let xs = array<f32, 6>(-1.0, 1.0, 1.0, -1.0, 1.0, -1.0);
    let ys = array<f32, 6>(-1.0, -1.0, 1.0, -1.0, 1.0, 1.0);
    return vec2<f32>(xs[k % 6u], ys[k % 6u]);
}

// forestlod_shared::impostor::impostor_corner (issue 33 item 2): corner `v` of an impostor quad
// as (s, t) in [-1, 1]² (t up) in `.xy` and its texture coordinate (u, v) in [0, 1]² (v down)
// in `.zw`.
fn impostor_corner(v: u32) -> vec4<f32> {
    let c = far_quad_corner(v);
    return vec4<f32>(c, (c.x + 1.0) * 0.5, (1.0 - c.y) * 0.5);
}

// forestlod_shared::impostor::impostor_texel: the nearest texel of a tile of
// `size = width | height << 16` at (u, v), its index in a slot of `side²` texels, row by row;
// outside [0, 1] clamps to the edge texel, NaN reads texel 0 (Rust's saturating `as u32`).
fn impostor_texel_axis(t: f32, n: u32) -> u32 {
    let x = floor(t * f32(n));
    // `!(x > 0.0)` catches NaN as well as negatives (Rust's `max(0.0)` then `as u32`).
    if !(x > 0.0) {
        return 0u;
    }
    let hi = max(n, 1u) - 1u;
    if x >= f32(hi) {
        return hi;
    }
    return u32(x);
}

fn impostor_texel(size: u32, side: u32, u: f32, v: f32) -> u32 {
    let x = impostor_texel_axis(u, size & 0xffffu);
    let y = impostor_texel_axis(v, size >> 16u);
    return y * side + x;
}

struct CubeCorner {
    face: u32,
    p: vec3<f32>,
}

// forestlod_shared::cube_corner.
fn cube_corner(v: u32) -> CubeCorner {
    let face = v / 6u;
    let st = far_quad_corner(v % 6u);
    let axis = face / 2u;
    let sign = select(-1.0, 1.0, face % 2u == 0u);
    var p = vec3<f32>(0.0);
    p[axis] = sign;
    p[(axis + 1u) % 3u] = st.x * sign;
    p[(axis + 2u) % 3u] = st.y;
    return CubeCorner(face, p);
}

// forestlod_shared::sprite_half: the box's reach along the quad's right and up.
fn sprite_half(e: vec3<f32>, r: vec3<f32>, up: vec3<f32>) -> vec2<f32> {
    return vec2<f32>(
        abs(r.x) * e.x + abs(r.y) * e.y + abs(r.z) * e.z,
        abs(up.x) * e.x + abs(up.y) * e.y + abs(up.z) * e.z,
    );
}

// The point LOD (issue 33, forestlod_shared::points; C§4.4, §4.6.3): the record the draw will
// read per point and the draw's formulas, twins of `point_keep`, `point_centre` and
// `point_half_side`. Keep in sync with forestlod_shared::points::PointRecord (48 bytes; layout
// checked by gpu/tests/layout.rs).
struct PointRecord {
    pos: array<f32, 3>,
    area: f32,
    lower: f32,
    parent_area: f32,
    normal: u32,
    rgba8: u32,
    parent: u32,
    leaves: u32,
    _pad: array<u32, 2>,
}

// forestlod_shared::points::point_keep: the interval rule, or the cut with a root's bound above
// every threshold by its POINT_NO_PARENT link (ROOT_PARENT_AREA · s² may overflow). `k` is
// [k_min, k_max] (point_thresholds). Products only, as the Rust side: `*` is correctly rounded.
fn point_keep(r: PointRecord, mode: u32, scale: f32, depth: f32, k: vec2<f32>) -> bool {
    let s2 = scale * scale;
    let d2 = depth * depth;
    if mode == POINT_SELECT_INTERVAL {
        let a = r.area * s2;
        return d2 * k.x <= a && a <= d2 * k.y;
    }
    let t = d2 * k.y;
    if r.parent == POINT_NO_PARENT {
        return r.lower * s2 <= t;
    }
    return r.lower * s2 <= t && t < r.parent_area * s2;
}

// forestlod_shared::points::point_centre: base + Rz(yaw)·(scale·pos), yaw as its sine and cosine.
fn point_centre(base: vec3<f32>, s: f32, c: f32, scale: f32, pos: array<f32, 3>) -> vec3<f32> {
    let p = vec3<f32>(pos[0] * scale, pos[1] * scale, pos[2] * scale);
    return base + vec3<f32>(c * p.x - s * p.y, s * p.x + c * p.y, p.z);
}

// forestlod_shared::points::point_half_side: √(A·s²) / 2.
fn point_half_side(area: f32, scale: f32) -> f32 {
    return sqrt(area * (scale * scale)) * 0.5;
}
