// draw.wgsl: the draw stage (E§4.4; SPEC §5.5), twin of reference/src/draw.rs. Prepended by
// common.wgsl (gpu/src/shaders.rs). Function names follow the reference: `tree_vertex` is
// `vertex_stage`, `tree_fragment` is `TreeShader::shade`, `terrain_*` draws `terrain_triangles`.
//
// One render pass: the ground grid (opaque, a plain vertex buffer), then every selected command
// with ONE multi-draw-indirect call (gpu/src/draw.rs). Vertices are pulled from storage buffers:
// `command = vertex_index >> COMMAND_SHIFT` and `local = vertex_index & (MAX_MESH_VERTICES - 1)`
// (`base_vertex = command << COMMAND_SHIFT`, shared/src/types.rs), the tree is
// `indirection[instance_index]` (`first_instance` = the batch's offset, E§4.4).

// Keep in sync with forestlod_shared::MAX_MESH_VERTICES.
const MAX_MESH_VERTICES: u32 = 1u << COMMAND_SHIFT;

// The LOD_ID_* values (forestlod_shared::color): generated from Rust (gpu/src/shaders.rs).

// A clip position outside the far plane (z > w): a triangle whose three vertices all sit here
// is clipped away entirely and, being degenerate too, could never cover a sample anyway. Used for
// trees beyond the draw distance and for commands past the selection's count.
const DISCARDED_POSITION: vec4<f32> = vec4<f32>(0.0, 0.0, 2.0, 1.0);

// Keep in sync with gpu/src/draw.rs `DrawUniform` (layout checked by its tests).
struct DrawUniform {
    view_proj: mat4x4<f32>,
    // The shared view constants (common.wgsl `ViewUniform`); the draw reads eye, unit forward
    // and draw distance.
    view: ViewUniform,
    angle_count: u32,
    fade_mode: u32,
    angle_index_mode: u32,
    alpha_cutoff: f32,
    billboard_first_vertex: u32,
    // Camera::pixel_origin: the frame pixel of the viewport's (0, 0), non-zero for a tile camera;
    // the dither threshold is the frame pixel's.
    pixel_origin_x: u32,
    pixel_origin_y: u32,
    // Shading (issue 30, G§5, common.wgsl `vertex_lightness`): the mode; the ambient level and
    // the unit direction towards the sun below.
    shading: u32,
    // Issue 30 (G§4): the dithered fades' threshold space, the progress's granularity and the
    // texture-space noise's side (reference/src/blend.rs).
    dither_space: u32,
    fade_granularity: u32,
    noise_size: u32,
    ambient: f32,
    sun: vec3<f32>,
    // forestlod_shared::depth_channel as 0/1 (issue 32): the blend re-projects the nearest
    // frame's surface point read from `billboard_depth`.
    octahedral_depth: u32,
    // Billboard azimuth views J and the AzimuthMode id (issue 30, common.wgsl azimuth_*).
    azimuth_count: u32,
    azimuth_mode: u32,
    // Octahedral impostors (issue 32, common.wgsl octahedral_*): the ViewSphere id, the grid
    // side N and whether the three frames blend (an AzimuthMode id).
    billboard_views: u32,
    octahedral_grid: u32,
    octahedral_blend: u32,
    // The far level (issue 32): 0 without one, else 1 + FarLod; the node records' and the hull
    // vertices' first words in `far_words`.
    far_kind: u32,
    far_nodes_base: u32,
    far_hull_base: u32,
    // The point LOD (issue 33, forestlod_shared::points): the camera's right and up (a point's
    // square lies in their plane), whether LOD1 commands draw points, the PointSelect id, the
    // thresholds [k_min, k_max] and the point header's first word in `far_words`
    // (gpu/src/draw.rs `point_words`).
    cam_right: vec3<f32>,
    points: u32,
    cam_up: vec3<f32>,
    point_mode: u32,
    point_k: vec2<f32>,
    point_base: u32,
    // Hierarchical impostors (issue 33 item 2, forestlod_shared::impostor): the atlas's first
    // word in `far_words` (after the hull) and the tile side `impostor_pixels` (0 unless
    // `far_lod = impostor`).
    far_texel_base: u32,
    impostor_side: u32,
    _pad_impostor0: u32,
    _pad_impostor1: u32,
    _pad_impostor2: u32,
}

// Keep in sync with gpu/src/draw.rs `DrawVertex` (= reference PackedVertex).
struct DrawVertex {
    position: array<f32, 3>,
    uv: array<f32, 2>,
}

// Keep in sync with gpu/src/draw.rs `DrawInstance`.
struct DrawInstance {
    position: array<f32, 3>,
    yaw: f32,
    scale: f32,
    mesh: u32,
}

@group(0) @binding(0) var<uniform> u: DrawUniform;
@group(0) @binding(1) var<storage, read> vertices: array<DrawVertex>;
@group(0) @binding(2) var<storage, read> instances: array<DrawInstance>;
@group(0) @binding(3) var<storage, read> indirection: array<u32>;
@group(0) @binding(4) var<storage, read> meshes: array<MeshMeta>;
@group(0) @binding(5) var<storage, read> command_data: array<CommandData>;
@group(0) @binding(6) var<storage, read> counters: SelectCounters;
// One layer per mesh (all mesh textures share one size).
@group(0) @binding(7) var mesh_textures: texture_2d_array<f32>;
// Layer `mesh * K + k` (E Alg. 3.1), `mesh·K·J + k·J + j` with J azimuth views (issue 30).
@group(0) @binding(8) var billboard_textures: texture_2d_array<f32>;
// Trilinear, clamp-to-edge (reference Sampler::TRILINEAR).
@group(0) @binding(9) var tree_sampler: sampler;
// The far level (issue 32; gpu/src/draw.rs `far_words`): cells (12 words each) from word 0, node
// records (4 words) from `u.far_nodes_base`, hull vertices (4 words) from `u.far_hull_base`, the
// impostor atlas (`impostor_side²` RGBA8 words per slot, row by row) from `u.far_texel_base`.
@group(0) @binding(10) var<storage, read> far_words: array<u32>;
// The octahedral impostors' depth channel (issue 32), in the billboard array's layer order; the
// billboard array itself when there is none (then never read).
@group(0) @binding(11) var billboard_depth: texture_2d_array<f32>;

fn far_f32(i: u32) -> f32 {
    return bitcast<f32>(far_words[i]);
}

fn far_vec3(i: u32) -> vec3<f32> {
    return vec3<f32>(far_f32(i), far_f32(i + 1u), far_f32(i + 2u));
}

// reference `far_stage` and the far arm of `TreeStage::vertex`: the cell's cube corner or sprite
// corner, or the node's hull vertex, and its colour word as two flat varyings (RGB, alpha).
fn far_vertex(command: u32, local: u32, instance: u32) -> TreeVaryings {
    var out: TreeVaryings;
    out.clip = DISCARDED_POSITION;
    out.uv_depth_light = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    out.layer_command_scale = vec4<u32>(0u, command, 0u, 0u);
    let words = arrayLength(&far_words);
    if u.far_kind == 0u {
        return out;
    }
    if u.far_kind == 1u + FAR_LOD_IMPOSTOR {
        return impostor_vertex(command, local, instance);
    }
    var world: vec3<f32>;
    var word: u32;
    if u.far_kind == 1u + FAR_LOD_HULL {
        let nb = u.far_nodes_base + instance * 4u;
        if nb + 4u > u.far_hull_base {
            return out;
        }
        let vb = u.far_hull_base + (far_words[nb + 2u] + local) * 4u;
        if vb + 4u > words {
            return out;
        }
        world = far_vec3(vb);
        word = far_words[vb + 3u];
    } else {
        let cb = instance * 12u;
        if cb + 12u > u.far_nodes_base {
            return out;
        }
        let c = far_vec3(cb);
        let e = far_vec3(cb + 3u);
        if u.far_kind == 1u + FAR_LOD_OCTANT_CUBE {
            let k = cube_corner(local);
            world = c + k.p * e;
            word = far_words[cb + 6u + k.face];
        } else {
            let d = u.view.eye - c;
            let len = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
            var v = vec3<f32>(0.0, 0.0, 1.0);
            if len > 0.0 {
                v = vec3<f32>(d.x / len, d.y / len, d.z / len);
            }
            let basis = octahedral_frame_basis(v);
            let half = sprite_half(e, basis.right, basis.up);
            let q = far_quad_corner(local);
            world = c + basis.right * (q.x * half.x) + basis.up * (q.y * half.y);
            var colours: array<u32, 6>;
            for (var s = 0u; s < 6u; s = s + 1u) {
                colours[s] = far_words[cb + 6u + s];
            }
            word = pack_far_colour(side_mix(colours, v));
        }
    }
    let rel = world - u.view.eye;
    let depth = rel.x * u.view.forward.x + rel.y * u.view.forward.y + rel.z * u.view.forward.z;
    out.clip = u.view_proj * vec4<f32>(world, 1.0);
    out.uv_depth_light = vec4<f32>(0.0, 0.0, depth, 1.0);
    out.layer_command_scale = vec4<u32>(word & 0xffffffu, command, word >> 24u, 0u);
    return out;
}

// reference `TreeStage::vertex`'s impostor arm (issue 33 item 2, forestlod_shared::impostor): the
// corner of the quad in cell `instance` (an ImpostorQuad: center, slot, right, size, up) and its
// texture coordinate; the quad's atlas slot rides as a flat varying (the fragment reads the
// tile's size and texels by it).
fn impostor_vertex(command: u32, local: u32, instance: u32) -> TreeVaryings {
    var out: TreeVaryings;
    out.clip = DISCARDED_POSITION;
    out.uv_depth_light = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    out.layer_command_scale = vec4<u32>(0u, command, 0u, 0u);
    let cb = instance * 12u;
    if cb + 12u > u.far_nodes_base {
        return out;
    }
    let k = impostor_corner(local);
    let world = far_vec3(cb) + far_vec3(cb + 4u) * k.x + far_vec3(cb + 8u) * k.y;
    let rel = world - u.view.eye;
    let depth = rel.x * u.view.forward.x + rel.y * u.view.forward.y + rel.z * u.view.forward.z;
    out.clip = u.view_proj * vec4<f32>(world, 1.0);
    out.uv_depth_light = vec4<f32>(k.z, k.w, depth, 1.0);
    out.layer_command_scale = vec4<u32>(far_words[cb + 3u], command, 0u, 0u);
    return out;
}

// reference `TreeShader::impostor_fragment` (issue 33 item 2): the nearest texel of the slot's
// tile, whether it is kept (alpha at least one half), and its word. An out-of-range slot or texel
// keeps nothing (the reference's `get` misses).
fn impostor_texel_word(slot: u32, uv: vec2<f32>) -> vec2<u32> {
    let cb = slot * 12u;
    if cb + 12u > u.far_nodes_base {
        return vec2<u32>(0u, 0u);
    }
    let side = u.impostor_side;
    let texel = impostor_texel(far_words[cb + 7u], side, uv.x, uv.y);
    let i = u.far_texel_base + slot * side * side + texel;
    if i >= arrayLength(&far_words) || u.far_texel_base + slot * side * side > i {
        return vec2<u32>(0u, 0u);
    }
    let word = far_words[i];
    return vec2<u32>(u32((word >> 24u) >= 128u), word);
}

// The point LOD (issue 33): record `i` (area order) of `mesh`, read from the point words in
// `far_words` (gpu/src/draw.rs `point_words`: a 3-word header per mesh, 12 words per record).
fn point_record(mesh: u32, i: u32) -> PointRecord {
    let w = u.point_base + far_words[u.point_base + 3u * mesh] + 12u * i;
    var r: PointRecord;
    r.pos = array<f32, 3>(far_f32(w), far_f32(w + 1u), far_f32(w + 2u));
    r.area = far_f32(w + 3u);
    r.lower = far_f32(w + 4u);
    r.parent_area = far_f32(w + 5u);
    r.normal = far_words[w + 6u];
    r.rgba8 = far_words[w + 7u];
    r.parent = far_words[w + 8u];
    r.leaves = far_words[w + 9u];
    return r;
}

// Records of `mesh` in the point words.
fn point_count(mesh: u32) -> u32 {
    return far_words[u.point_base + 3u * mesh + 1u];
}

// The area-order index of rank `k` in the mode's order: `k` itself (interval) or the cut order's.
fn point_index(mesh: u32, k: u32) -> u32 {
    if u.point_mode == POINT_SELECT_INTERVAL {
        return k;
    }
    return far_words[u.point_base + far_words[u.point_base + 3u * mesh + 2u] + k];
}

// Two locations, not four (issue 14): lavapipe keeps every set-up triangle of a frame's scene
// with three vec4s per location (a0, d/dx, d/dy), so packing the reference's five varyings
// `u, v, depth | layer, command` into one perspective vec3 and one flat vec2 cuts that memory
// by about a quarter; each component is interpolated alone, so no value changes. The tree's
// scale rides in the flat vector as bits (the reference's sixth varying, which interpolates to
// itself exactly: reference/src/draw.rs TREE_VARYINGS).
struct TreeVaryings {
    @builtin(position) clip: vec4<f32>,
    // `uv`, the view depth `(p - eye) · forward` (clamped to the tree's sphere interval for
    // billboards) and the vertex's lightness (issue 30; 1 when unlit): one location, so the
    // lightness costs lavapipe no set-up memory.
    @location(0) uv_depth_light: vec4<f32>,
    // Texture layer (for a billboard, the azimuth word: common.wgsl `azimuth_pack`, issue 30;
    // the layer itself with one azimuth or the nearest view), command index, the tree's scale as
    // bits (what a scaled LOD metric scales the command's band by, C§4.6; under
    // `fade_granularity = tree`, issue 30, the tree's progress through that band instead: the
    // fragment then needs no band), and its far-field subset word (common.wgsl `subset_pack`,
    // issue 29).
    @location(1) @interpolate(flat) layer_command_scale: vec4<u32>,
}

struct TargetOutput {
    @location(0) color: vec4<f32>,
    @location(1) lod_id: u32,
}

// reference/src/scene/mod.rs `round_up`: the next f32 above a positive finite value.
fn round_up(x: f32) -> f32 {
    let bits = bitcast<u32>(x);
    if x > 0.0 && (bits & 0x7f800000u) != 0x7f800000u {
        return bitcast<f32>(bits + 1u);
    }
    return x;
}

struct TreeSphere {
    center: vec3<f32>,
    radius: f32,
}

// reference/src/scene/mod.rs `tree_sphere`: the mesh's local sphere scaled, rotated, translated.
fn tree_sphere(t: DrawInstance, mesh: MeshMeta) -> TreeSphere {
    let lx = (mesh.bbox_min[0] + mesh.bbox_max[0]) * 0.5 * t.scale;
    let ly = (mesh.bbox_min[1] + mesh.bbox_max[1]) * 0.5 * t.scale;
    let lz = (mesh.bbox_min[2] + mesh.bbox_max[2]) * 0.5 * t.scale;
    let s = sin(t.yaw);
    let c = cos(t.yaw);
    let rotated = vec3<f32>(c * lx - s * ly, s * lx + c * ly, lz);
    let base = vec3<f32>(t.position[0], t.position[1], t.position[2]);
    return TreeSphere(base + rotated, round_up(mesh.sphere_radius * t.scale));
}

// reference/src/select.rs `tree_within_draw_distance` (E§4.4's per-tree discard; common.wgsl).
fn tree_within_draw_distance(center: vec3<f32>) -> bool {
    return within_draw_distance(center, u.view.eye, u.view.forward, u.view.draw_distance);
}

// reference `vertex_stage`.
@vertex
fn tree_vertex(
    @builtin(vertex_index) vertex_index: u32,
    @builtin(instance_index) instance_index: u32,
) -> TreeVaryings {
    var out: TreeVaryings;
    out.clip = DISCARDED_POSITION;
    out.uv_depth_light = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    out.layer_command_scale = vec4<u32>(0u, 0u, 0u, 0u);
    let command = vertex_index >> COMMAND_SHIFT;
    let local = vertex_index & (MAX_MESH_VERTICES - 1u);
    // Without a count buffer the multi-draw runs every slot; slots past the count may hold a
    // previous frame's commands.
    if command >= counters.commands {
        return out;
    }
    let data = command_data[command];
    if data.lod == LOD_FAR {
        return far_vertex(command, local, instance_index);
    }
    // A point command (issue 33; point_commands.wgsl expanded it into `trees × n` instances):
    // instance `i` is the batch's tree at indirection entry `i / n`, record rank `i % n`.
    let points = u.points != 0u && data.billboard != 0u;
    var slot = instance_index;
    var point_rank = 0u;
    if points {
        let n = point_count(data.mesh);
        if n == 0u {
            return out;
        }
        slot = instance_index / n;
        point_rank = instance_index % n;
    }
    let tree_index = indirection[slot];
    var t = instances[tree_index];
    let mesh_meta = meshes[t.mesh];
    var sphere = tree_sphere(t, mesh_meta);
    if !tree_within_draw_distance(sphere.center) {
        return out;
    }
    // Far-field subsets (reference tree_stage; common.wgsl subset_*): weight 0 drops the tree,
    // `thin-scale` enlarges a kept one about its base.
    let rank = slot - data.first_tree;
    let d_tree = view_interval(sphere.center, 0.0, u.view.eye, u.view.forward).d;
    let code = subset_weight_code(rank, data.group_len, d_tree, u.view);
    if code == 0u {
        return out;
    }
    let band_scale = t.scale;
    let grow = subset_scale(d_tree, u.view);
    if grow != 1.0 {
        t.scale = t.scale * grow;
        sphere = tree_sphere(t, mesh_meta);
    }
    let base = vec3<f32>(t.position[0], t.position[1], t.position[2]);
    // The tree's scale, or under the `tree` granularity its progress through its own band at
    // its centre's depth (reference tree_stage's `fade_word`).
    var fade_word = bitcast<u32>(band_scale);
    if u.fade_granularity == FADE_GRANULARITY_TREE {
        let band = group_band(u.view, vec2<f32>(data.fade_start, data.fade_end), vec2<f32>(band_scale, band_scale));
        fade_word = bitcast<u32>(fade_progress(d_tree, band.x, band.y));
    }
    if points {
        // reference `shade_points`: the record of this rank in the mode's order, kept by
        // point_keep at the tree's centre depth and drawn scale (else a degenerate quad), a
        // square of half side point_half_side about point_centre in the camera's right/up
        // plane; its colour word (sRGB RGB) flat in the layer and as the uv's x (the
        // reference's first varying), lightness 1, the depth clamped as a billboard's.
        if point_rank >= point_count(t.mesh) {
            return out;
        }
        let r = point_record(t.mesh, point_index(t.mesh, point_rank));
        if !point_keep(r, u.point_mode, t.scale, d_tree, u.point_k) {
            return out;
        }
        let centre = point_centre(base, sin(t.yaw), cos(t.yaw), t.scale, r.pos);
        let half = point_half_side(r.area, t.scale);
        let q = far_quad_corner(local);
        let p_world = centre + u.cam_right * (q.x * half) + u.cam_up * (q.y * half);
        let p_rel = p_world - u.view.eye;
        var p_depth = p_rel.x * u.view.forward.x + p_rel.y * u.view.forward.y + p_rel.z * u.view.forward.z;
        let p_i = view_interval(sphere.center, sphere.radius, u.view.eye, u.view.forward);
        p_depth = min(max(p_depth, p_i.lo), p_i.hi);
        let word = r.rgba8 & 0xffffffu;
        out.clip = u.view_proj * vec4<f32>(p_world, 1.0);
        out.uv_depth_light = vec4<f32>(f32(word), 0.0, p_depth, 1.0);
        out.layer_command_scale = vec4<u32>(word, command, fade_word, subset_pack(rank, code));
        return out;
    }
    var world: vec3<f32>;
    var uv: vec2<f32>;
    var layer: u32;
    // The billboard's unit horizontal direction to the eye (sun-depth-plane's offset, issue 30).
    var toward_eye = vec3<f32>(0.0, 0.0, 0.0);
    if data.billboard == 0u {
        let v = vertices[mesh_meta.first_vertex + local];
        let p = vec3<f32>(v.position[0], v.position[1], v.position[2]) * t.scale;
        let s = sin(t.yaw);
        let c = cos(t.yaw);
        let rotated = vec3<f32>(c * p.x - s * p.y, s * p.x + c * p.y, p.z);
        world = base + rotated;
        uv = vec2<f32>(v.uv[0], v.uv[1]);
        layer = t.mesh;
    } else if u.billboard_views != VIEW_SPHERE_ELEVATION {
        // Octahedral impostors (issue 32; reference `octahedral_kind`): the eye's mesh-local
        // direction from the sphere centre picks the cell; the quad lies on the nearest frame.
        let corner_vertex = vertices[u.billboard_first_vertex + local];
        let corner = vec2<f32>(corner_vertex.uv[0], corner_vertex.uv[1]);
        let hemi = u.billboard_views == VIEW_SPHERE_HEMI_OCTAHEDRAL;
        let to_eye = u.view.eye - sphere.center;
        let s = sin(t.yaw);
        let c = cos(t.yaw);
        let local_eye = vec3<f32>(c * to_eye.x + s * to_eye.y, c * to_eye.y - s * to_eye.x, to_eye.z);
        let view = octahedral_view(local_eye, u.octahedral_grid, hemi);
        let frames = octahedral_frames(view, u.octahedral_grid);
        let nearest = frames.frames[frames.nearest];
        let basis = octahedral_frame_basis(octahedral_frame_direction(nearest, u.octahedral_grid, hemi));
        // The quad faces the eye (the basis of the eye's own direction); its corners' uv are
        // their re-projection onto the nearest frame.
        let len = sqrt(local_eye.x * local_eye.x + local_eye.y * local_eye.y + local_eye.z * local_eye.z);
        let quad = octahedral_frame_basis(vec3<f32>(local_eye.x / len, local_eye.y / len, local_eye.z / len));
        let right = vec3<f32>(c * quad.right.x - s * quad.right.y, s * quad.right.x + c * quad.right.y, quad.right.z);
        let up = vec3<f32>(c * quad.up.x - s * quad.up.y, s * quad.up.x + c * quad.up.y, quad.up.z);
        var h = vec3<f32>(u.view.eye.x - base.x, u.view.eye.y - base.y, 0.0);
        if dot(h, h) < 1e-12 {
            h = vec3<f32>(-u.view.forward.x, -u.view.forward.y, 0.0);
        }
        if dot(h, h) < 1e-12 {
            h = vec3<f32>(1.0, 0.0, 0.0);
        }
        toward_eye = h * (1.0 / length(h));
        // The quad fitted to the bounding box on the quad's basis (common.wgsl octahedral_quad_fit).
        let s_r = mesh_meta.sphere_radius;
        let half = vec3<f32>(
            (mesh_meta.bbox_max[0] - mesh_meta.bbox_min[0]) * 0.5,
            (mesh_meta.bbox_max[1] - mesh_meta.bbox_min[1]) * 0.5,
            (mesh_meta.bbox_max[2] - mesh_meta.bbox_min[2]) * 0.5,
        );
        let fit = octahedral_quad_fit(half, quad, s_r);
        let half_width = fit.x * s_r;
        let half_height = fit.y * s_r;
        let along_right = (2.0 * corner.x - 1.0) * half_width * t.scale;
        let along_up = (-half_height + (1.0 - corner.y) * (2.0 * half_height)) * t.scale;
        world = sphere.center + right * along_right + up * along_up;
        let fitted = vec2<f32>(0.5 + (corner.x - 0.5) * fit.x, 0.5 + (corner.y - 0.5) * fit.y);
        uv = octahedral_reproject(fitted, quad, basis);
        let n = max(u.octahedral_grid, MIN_OCTAHEDRAL_GRID);
        layer = octahedral_pack(t.mesh * n * n + view.cell, view);
    } else {
        let corner_vertex = vertices[u.billboard_first_vertex + local];
        let corner = vec2<f32>(corner_vertex.uv[0], corner_vertex.uv[1]);
        let to_eye = u.view.eye - base;
        let v_dot_u = to_eye.z / length(to_eye);
        let k_count = u.angle_count;
        let k = angle_index_for(u.angle_index_mode, v_dot_u, k_count);
        let elevation = bake_elevation(k, k_count);
        var h = vec3<f32>(to_eye.x, to_eye.y, 0.0);
        if dot(h, h) < 1e-12 {
            h = vec3<f32>(-u.view.forward.x, -u.view.forward.y, 0.0);
        }
        if dot(h, h) < 1e-12 {
            h = vec3<f32>(1.0, 0.0, 0.0);
        }
        h = h * (1.0 / length(h));
        toward_eye = h;
        // Azimuth views (issue 30): the eye's mesh-local azimuth picks the view(s).
        let t_az = azimuth_position(h.x, h.y, t.yaw, u.azimuth_count);
        let view = azimuth_view(u.azimuth_mode, t_az, u.azimuth_count);
        // Z × h and Z cos e - h sin e, written out (h.z = 0).
        let right = vec3<f32>(-h.y, h.x, 0.0);
        let s = sin(elevation);
        let c = cos(elevation);
        let up = vec3<f32>(-(h.x * s), -(h.y * s), c);
        let e = billboard_extent(mesh_meta, elevation);
        let along_right = (2.0 * corner.x - 1.0) * e.half_width * t.scale;
        let along_up = (e.bottom + (1.0 - corner.y) * e.height) * t.scale;
        world = base + right * along_right + up * along_up;
        uv = corner;
        layer = azimuth_pack(view_layer(t.mesh, k, k_count, view.j, u.azimuth_count), view.code);
    }
    let rel = world - u.view.eye;
    var depth = rel.x * u.view.forward.x + rel.y * u.view.forward.y + rel.z * u.view.forward.z;
    if data.billboard != 0u {
        let i = view_interval(sphere.center, sphere.radius, u.view.eye, u.view.forward);
        depth = min(max(depth, i.lo), i.hi);
    }
    out.clip = u.view_proj * vec4<f32>(world, 1.0);
    let radii = crown_radii(mesh_meta, t.scale);
    let lightness = vertex_lightness(
        u.shading, world, data.billboard != 0u, toward_eye, sphere.center, radii, u.sun, u.ambient,
    );
    out.uv_depth_light = vec4<f32>(uv, depth, lightness);
    out.layer_command_scale = vec4<u32>(layer, command, fade_word, subset_pack(rank, code));
    return out;
}

// reference `TreeShader::shade`.
@fragment
fn tree_fragment(in: TreeVaryings) -> TargetOutput {
    let uv = in.uv_depth_light.xy;
    let depth = in.uv_depth_light.z;
    let layer = in.layer_command_scale.x;
    // A billboard's azimuth word (issue 30): its view's layer and the blend's weight code.
    let view_layer = layer & ((1u << AZIMUTH_LAYER_BITS) - 1u);
    let azimuth_code = layer >> AZIMUTH_LAYER_BITS;
    let data = command_data[in.layer_command_scale.y];
    // The tree's scale, or its progress under the `tree` granularity (tree_vertex).
    let word = bitcast<f32>(in.layer_command_scale.z);
    // Both textures are sampled before any branch: implicit-LOD sampling needs uniform control
    // flow (the quad's derivatives); the layer index clamps to the array (WGSL and Vulkan). The
    // texture-space noise's explicit level reads the same derivatives, taken here for the same
    // reason (the reference's are the rasterizer's coarse ones).
    let mesh_texel = textureSample(mesh_textures, tree_sampler, uv, layer);
    var billboard_texel = textureSample(billboard_textures, tree_sampler, uv, view_layer);
    if u.billboard_views != VIEW_SPHERE_ELEVATION {
        // Octahedral impostors (issue 32; reference `octahedral_texel`): the nearest frame at
        // the quad's uv; under the blend the other two at the quad point re-projected onto their
        // frames (uniform branches: the implicit derivatives of the re-projected uvs stay
        // defined), mixed before the alpha test.
        let hemi = u.billboard_views == VIEW_SPHERE_HEMI_OCTAHEDRAL;
        let oview = octahedral_unpack_view(layer, u.octahedral_grid);
        // The word's low OCTAHEDRAL_LAYER_BITS (11, not the azimuth word's 12) are the cell's
        // first layer.
        let base_layer = (layer & ((1u << OCTAHEDRAL_LAYER_BITS) - 1u)) - oview.cell;
        let fr = octahedral_frames(oview, u.octahedral_grid);
        let near = fr.frames[fr.nearest];
        let t_near = textureSample(billboard_textures, tree_sampler, uv, base_layer + near);
        billboard_texel = t_near;
        if u.octahedral_blend == AZIMUTH_MODE_BLEND {
            let d0 = octahedral_frame_direction(near, u.octahedral_grid, hemi);
            let b0 = octahedral_frame_basis(d0);
            // The depth channel (issue 32; reference `octahedral_texel`): each frame one parallax
            // step along the eye's ray from the quad point.
            let e = octahedral_view_direction(oview, u.octahedral_grid, hemi);
            let q = octahedral_quad_point(uv, e, b0, d0);
            var texels = array<vec4<f32>, 3>(t_near, t_near, t_near);
            for (var k = 0u; k < 3u; k = k + 1u) {
                let f = fr.frames[k];
                let dk = octahedral_frame_direction(f, u.octahedral_grid, hemi);
                let bk = octahedral_frame_basis(dk);
                // Derivatives of the plane's re-projection (linear in uv), as the reference's
                // `reproject_duv`: the depth's steps must not pick the mip level. (A uniform
                // branch; without the depth channel the plane's sample as before.)
                let plane = octahedral_reproject(uv, b0, bk);
                var sampled = textureSample(billboard_textures, tree_sampler, plane, base_layer + f);
                if u.octahedral_depth != 0u {
                    let on_plane = octahedral_parallax_uv(q, e, dot3(q, dk), bk, dk);
                    let z = textureSampleGrad(
                        billboard_depth, tree_sampler, on_plane, base_layer + f, dpdx(plane), dpdy(plane),
                    );
                    let at = octahedral_parallax_uv(q, e, octahedral_depth_offset(z.r, z.a), bk, dk);
                    sampled = textureSampleGrad(
                        billboard_textures, tree_sampler, at, base_layer + f, dpdx(plane), dpdy(plane),
                    );
                    texels[k] = sampled;
                } else {
                    texels[k] = select(sampled, t_near, k == fr.nearest);
                }
            }
            billboard_texel = octahedral_mix(texels[0], texels[1], texels[2], fr.weights);
        }
    } else if u.azimuth_mode == AZIMUTH_MODE_BLEND && u.azimuth_count > 1u {
    // The azimuth blend samples the second view too (a uniform branch: the derivatives stay
    // defined) and mixes before the alpha test.
        let second = azimuth_second_layer(view_layer, u.azimuth_count);
        let other = textureSample(billboard_textures, tree_sampler, uv, second);
        billboard_texel = azimuth_mix(billboard_texel, other, azimuth_code);
    }
    let duv_dx = dpdxCoarse(uv);
    let duv_dy = dpdyCoarse(uv);
    if data.lod == LOD_FAR && u.far_kind == 1u + FAR_LOD_IMPOSTOR {
        // reference `TreeShader::impostor_fragment`: the nearest texel, kept where its alpha is
        // at least one half, opaque, LOD_ID_FAR.
        let t = impostor_texel_word(layer, uv);
        if t.x == 0u {
            discard;
        }
        var imp_out: TargetOutput;
        imp_out.color = vec4<f32>(srgb_decode(t.y), srgb_decode(t.y >> 8u), srgb_decode(t.y >> 16u), 1.0);
        imp_out.lod_id = LOD_ID_FAR;
        return imp_out;
    }
    if data.lod == LOD_FAR {
        // reference `TreeShader::far_fragment`: a screen door of the alpha, opaque colour.
        let pixel = vec2<u32>(in.clip.xy);
        let alpha = f32(in.layer_command_scale.z) / 255.0;
        if !(alpha > dither_threshold(pixel.x + u.pixel_origin_x, pixel.y + u.pixel_origin_y)) {
            discard;
        }
        let w = in.layer_command_scale.x;
        var far_out: TargetOutput;
        far_out.color = vec4<f32>(srgb_decode(w), srgb_decode(w >> 8u), srgb_decode(w >> 16u), 1.0);
        far_out.lod_id = LOD_ID_FAR;
        return far_out;
    }
    var texel = select(mesh_texel, billboard_texel, data.billboard != 0u);
    // A point's flat colour (issue 33; reference TreeShader): its sRGB RGB word (the flat
    // layer), opaque, so every alpha test keeps it.
    if u.points != 0u && data.billboard != 0u {
        texel = vec4<f32>(srgb_decode(layer), srgb_decode(layer >> 8u), srgb_decode(layer >> 16u), 1.0);
    }
    if texel.a < u.alpha_cutoff {
        discard;
    }
    // The fade of a fading command (reference/src/blend.rs BlendRule::fade).
    var weight = 1.0;
    var in_band = false;
    if data.fading != 0u {
        let pixel = vec2<u32>(in.clip.xy);
        var t: f32;
        var past_end: bool;
        if u.fade_granularity == FADE_GRANULARITY_TREE {
            t = word;
            past_end = word >= 1.0;
        } else {
            // The tree's own band: the command's (unit scale) times the tree's scale under a
            // scaled metric.
            let band = group_band(u.view, vec2<f32>(data.fade_start, data.fade_end), vec2<f32>(word, word));
            t = fade_progress(depth, band.x, band.y);
            past_end = depth >= band.y;
        }
        var h: f32;
        if u.dither_space == DITHER_SPACE_TEXTURE {
            h = texture_noise(uv, duv_dx, duv_dy, u.noise_size);
        } else {
            h = dither_threshold(pixel.x + u.pixel_origin_x, pixel.y + u.pixel_origin_y);
        }
        weight = lod_weight_of(weights_at(u.fade_mode, t, past_end, h), data.lod);
        in_band = t > 0.0 && t < 1.0;
    }
    // A tree leaving its far-field subset fades by its own screen door (issue 29).
    let pixel = vec2<u32>(in.clip.xy);
    weight = weight * subset_fragment_weight(
        in.layer_command_scale.w, u.fade_mode, pixel.x + u.pixel_origin_x, pixel.y + u.pixel_origin_y,
    );
    if weight <= 0.0 {
        discard;
    }
    var out: TargetOutput;
    // Sun-depth shading (issue 30): nothing is multiplied when unlit (bit-identical frames).
    var rgb = texel.rgb;
    if u.shading != SHADING_UNLIT {
        rgb = rgb * in.uv_depth_light.w;
    }
    out.color = vec4<f32>(rgb, weight);
    if in_band {
        out.lod_id = LOD_ID_TRANSITION;
    } else if data.billboard == 0u {
        out.lod_id = LOD_ID_MESH;
    } else {
        out.lod_id = LOD_ID_BILLBOARD;
    }
    return out;
}

struct TerrainVaryings {
    @builtin(position) clip: vec4<f32>,
    // Linear RGB.
    @location(0) color: vec3<f32>,
}

// reference `terrain_triangles`' vertex transform.
@vertex
fn terrain_vertex(@location(0) position: vec3<f32>, @location(1) color: vec3<f32>) -> TerrainVaryings {
    var out: TerrainVaryings;
    out.clip = u.view_proj * vec4<f32>(position, 1.0);
    out.color = color;
    return out;
}

// reference `draw_frame`'s ground shader: opaque, LOD_ID_TERRAIN.
@fragment
fn terrain_fragment(in: TerrainVaryings) -> TargetOutput {
    var out: TargetOutput;
    out.color = vec4<f32>(in.color, 1.0);
    out.lod_id = LOD_ID_TERRAIN;
    return out;
}
