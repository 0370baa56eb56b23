//! Draw execution (E§4.4; SPEC §5.5): the reference twin of `gpu/src/shaders/draw.wgsl`, written
//! shader-shaped: [`vertex_stage`] is the vertex shader, [`TreeShader`] the fragment shader, and
//! [`draw_frame`] replays the one multi-draw-indirect call command by command.
//!
//! ## Contract
//! - **Vertex pulling through the indirection** (E§4.4): for command `c` and instance `j`, the tree
//!   is `indirection[first_instance + j]`; vertex `index + base_vertex` splits into the command
//!   (`>> COMMAND_SHIFT`) and the mesh-local vertex. No per-command state changes: one draw call.
//! - **Per-tree draw-distance discard** (E§4.4 "a fine-grained discard operation, based on whether
//!   the tree is within the draw distance"): a tree whose bounding-sphere centre lies beyond the draw
//!   distance (view depth) emits no triangles ([`crate::select::tree_within_draw_distance`]).
//! - **LOD0** transforms the mesh: `p = base + Rz(yaw) · scale · local`.
//! - **LOD1** expands the billboard quad in the vertex stage (wgpu has no geometry stage): yaw faces
//!   the camera, tilt snaps to the elevation of the layer chosen by the angle index
//!   ([`forestlod_shared::angle_index_for`] of `V · U` with `V` from the tree base to the eye),
//!   extent from [`forestlod_shared::billboard_extent`], the frame of `shared::billboard`. When the
//!   eye is straight above the base (no horizontal direction) the camera's horizontal back vector
//!   stands in, and `+X` if that is degenerate too.
//! - **Azimuth views** (issue 30, E§7; `forestlod_shared::azimuth`): with `J > 1` the billboard's
//!   horizontal direction `h` to the eye, less the tree's yaw, picks the view
//!   ([`forestlod_shared::azimuth_position`], [`forestlod_shared::azimuth_view`]): the nearest, or
//!   the two nearest and the second's weight, packed with the layer into the layer varying
//!   ([`forestlod_shared::azimuth_pack`]; `J = 1` leaves the word the layer, today's).
//! - **Fade** (E§4.4; SPEC §6): every fragment carries its view depth `d = (p - eye) · forward`;
//!   for billboards it is clamped per vertex to the tree's bounding-sphere interval, so a quad corner
//!   poking out of the sphere never asks for a LOD its batch was not selected for. Weights come from
//!   [`forestlod_shared::lod_weights`] with the per-pixel [`forestlod_shared::dither_threshold`]; a
//!   weight of 0 discards, otherwise the fragment's alpha is the weight and blending is source-over
//!   (so weight 1 is an opaque write). Issue 30 (G§4) adds where the threshold comes from (the
//!   frame pixel, or a noise texture in the LOD's texture space) and what the progress is taken
//!   from (the fragment's depth, or the tree's centre, once per tree in the vertex stage):
//!   `crate::blend`, whose defaults are the rule above.
//! - **Alpha test**: a texel with alpha below `params.alpha_cutoff` is discarded; kept texels count
//!   as opaque (the fade weight alone sets the output alpha).
//! - **Textures**: LOD0 samples its mesh's texture, LOD1 the billboard array layer
//!   `mesh * K + k` (`mesh·K·J + k·J + j` with azimuth views), both trilinear with the implicit
//!   level of detail of the quad's derivatives. Under the azimuth blend the fragment samples the
//!   second view's layer too and mixes the two ([`forestlod_shared::azimuth_mix`]) before the
//!   alpha test.
//! - **Outputs**: colour (RGBA8 sRGB), depth, and the LOD-id view of E Fig. 3.1 in the aux target:
//!   [`LOD_ID_TERRAIN`], [`LOD_ID_MESH`], [`LOD_ID_BILLBOARD`], [`LOD_ID_TRANSITION`] (a fragment
//!   of a fading command whose view depth lies strictly inside the band, in every fade mode).
//! - **Shading** (G§5, issue 30; `forestlod_shared::light`): under a sun-depth mode each vertex
//!   carries its lightness (the 8th varying, perspective-interpolated) and the fragment multiplies
//!   its texel's linear RGB by it; under `unlit` nothing is multiplied (bit-identical frames).
//! - **The far level** (issue 32, `forestlod_shared::far`): a command with `lod = LOD_FAR` pulls
//!   no tree. Its instance is a cell of [`DrawResources::far`] (octant sprite or cube) or a node
//!   (hull); the vertex stage builds the cube's corner ([`forestlod_shared::cube_corner`]), the
//!   sprite's corner on the basis of the eye's direction from the cell
//!   ([`forestlod_shared::sprite_half`], the colour [`forestlod_shared::side_mix`] of that
//!   direction) or reads the hull's vertex, and passes the primitive's RGBA8 colour as two
//!   constant varyings: the RGB word in the layer's place, the alpha byte in the scale's. The
//!   fragment keeps a pixel where `alpha / 255` exceeds the pixel's
//!   [`forestlod_shared::dither_threshold`] (a screen door, no sorting) and writes the colour
//!   opaque with [`LOD_ID_FAR`]. Far levels are unlit (baked unlit).
//! - **Points** (issue 33, C§4.4, §4.6.3; `forestlod_shared::points`): under `lod1 = points` a
//!   LOD1 command's tree is drawn as the records of its point hierarchy that
//!   [`forestlod_shared::points::point_keep`] keeps at the tree's centre depth and drawn scale
//!   (`point_select`, `point_detail`), each a camera-facing square of side `√(A·s²)` at the
//!   tree's transform, two triangles, flat colour (the record's sRGB word in the first varying,
//!   unlit, opaque), depth-tested, with the billboard's fade and LOD id ([`drawn_point_records`],
//!   [`DrawnFrame::points_drawn`]).
//! - A flat terrain-following ground grid is drawn first ([`terrain_triangles`]), opaque.

use forestlod_shared::coverage;
use forestlod_shared::{
    AzimuthMode, COMMAND_SHIFT, Camera, CommandData, FadeGranularity, FadeMode, MAX_MESH_VERTICES,
    MeshMeta, Params, Shading, angle_index_for, azimuth_mix, azimuth_pack, azimuth_position,
    azimuth_second_layer, azimuth_unpack, azimuth_view, bake_elevation, billboard_extent,
    crown_radii, depth_offset, fade_progress, fitted_corner, frame_basis, frame_direction,
    octahedral_frames, octahedral_layer, octahedral_mix, octahedral_pack, octahedral_unpack,
    octahedral_view, parallax_uv, quad_fit, quad_point, reproject_duv, reproject_uv,
    subset_fragment_weight, subset_pack, subset_scale, subset_weight_code, vertex_lightness,
    view_direction, view_interval, view_layer,
};
use forestlod_shared::{
    FarLevel, FarLod, LOD_FAR, cube_corner, dither_threshold,
    impostor::{ImpostorQuad, impostor_corner, impostor_texel, impostor_texel_kept},
    pack_far_colour, side_mix, sprite_corner, sprite_half, unpack_far_colour,
};
use glam::{Mat4, Vec3, Vec4};

use crate::bake::BakedBillboards;
use crate::blend::BlendRule;
use crate::geometry::PackedGeometry;
use crate::raster::{
    ClearValues, DrawState, DrawStats, Fragment, FragmentOutput, MaskCounts, PassSet, PassShader,
    RenderTarget, SETUP_CHUNK, Triangle, TriangleSource, Vertex, draw_passes_streamed, round_exact,
};
use crate::sampler::{LodRule, Sampler, Texture};
use crate::scene::{Instance, Scene, tree_sphere};
use crate::select::{SelectUniform, Selection, tree_within_draw_distance};
use crate::texture::srgb_to_linear;

// The LOD-id codes, the sky colour and the ground grid are shared with the GPU twin
// (`forestlod_shared::{color, terrain}`); re-exported where the reference's users find them.
pub use forestlod_shared::{
    LOD_ID_BACKGROUND, LOD_ID_BILLBOARD, LOD_ID_FAR, LOD_ID_MESH, LOD_ID_TERRAIN,
    LOD_ID_TRANSITION, SKY_SRGB, TERRAIN_CELLS, TERRAIN_MARGIN, ground_color,
};

/// Varyings of the tree pipeline: `u, v, view depth, texture layer, command index, tree scale
/// (or the tree's fade progress), subset word, lightness`.
///
/// The lightness (issue 30, G§5, `forestlod_shared::light`) is 1 under `unlit`, and then unused.
///
/// Under `fade_granularity = tree` (issue 30, G§4, `crate::blend`) the sixth varying carries the
/// tree's progress `t` through its band instead of its scale: the fragment then needs no band,
/// so no scale, and `t` is constant over the tree like the scale (the argument below holds for
/// it too), so both LODs' fragments read it exactly.
///
/// The texture layer of a billboard is the azimuth word ([`forestlod_shared::azimuth_pack`],
/// issue 30): the layer and the azimuth blend's weight code, 24 bits, exact in an `f32` and
/// constant over the tree; with one azimuth (or the nearest view) the word is the layer.
///
/// The subset word ([`forestlod_shared::subset_pack`], issue 29) is the tree's far-field subset
/// weight code and its rank's dither shift, 24 bits, so exact in an `f32`, and constant over the
/// tree like the scale.
///
/// The tree scale is what the fragment scales its command's band by under a scaled LOD metric
/// ([`forestlod_shared::ViewUniform::group_band`] with `[s, s]`: a tree's own band, the one the
/// per-tree selection decides on). It is constant over the tree's triangles, and a constant
/// varying interpolates to itself bit for bit: clipping's `x + t (x - x)` is `x`, and the
/// perspective-correct `Σ q_i x / Σ q_i` is computed in `f64`, whose relative error (a few
/// 2^-53, the fragment's barycentrics lying in [0, 1]) is far below the half-ulp of the `f32`
/// it is rounded to. The GPU twin passes it flat (`draw.wgsl`), so both read the tree's scale
/// exactly (`raster::setup::tests::a_constant_varying_interpolates_to_itself`).
pub const TREE_VARYINGS: usize = 8;

/// The tree's world transform pieces the vertex stage needs.
#[derive(Clone, Copy, Debug)]
struct TreeFrame {
    base: Vec3,
    yaw: f32,
    scale: f32,
    mesh: u32,
    sphere_center: [f32; 3],
    sphere_radius: f32,
}

/// Everything a frame's draw reads, as bound resources would be.
pub struct DrawResources<'a> {
    /// The scene (instances are the per-tree data).
    pub scene: &'a Scene,
    /// Packed vertex and index buffers.
    pub geometry: &'a PackedGeometry,
    /// The indirection array the commands' instance ranges index: the batches' (E§4.2), or the
    /// `refine` stage's or a baseline's.
    pub indirection: &'a [u32],
    /// Mesh textures with mips, in mesh order.
    pub mesh_textures: &'a [Texture],
    /// Billboard array texture.
    pub billboards: &'a BakedBillboards,
    /// The far level (issue 32) the far commands draw, under `lod_levels = 3`.
    pub far: Option<&'a FarLevel>,
    /// The point LOD (issue 33) the LOD1 commands draw under `lod1 = points`; `None` draws
    /// billboards.
    pub points: Option<&'a crate::points::PointLod>,
    /// How the tree shader's implicit level of detail computes `ρ`: [`LodRule::Exact`] (the
    /// pipeline's); the others only for the reference frames that classify what a conforming
    /// adapter's other `λ` explains (`forestlod-harness`'s alternatives).
    pub lod_rule: LodRule,
}

/// The per-frame uniform of the draw stage (the `Camera` and `Params` bindings of `draw.wgsl`).
pub struct DrawUniform<'a> {
    /// Selection's uniform: eye, unit forward, draw distance.
    pub select: SelectUniform,
    /// The camera.
    pub camera: &'a Camera,
    /// `projection * view`.
    pub view_proj: Mat4,
    /// The parameters.
    pub params: &'a Params,
    /// The unit direction towards the sun ([`Params::sun_dir`]), computed once per frame.
    pub sun: [f32; 3],
}

impl<'a> DrawUniform<'a> {
    /// The uniform of a validated camera and parameters.
    pub fn new(camera: &'a Camera, params: &'a Params) -> Self {
        Self {
            select: SelectUniform::new(camera, params),
            camera,
            view_proj: camera.view_projection(),
            params,
            sun: params.sun_dir(),
        }
    }
}

/// The baked elevation layer `k` (in `0..K`) a billboard standing at `base` shows to an eye at
/// `eye`: the angle index ([`forestlod_shared::angle_index_for`], `params`' mode) of `V · U` with
/// `V` from the tree base to the eye (E Eq. 3.1). The vertex stage's choice, exposed so that
/// experiments can say which trees change layer between two poses. `params` must be valid
/// ([`Params::validate`]).
pub fn billboard_layer(base: Vec3, eye: Vec3, params: &Params) -> u32 {
    let to_eye = eye - base;
    let v_dot_u = to_eye.z / to_eye.length();
    let mode = params
        .angle_mode()
        .expect("parameters are validated before drawing");
    angle_index_for(mode, v_dot_u, params.angle_count)
}

/// The vertex shader: clip position and varyings of vertex `vertex_index` (index value plus
/// `base_vertex`) of instance `instance_index` (plus `first_instance`). `None` when the tree is
/// discarded by the draw distance (the GPU twin emits a degenerate position instead).
///
/// It is [`tree_stage`] (what depends only on the command and the tree) followed by
/// [`TreeStage::vertex`] (what depends on the vertex too): the same expressions as one
/// function, split so that the tree draw evaluates the first once per tree, not once per
/// vertex (issue 14, session 11: a mesh tree's vertices each computed the yaw's sine and cosine
/// twice and its bounding sphere; a billboard's four vertices each chose the layer, built the
/// frame and the view interval). Each value is computed by the same expression from the same
/// inputs either way, so the vertices are bit-identical.
pub fn vertex_stage(
    res: &DrawResources,
    selection: &Selection,
    uniform: &DrawUniform,
    vertex_index: u32,
    instance_index: u32,
) -> Option<Vertex<TREE_VARYINGS>> {
    let command = vertex_index >> COMMAND_SHIFT;
    let local = vertex_index & (MAX_MESH_VERTICES - 1);
    tree_stage(res, selection, uniform, command, instance_index)
        .map(|tree| tree.vertex(res, uniform, local))
}

/// The part of [`vertex_stage`] shared by every vertex of one tree in one command: `None` when
/// the draw distance discards the tree.
pub fn tree_stage(
    res: &DrawResources,
    selection: &Selection,
    uniform: &DrawUniform,
    command: u32,
    instance_index: u32,
) -> Option<TreeStage> {
    let (u, camera, params) = (&uniform.select, uniform.camera, uniform.params);
    let data = &selection.data[command as usize];
    if data.lod == LOD_FAR {
        return far_stage(res, uniform, command, instance_index);
    }
    let tree_index = res.indirection[instance_index as usize] as usize;
    let t = &res.scene.instances[tree_index];
    let mesh_meta = &res.geometry.meshes[t.mesh as usize];
    let (sphere_center, sphere_radius) = tree_sphere(t, mesh_meta);
    let tree = TreeFrame {
        base: Vec3::from(t.position),
        yaw: t.yaw,
        scale: t.scale,
        mesh: t.mesh,
        sphere_center,
        sphere_radius,
    };
    let within = tree_within_draw_distance(u, tree.sphere_center);
    coverage::hit(coverage::Threshold::DrawTreeDistance, !within);
    if data.billboard == 0 {
        coverage::hit(coverage::Threshold::DrawMeshTreeDistance, !within);
    }
    if !within {
        return None;
    }
    // Far-field subsets (issue 29, E§7, `forestlod_shared::subset`): the tree's rank in its
    // batch's progressive order, its weight at its centre's view depth; weight 0 drops it, and
    // `thin-scale` enlarges a kept tree about its base.
    let rank = instance_index.wrapping_sub(data.first_tree);
    let d_tree = view_interval(tree.sphere_center, 0.0, u.eye, u.forward).d;
    let code = subset_weight_code(
        rank,
        data.group_len,
        d_tree,
        u.subset_mode,
        u.subset_distance,
        u.subset_min,
    );
    if coverage::enabled() && data.group_len > 0 && u.subset_mode != 0 {
        coverage::hit(coverage::Threshold::DrawSubsetDrop, code == 0);
        if code > 0 {
            coverage::hit(
                coverage::Threshold::DrawSubsetFade,
                code < forestlod_shared::SUBSET_WEIGHT_STEPS,
            );
        }
    }
    if code == 0 {
        return None;
    }
    let subset = subset_pack(rank, code) as f32;
    let grow = subset_scale(d_tree, u.subset_mode, u.subset_distance, u.subset_min);
    let tree = if grow == 1.0 {
        tree
    } else {
        let drawn = Instance {
            scale: t.scale * grow,
            ..*t
        };
        let (sphere_center, sphere_radius) = tree_sphere(&drawn, mesh_meta);
        TreeFrame {
            scale: drawn.scale,
            sphere_center,
            sphere_radius,
            ..tree
        }
    };
    let eye = Vec3::from(camera.eye);
    let forward = Vec3::from(u.forward);
    let kind = if data.billboard == 0 {
        let (s, c) = tree.yaw.sin_cos();
        TreeKind::Mesh {
            first_vertex: mesh_meta.first_vertex,
            sin: s,
            cos: c,
            layer: tree.mesh as f32,
        }
    } else if forestlod_shared::octahedral::is_octahedral(params.billboard_views) {
        octahedral_kind(
            &tree, mesh_meta, eye, forward, camera.eye, u.forward, params,
        )
    } else {
        let to_eye = eye - tree.base;
        let k_count = params.angle_count;
        let k = billboard_layer(tree.base, eye, params);
        let elevation = bake_elevation(k, k_count);
        let mut h = Vec3::new(to_eye.x, to_eye.y, 0.0);
        if h.length_squared() < 1e-12 {
            h = Vec3::new(-forward.x, -forward.y, 0.0);
        }
        if h.length_squared() < 1e-12 {
            h = Vec3::X;
        }
        let h = h.normalize();
        // Azimuth views (issue 30): the eye's mesh-local azimuth picks the view(s).
        let j_count = params.azimuth_count;
        let t_az = azimuth_position(h.x, h.y, tree.yaw, j_count);
        if j_count > 1 {
            coverage::hit(
                coverage::Threshold::DrawAzimuthRound,
                t_az - t_az.floor() >= 0.5,
            );
        }
        let view = azimuth_view(params.azimuth_mode, t_az, j_count);
        let layer = view_layer(tree.mesh, k, k_count, view.j, j_count);
        let right = Vec3::Z.cross(h);
        let (s, c) = elevation.sin_cos();
        let up = Vec3::Z * c - h * s;
        let e = billboard_extent(mesh_meta, elevation);
        let interval = view_interval(
            tree.sphere_center,
            tree.sphere_radius,
            camera.eye,
            u.forward,
        );
        TreeKind::Billboard {
            origin: tree.base,
            toward_eye: h.to_array(),
            right,
            up,
            frame: None,
            half_width: e.half_width,
            bottom: e.bottom,
            height: e.height,
            layer: azimuth_pack(layer, view.code) as f32,
            depth_lo: interval.lo,
            depth_hi: interval.hi,
        }
    };
    // Sun-depth shading (G§5): the crown of the tree as drawn, its centre the drawn sphere's.
    let light = TreeLight {
        shading: params.shading,
        centre: tree.sphere_center,
        radii: crown_radii(mesh_meta, tree.scale),
        toward_eye: match kind {
            TreeKind::Billboard { toward_eye, .. } => toward_eye,
            _ => [0.0; 3],
        },
        sun: uniform.sun,
        ambient: params.ambient,
    };
    // The sixth varying ([`TREE_VARYINGS`]): the tree's own scale, or under the `tree`
    // granularity (issue 30, G§4) its progress through its own band at its centre's depth,
    // the band the fragment would otherwise scale by that scale (`crate::blend`).
    let fade_word = match params.fade_granularity {
        g if g == FadeGranularity::Tree as u32 => {
            let [fade_start, fade_end] =
                u.group_band([data.fade_start, data.fade_end], [t.scale, t.scale]);
            fade_progress(d_tree, fade_start, fade_end)
        }
        _ => t.scale,
    };
    Some(TreeStage {
        command,
        base: tree.base,
        scale: tree.scale,
        fade_word,
        subset,
        depth: d_tree,
        kind,
        light,
    })
}

/// The billboard of an octahedral impostor (issue 32, `forestlod_shared::octahedral`): the
/// eye's mesh-local direction from the tree's sphere centre picks the cell and the position in
/// it; the quad, a square of half side `S·scale` about the sphere centre, faces the eye (the
/// basis of the eye's direction, turned by the tree's yaw), its corners' `uv` their
/// re-projection onto the nearest frame, and its layer word is the cell's packed view. The
/// lighting's horizontal direction to the eye and the depth clamp are the thesis billboard's.
fn octahedral_kind(
    tree: &TreeFrame,
    mesh_meta: &MeshMeta,
    eye: Vec3,
    forward: Vec3,
    camera_eye: [f32; 3],
    view_forward: [f32; 3],
    params: &Params,
) -> TreeKind {
    let n = params.octahedral_grid;
    let hemi = forestlod_shared::octahedral::is_hemi(params.billboard_views);
    let centre = Vec3::from(tree.sphere_center);
    let to_eye = eye - centre;
    let (s, c) = tree.yaw.sin_cos();
    // World to mesh-local: the yaw turned back.
    let local = [
        c * to_eye.x + s * to_eye.y,
        c * to_eye.y - s * to_eye.x,
        to_eye.z,
    ];
    let view = octahedral_view(local, n, hemi);
    let frames = octahedral_frames(view, n);
    let nearest = frames.frames[frames.nearest];
    if coverage::enabled() {
        coverage::hit(
            coverage::Threshold::DrawOctahedralTriangle,
            view.qx + view.qy > forestlod_shared::OCTAHEDRAL_STEPS,
        );
    }
    let (r, u) = frame_basis(frame_direction(nearest, n, hemi));
    // The quad faces the eye: the basis of the eye's own direction (mesh-local).
    let len = (local[0] * local[0] + local[1] * local[1] + local[2] * local[2]).sqrt();
    let (qr, qu) = frame_basis([local[0] / len, local[1] / len, local[2] / len]);
    let turn = |v: [f32; 3]| Vec3::new(c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]);
    let mut h = Vec3::new(eye.x - tree.base.x, eye.y - tree.base.y, 0.0);
    if h.length_squared() < 1e-12 {
        h = Vec3::new(-forward.x, -forward.y, 0.0);
    }
    if h.length_squared() < 1e-12 {
        h = Vec3::X;
    }
    let interval = view_interval(
        tree.sphere_center,
        tree.sphere_radius,
        camera_eye,
        view_forward,
    );
    // The quad fitted to the bounding box on the quad's basis (`quad_fit`).
    let s_r = mesh_meta.sphere_radius;
    let half = [0, 1, 2].map(|i| (mesh_meta.bbox_max[i] - mesh_meta.bbox_min[i]) * 0.5);
    let fit = quad_fit(half, qr, qu, s_r);
    TreeKind::Billboard {
        origin: centre,
        toward_eye: h.normalize().to_array(),
        right: turn(qr),
        up: turn(qu),
        frame: Some(OctahedralQuad {
            quad: [qr, qu],
            frame: [r, u],
            fit,
        }),
        half_width: fit[0] * s_r,
        bottom: -(fit[1] * s_r),
        height: 2.0 * (fit[1] * s_r),
        layer: octahedral_pack(octahedral_layer(tree.mesh, view.cell, n), view) as f32,
        depth_lo: interval.lo,
        depth_hi: interval.hi,
    }
}

/// An octahedral impostor's quad (issue 32): its basis and the nearest frame's (mesh-local), and
/// its fit in the sphere's square ([`forestlod_shared::quad_fit`]).
#[derive(Clone, Copy, Debug)]
struct OctahedralQuad {
    quad: [[f32; 3]; 2],
    frame: [[f32; 3]; 2],
    fit: [f32; 2],
}

/// [`tree_stage`] for a far command (module docs): the cell (sprite, cube) or the node (hull)
/// `instance`; `None` when the frame has no far level or the instance is out of its range.
fn far_stage(
    res: &DrawResources,
    uniform: &DrawUniform,
    command: u32,
    instance: u32,
) -> Option<TreeStage> {
    let far = res.far?;
    let kind = match uniform.params.far_level().ok()? {
        FarLod::Hull => {
            let node = far.nodes.get(instance as usize)?;
            TreeKind::FarHull {
                offset: node.hull_offset,
            }
        }
        FarLod::Impostor => TreeKind::FarImpostor {
            quad: ImpostorQuad::from_cell(*far.cells.get(instance as usize)?),
        },
        lod => {
            let cell = far.cells.get(instance as usize)?;
            if lod == FarLod::OctantCube {
                TreeKind::FarCube {
                    center: Vec3::from(cell.center),
                    extent: Vec3::from(cell.extent),
                    colours: cell.colours,
                }
            } else {
                let to_eye = Vec3::from(uniform.camera.eye) - Vec3::from(cell.center);
                let len = (to_eye.x * to_eye.x + to_eye.y * to_eye.y + to_eye.z * to_eye.z).sqrt();
                let v = if len > 0.0 {
                    [to_eye.x / len, to_eye.y / len, to_eye.z / len]
                } else {
                    [0.0, 0.0, 1.0]
                };
                let (r, u) = frame_basis(v);
                TreeKind::FarSprite {
                    center: Vec3::from(cell.center),
                    right: Vec3::from(r),
                    up: Vec3::from(u),
                    half: sprite_half(cell.extent, r, u),
                    word: pack_far_colour(side_mix(&cell.colours, v)),
                }
            }
        }
    };
    Some(TreeStage {
        command,
        base: Vec3::ZERO,
        scale: 1.0,
        fade_word: 0.0,
        subset: 0.0,
        depth: 0.0,
        kind,
        light: TreeLight {
            shading: Shading::Unlit as u32,
            centre: [0.0; 3],
            radii: [0.0; 2],
            toward_eye: [0.0; 3],
            sun: uniform.sun,
            ambient: 1.0,
        },
    })
}

/// A far primitive's colour word as the two varyings (module docs): the RGB bytes as one 24-bit
/// integer and the alpha byte, both exact in an `f32`.
fn far_varyings(word: u32) -> (f32, f32) {
    ((word & 0x00ff_ffff) as f32, (word >> 24) as f32)
}

/// What [`tree_stage`] computed for one tree in one command.
#[derive(Clone, Copy, Debug)]
pub struct TreeStage {
    command: u32,
    base: Vec3,
    /// The scale the tree is drawn at (its own, or enlarged by `thin-scale`).
    scale: f32,
    /// The tree's own scale, what its LOD band scales with (the selection's); or, under the
    /// `tree` fade granularity, its progress through that band ([`TREE_VARYINGS`]).
    fade_word: f32,
    /// The subset word ([`TREE_VARYINGS`]) as an `f32`.
    subset: f32,
    /// The view depth of the tree's bounding-sphere centre (0 for a far primitive): the depth
    /// the point LOD's keep test reads (issue 33).
    depth: f32,
    kind: TreeKind,
    light: TreeLight,
}

/// What a tree's vertices are lit by ([`forestlod_shared::vertex_lightness`]'s per-tree inputs).
#[derive(Clone, Copy, Debug)]
struct TreeLight {
    shading: u32,
    centre: [f32; 3],
    radii: [f32; 2],
    /// The billboard's unit horizontal direction to the eye (zero for a mesh, which never reads it).
    toward_eye: [f32; 3],
    sun: [f32; 3],
    ambient: f32,
}

/// The per-tree values of a mesh (LOD0) or a billboard (LOD1) command.
#[derive(Clone, Copy, Debug)]
enum TreeKind {
    Mesh {
        first_vertex: u32,
        /// The yaw's sine and cosine.
        sin: f32,
        cos: f32,
        layer: f32,
    },
    Billboard {
        /// The point the quad's extent is measured from: the tree's base (elevation views) or its
        /// sphere centre (octahedral frames, issue 32).
        origin: Vec3,
        /// The unit horizontal direction from the tree to the eye (`ĥ`), the quad's facing.
        toward_eye: [f32; 3],
        right: Vec3,
        up: Vec3,
        /// An octahedral impostor's quad (issue 32): a corner's `uv` is its re-projection onto
        /// the nearest frame. `None` for the thesis's billboards (the corner is the `uv`).
        frame: Option<OctahedralQuad>,
        half_width: f32,
        bottom: f32,
        height: f32,
        layer: f32,
        /// The tree's bounding-sphere view-depth interval (the per-vertex depth's clamp).
        depth_lo: f32,
        depth_hi: f32,
    },
    /// An octant cube (issue 32): the cell's box and its six side colours.
    FarCube {
        center: Vec3,
        extent: Vec3,
        colours: [u32; forestlod_shared::SIDE_COUNT],
    },
    /// An octant sprite (issue 32): the quad facing the eye and its mixed colour word.
    FarSprite {
        center: Vec3,
        right: Vec3,
        up: Vec3,
        half: [f32; 2],
        word: u32,
    },
    /// A batch hull (issue 32): its first vertex in the far level's hull.
    FarHull { offset: u32 },
    /// A hierarchical impostor (issue 33 item 2, `forestlod_shared::impostor`): its quad.
    FarImpostor { quad: ImpostorQuad },
}

impl TreeStage {
    /// The command this tree was staged for.
    pub fn command(&self) -> u32 {
        self.command
    }

    /// The rest of [`vertex_stage`]: mesh-local vertex `local` of this tree.
    pub fn vertex(
        &self,
        res: &DrawResources,
        uniform: &DrawUniform,
        local: u32,
    ) -> Vertex<TREE_VARYINGS> {
        let (camera, view_proj) = (uniform.camera, &uniform.view_proj);
        let eye = Vec3::from(camera.eye);
        let forward = Vec3::from(uniform.select.forward);
        let far_word = match self.kind {
            TreeKind::FarCube {
                center,
                extent,
                colours,
            } => {
                let (face, s) = cube_corner(local);
                Some((center + Vec3::from(s) * extent, colours[face as usize]))
            }
            TreeKind::FarSprite {
                center,
                right,
                up,
                half,
                word,
            } => {
                let c = sprite_corner(local);
                Some((
                    center + right * (c[0] * half[0]) + up * (c[1] * half[1]),
                    word,
                ))
            }
            TreeKind::FarHull { offset } => res
                .far
                .and_then(|f| f.hull.get((offset + local) as usize))
                .map(|v| (Vec3::from(v.position), v.colour)),
            _ => None,
        };
        if let TreeKind::FarImpostor { quad } = self.kind {
            // The quad's corner and its texture coordinate; the slot rides as an exact `f32`.
            let (c, uv) = impostor_corner(local);
            let world = Vec3::from(quad.center)
                + Vec3::from(quad.right) * c[0]
                + Vec3::from(quad.up) * c[1];
            let depth = (world - eye).dot(forward);
            let clip = *view_proj * Vec4::new(world.x, world.y, world.z, 1.0);
            return Vertex::new(
                clip.to_array(),
                [
                    uv[0],
                    uv[1],
                    depth,
                    quad.slot as f32,
                    self.command as f32,
                    0.0,
                    0.0,
                    1.0,
                ],
            );
        }
        if let Some((world, word)) = far_word {
            let depth = (world - eye).dot(forward);
            let clip = *view_proj * Vec4::new(world.x, world.y, world.z, 1.0);
            let (rgb, alpha) = far_varyings(word);
            return Vertex::new(
                clip.to_array(),
                [0.0, 0.0, depth, rgb, self.command as f32, alpha, 0.0, 1.0],
            );
        }
        let (world, uv, layer) = match self.kind {
            TreeKind::Mesh {
                first_vertex,
                sin: s,
                cos: c,
                layer,
            } => {
                let v = res.geometry.vertices[(first_vertex + local) as usize];
                let p = Vec3::from(v.position) * self.scale;
                let rotated = Vec3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z);
                (self.base + rotated, v.uv, layer)
            }
            TreeKind::Billboard {
                origin,
                right,
                up,
                frame,
                half_width,
                bottom,
                height,
                layer,
                ..
            } => {
                let corner = res.geometry.vertices
                    [(res.geometry.billboard.first_vertex + local) as usize]
                    .uv;
                let along_right = (2.0 * corner[0] - 1.0) * half_width * self.scale;
                let along_up = (bottom + (1.0 - corner[1]) * height) * self.scale;
                let uv = match frame {
                    Some(q) => reproject_uv(
                        fitted_corner(corner, q.fit),
                        q.quad[0],
                        q.quad[1],
                        q.frame[0],
                        q.frame[1],
                    ),
                    None => corner,
                };
                (origin + right * along_right + up * along_up, uv, layer)
            }
            TreeKind::FarCube { .. }
            | TreeKind::FarSprite { .. }
            | TreeKind::FarHull { .. }
            | TreeKind::FarImpostor { .. } => {
                // Handled above; a hull vertex out of range draws at the eye, degenerate.
                (eye, [0.0; 2], 0.0)
            }
        };
        let mut depth = (world - eye).dot(forward);
        if let TreeKind::Billboard {
            depth_lo, depth_hi, ..
        } = self.kind
        {
            depth = depth.max(depth_lo).min(depth_hi);
        }
        let clip = *view_proj * Vec4::new(world.x, world.y, world.z, 1.0);
        let l = &self.light;
        let lightness = vertex_lightness(
            l.shading,
            world.to_array(),
            matches!(self.kind, TreeKind::Billboard { .. }),
            l.toward_eye,
            l.centre,
            l.radii,
            l.sun,
            l.ambient,
        );
        Vertex::new(
            clip.to_array(),
            [
                uv[0],
                uv[1],
                depth,
                layer,
                self.command as f32,
                self.fade_word,
                self.subset,
                lightness,
            ],
        )
    }
}

/// The fragment shader of the tree pipeline (module docs), one pass per alpha-test cutoff of
/// `alpha_cutoffs` ([`PassShader`]): a plain frame is one pass with `params.alpha_cutoff`; the
/// parity's alternative frames are six, the cutoff moved (issue 14). Everything but the alpha test
/// (the texel, the fade weight, the LOD id) is the same in every pass, so it is computed once
/// per fragment; each pass keeps the fragment when its own test does.
pub struct TreeShader<'a> {
    res: &'a DrawResources<'a>,
    selection: &'a Selection,
    /// The fade rule (`crate::blend`): mode, threshold space, progress granularity.
    blend: BlendRule,
    alpha_cutoffs: &'a [f32],
    /// `Camera::pixel_origin`: the frame pixel of the viewport's (0, 0) (a tile camera's is
    /// non-zero); the dither threshold is the frame pixel's.
    pixel_origin: [u32; 2],
    /// The frame's view constants: the LOD metric a fragment's band is scaled under
    /// ([`forestlod_shared::ViewUniform::group_band`]).
    view: SelectUniform,
    /// The shading mode (issue 30): whether the lightness varying multiplies the texel.
    shading: Shading,
    /// Whether octahedral impostors blend their three frames (issue 32).
    octahedral_blend: bool,
    /// Whether LOD1 commands draw points (issue 33): their colour is the flat word of the
    /// first varying, not a texel.
    points: bool,
    /// The impostor tile side under `far_lod = impostor` (issue 33 item 2), else 0: far
    /// fragments then sample the far level's atlas.
    impostor_side: u32,
}

impl<'a> TreeShader<'a> {
    /// The fragment shader of a frame drawn by `camera` under validated `params`, one pass per
    /// cutoff of `alpha_cutoffs`, the noise level's `ρ²` multiplied by `rho2_scale`
    /// ([`BlendRule::rho2_scale`]: 1 except in the parity test's alternative frames).
    pub(crate) fn new(
        res: &'a DrawResources<'a>,
        selection: &'a Selection,
        camera: &Camera,
        params: &Params,
        alpha_cutoffs: &'a [f32],
        rho2_scale: f32,
    ) -> Self {
        TreeShader {
            res,
            selection,
            blend: BlendRule {
                rho2_scale,
                ..BlendRule::new(params)
            },
            alpha_cutoffs,
            pixel_origin: camera.pixel_origin(),
            view: SelectUniform::new(camera, params),
            shading: params
                .shading_mode()
                .expect("parameters are validated before drawing"),
            octahedral_blend: params.octahedral_blend == AzimuthMode::Blend as u32,
            points: res.points.is_some() && forestlod_shared::points::draws_points(params),
            impostor_side: if params.lod_levels >= 3 && params.far_level() == Ok(FarLod::Impostor) {
                params.impostor_pixels
            } else {
                0
            },
        }
    }

    /// The fade rule.
    pub(crate) fn blend(&self) -> BlendRule {
        self.blend
    }

    /// The frame's view constants.
    pub(crate) fn view(&self) -> SelectUniform {
        self.view
    }

    /// The command data of the fragment's command.
    fn data(&self, f: &Fragment<TREE_VARYINGS>) -> &'a CommandData {
        // `round_exact` is `f32::round` bit for bit, without a libm call (issue 14).
        &self.selection.data[round_exact(f.varyings[4]) as usize]
    }

    /// The fragment's texel: its mesh's texture (LOD0) or its billboard layer, trilinear with
    /// the implicit level of detail of its `uv` derivatives.
    pub(crate) fn texel(&self, f: &Fragment<TREE_VARYINGS>) -> [f32; 4] {
        let [u, v, _, layer, ..] = f.varyings;
        let data = self.data(f);
        let layer = round_exact(layer) as u32;
        let uv = [u, v];
        let (ddx, ddy) = ([f.ddx[0], f.ddx[1]], [f.ddy[0], f.ddy[1]]);
        // The implicit level of detail's rule (`LodRule::Exact` but in the parity's alternative
        // frames of the Vulkan specification's other scale-factor models).
        let sampler = Sampler {
            lod_rule: self.res.lod_rule,
            ..Sampler::TRILINEAR
        };
        if data.billboard == 0 {
            self.res.mesh_textures[layer as usize].sample(&sampler, 0, uv, ddx, ddy)
        } else if self.res.billboards.views().octahedral() {
            self.octahedral_texel(&sampler, layer, uv, ddx, ddy)
        } else {
            // The azimuth word (issue 30): the view's layer, and the blend's second view.
            let (layer, code) = azimuth_unpack(layer);
            let array = &self.res.billboards.texture;
            let first = array.sample(&sampler, layer, uv, ddx, ddy);
            if code == 0 {
                first
            } else {
                let j_count = self.res.billboards.azimuth_count;
                let second = azimuth_second_layer(layer, j_count);
                let other = array.sample(&sampler, second, uv, ddx, ddy);
                azimuth_mix(first, other, code)
            }
        }
    }
}

fn dot3(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl TreeShader<'_> {
    /// An octahedral impostor's texel (issue 32, `forestlod_shared::octahedral`): the nearest
    /// frame at the quad's `uv`; under the blend, the other two at the quad point re-projected
    /// onto their frames (their derivatives the same linear map of the quad's), mixed
    /// premultiplied.
    fn octahedral_texel(
        &self,
        sampler: &Sampler,
        word: u32,
        uv: [f32; 2],
        ddx: [f32; 2],
        ddy: [f32; 2],
    ) -> [f32; 4] {
        let baked = self.res.billboards;
        let (n, hemi) = (
            baked.grid,
            forestlod_shared::octahedral::is_hemi(baked.sphere),
        );
        let (cell_layer, view) = octahedral_unpack(word, n);
        let base = cell_layer - view.cell;
        let fr = octahedral_frames(view, n);
        let array = &baked.texture;
        let near = fr.frames[fr.nearest];
        if !self.octahedral_blend {
            return array.sample(sampler, base + near, uv, ddx, ddy);
        }
        let d0 = frame_direction(near, n, hemi);
        let (r0, u0) = frame_basis(d0);
        let basis = |f: u32| {
            let d = frame_direction(f, n, hemi);
            let (r, u) = frame_basis(d);
            (r, u, d)
        };
        // The depth channel (issue 32, module docs of `forestlod_shared::octahedral`): each
        // frame sampled one parallax step along the eye's ray from the quad point.
        if let Some(depth) = baked.depth.as_ref() {
            let e = view_direction(view, n, hemi);
            let q = quad_point(uv, e, (r0, u0, d0));
            let texels = core::array::from_fn(|k| {
                let f = fr.frames[k];
                let (r, u, d) = basis(f);
                // Derivatives of the plane's re-projection (linear in uv): the depth's steps must
                // not pick the mip level.
                let (dx, dy) = (
                    reproject_duv(ddx, r0, u0, r, u),
                    reproject_duv(ddy, r0, u0, r, u),
                );
                let plane = parallax_uv(q, e, dot3(q, d), (r, u, d));
                let z = depth.texture.sample(sampler, base + f, plane, dx, dy);
                let at = parallax_uv(q, e, depth_offset(z[0], z[3]), (r, u, d));
                array.sample(sampler, base + f, at, dx, dy)
            });
            return octahedral_mix(texels, fr.weights);
        }
        // Without the depth channel the nearest frame's own sample at the quad's uv.
        let first = array.sample(sampler, base + near, uv, ddx, ddy);
        let texels = core::array::from_fn(|k| {
            if k == fr.nearest {
                return first;
            }
            let (r, u, _) = basis(fr.frames[k]);
            let at = reproject_uv(uv, r0, u0, r, u);
            let (dx, dy) = (
                reproject_duv(ddx, r0, u0, r, u),
                reproject_duv(ddy, r0, u0, r, u),
            );
            array.sample(sampler, base + fr.frames[k], at, dx, dy)
        });
        octahedral_mix(texels, fr.weights)
    }
}

impl TreeShader<'_> {
    /// A far primitive's fragment (module docs): its colour where its alpha beats the pixel's
    /// dither threshold, opaque, [`LOD_ID_FAR`]; every pass alike (no alpha test).
    fn far_fragment(&self, f: &Fragment<TREE_VARYINGS>) -> Option<FragmentOutput> {
        if self.impostor_side > 0 {
            return self.impostor_fragment(f);
        }
        let rgb = round_exact(f.varyings[3]) as u32;
        let alpha = round_exact(f.varyings[5]) / 255.0;
        let (px, py) = (f.x + self.pixel_origin[0], f.y + self.pixel_origin[1]);
        let kept = alpha > dither_threshold(px, py);
        coverage::hit(coverage::Threshold::DrawFarAlpha, kept);
        if !kept {
            return None;
        }
        let c = unpack_far_colour(rgb | 0xff00_0000);
        Some(FragmentOutput {
            color: [c[0], c[1], c[2], 1.0],
            id: LOD_ID_FAR,
            depth: None,
        })
    }
}

impl TreeShader<'_> {
    /// A hierarchical impostor's fragment (`forestlod_shared::impostor`): the nearest texel of
    /// its tile, kept where its alpha is at least one half, opaque, [`LOD_ID_FAR`].
    fn impostor_fragment(&self, f: &Fragment<TREE_VARYINGS>) -> Option<FragmentOutput> {
        let far = self.res.far?;
        let slot = round_exact(f.varyings[3]) as u32;
        let quad = ImpostorQuad::from_cell(*far.cells.get(slot as usize)?);
        let side = self.impostor_side;
        let texel = impostor_texel(quad.size, side, f.varyings[0], f.varyings[1]);
        let word = *far
            .texels
            .get((slot as u64 * side as u64 * side as u64 + texel as u64) as usize)?;
        let kept = impostor_texel_kept(word);
        coverage::hit(coverage::Threshold::DrawFarAlpha, kept);
        if !kept {
            return None;
        }
        let c = unpack_far_colour(word | 0xff00_0000);
        Some(FragmentOutput {
            color: [c[0], c[1], c[2], 1.0],
            id: LOD_ID_FAR,
            depth: None,
        })
    }
}

impl PassShader<TREE_VARYINGS> for TreeShader<'_> {
    fn shade_passes(
        &self,
        f: &Fragment<TREE_VARYINGS>,
        passes: PassSet,
    ) -> Option<(FragmentOutput, PassSet)> {
        let subset = f.varyings[6];
        let lightness = f.varyings[7];
        let data = self.data(f);
        if data.lod == LOD_FAR {
            return self.far_fragment(f).map(|out| (out, passes));
        }
        // A point's flat colour (issue 33): its sRGB RGB word, opaque, so every alpha test
        // keeps it.
        let texel = if self.points && data.billboard != 0 {
            unpack_far_colour(round_exact(f.varyings[0]) as u32 | 0xff00_0000)
        } else {
            self.texel(f)
        };
        // The alpha test, per pass.
        let mut kept: PassSet = 0;
        for (p, &cutoff) in self.alpha_cutoffs.iter().enumerate() {
            if passes & (1 << p) != 0 {
                let discard = texel[3] < cutoff;
                coverage::hit(coverage::Threshold::DrawAlphaCutoff, discard);
                if !discard {
                    kept |= 1 << p;
                }
            }
        }
        if kept == 0 {
            return None;
        }
        let (px, py) = (f.x + self.pixel_origin[0], f.y + self.pixel_origin[1]);
        // The fade of a fading command (`crate::blend`: the threshold's space, the progress's
        // granularity; the rule before issue 30 at their defaults).
        let faded = (data.fading != 0).then(|| self.blend.fade(&self.view, data, f, px, py));
        let weight = faded.map_or(1.0, |d| d.weight);
        // A tree leaving its far-field subset fades by its own screen door (issue 29).
        let fade = self.blend.fade;
        let weight =
            weight * subset_fragment_weight(round_exact(subset) as u32, fade as u32, px, py);
        if coverage::enabled()
            && data.fading != 0
            && matches!(fade, FadeMode::Dither | FadeMode::DitherSequential)
        {
            coverage::hit(coverage::Threshold::DrawDither, weight > 0.0);
        }
        if weight <= 0.0 {
            return None;
        }
        let in_band = faded.is_some_and(|d| d.in_band());
        if data.fading != 0 {
            coverage::hit(coverage::Threshold::DrawTransitionId, in_band);
        }
        let id = if in_band {
            LOD_ID_TRANSITION
        } else if data.billboard == 0 {
            LOD_ID_MESH
        } else {
            LOD_ID_BILLBOARD
        };
        // Sun-depth shading (issue 30): nothing is multiplied when unlit.
        let texel = if self.shading == Shading::Unlit {
            texel
        } else {
            [
                texel[0] * lightness,
                texel[1] * lightness,
                texel[2] * lightness,
                texel[3],
            ]
        };
        let out = FragmentOutput {
            color: [texel[0], texel[1], texel[2], weight],
            id,
            depth: None,
        };
        Some((out, kept))
    }
}

/// The ground ([`forestlod_shared::terrain_grid`]: a `TERRAIN_CELLS`² grid over the footprint
/// plus [`TERRAIN_MARGIN`], following the terrain height, sunk 0.05 m so tree bases are not
/// z-fighting it), projected by `view_proj`. Varyings: linear RGB.
///
/// Speed-ups (issue 14, session 12), equalities both: the world-space grid depends only on the
/// scene's footprint and terrain, so it is remembered for the last ones asked for
/// ([`ground_grid`]) instead of evaluated per frame (the terrain's `sin`/`cos` and the ground
/// colour's `powf` per vertex were a fifth of a 320x180 frame without trees); and each shared
/// grid vertex is projected once ([`forestlod_shared::terrain_grid_vertices`]), not once per
/// triangle corner (the projection is a pure function of the vertex, so every corner gets the
/// same bits).
pub fn terrain_triangles(scene: &Scene, view_proj: &Mat4) -> Vec<Triangle<3>> {
    let project = |&(p, color): &([f32; 3], [f32; 3])| {
        let clip = *view_proj * Vec4::new(p[0], p[1], p[2], 1.0);
        Vertex::new(clip.to_array(), color)
    };
    let projected: Vec<Vertex<3>> = ground_grid(scene).iter().map(project).collect();
    forestlod_shared::axes_triangles(&scene.ground_axes())
        .map(|t| t.map(|k| projected[k as usize]))
        .collect()
}

/// [`forestlod_shared::terrain_grid_vertices`] of the scene's footprint and terrain, remembered
/// for the last footprint and terrain asked for (a frame loop draws one scene many times). The
/// key is every input as bits, so a hit returns what the call would, bit for bit
/// (`the_remembered_ground_grid_is_the_computed_one`).
fn ground_grid(scene: &Scene) -> std::sync::Arc<Vec<([f32; 3], [f32; 3])>> {
    use crate::scene::Terrain;
    use std::sync::{Arc, Mutex};
    // A grid terrain is keyed by its `Arc`, which the memo holds: while it is remembered its
    // address cannot be reused by another grid, so equal pointers mean the same heights.
    type Key = (
        [u32; 4],
        u32,
        [u32; 2],
        Option<Arc<crate::scene::HeightGrid>>,
    );
    type Grid = Arc<Vec<([f32; 3], [f32; 3])>>;
    static LAST: Mutex<Option<(Key, Grid)>> = Mutex::new(None);
    let terrain = match &scene.terrain {
        Terrain::Flat { z } => (0, [z.to_bits(), 0], None),
        Terrain::Hills {
            amplitude,
            wavelength,
        } => (1, [amplitude.to_bits(), wavelength.to_bits()], None),
        Terrain::Grid(g) => (2, [0, 0], Some(g.clone())),
    };
    let same = |a: &Key, b: &Key| {
        (a.0, a.1, a.2) == (b.0, b.1, b.2)
            && match (&a.3, &b.3) {
                (None, None) => true,
                (Some(p), Some(q)) => Arc::ptr_eq(p, q),
                _ => false,
            }
    };
    let key = (
        scene.bounds.map(f32::to_bits),
        terrain.0,
        terrain.1,
        terrain.2,
    );
    let mut last = LAST.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((k, grid)) = last.as_ref()
        && same(k, &key)
    {
        return grid.clone();
    }
    let grid = Arc::new(scene.ground_vertices());
    *last = Some((key, grid.clone()));
    grid
}

/// The result of drawing one frame.
pub struct DrawnFrame {
    /// Colour, depth and LOD-id buffers.
    pub target: RenderTarget,
    /// Ground draw counters.
    pub terrain_stats: DrawStats,
    /// Tree draw counters. In a frame drawn under a pixel mask ([`draw_frame_cutoffs`]) they count
    /// only the trees and triangles whose screen box meets the mask ([`TreeTriangles`]):
    /// `triangles_in`, clipping and setup counts are then lower than an unmasked draw's; the
    /// fragment counters count the masked pixels' fragments, which are an unmasked draw's.
    pub tree_stats: DrawStats,
    /// Trees dropped by the per-tree draw-distance discard.
    pub trees_discarded: u64,
    /// Point records drawn (issue 33, `lod1 = points`; 0 otherwise): each a square of two
    /// triangles.
    pub points_drawn: u64,
}

/// Assembles the tree triangles of every command in command order (the input assembly and vertex
/// stage of the multi-draw), skipping discarded trees.
pub fn tree_triangles(
    res: &DrawResources,
    selection: &Selection,
    camera: &Camera,
    params: &Params,
) -> (Vec<Triangle<TREE_VARYINGS>>, u64) {
    let mut source = TreeTriangles::new(res, selection, camera, params, None);
    let mut triangles = Vec::new();
    while let Some(piece) = source.next_triangles() {
        triangles.extend_from_slice(piece);
    }
    (triangles, source.discarded)
}

/// A radius about the tree's base point (`instance.position`) that contains every vertex the
/// vertex stage can give the tree: its mesh (every LOD's vertices lie in [`tree_sphere`], whose
/// centre is `|centre - base|` from the base) and its billboard quad at any layer, for any eye.
/// The quad is `base + R·a + U·b` with unit, orthogonal `R` and `U` (`shared::billboard`),
/// `|a| <= W·scale` and `b` in `[bottom, bottom + height]·scale`, whose ends
/// `z_min cos e - W sin e` and `z_max cos e + W sin e` are at most `max(|z_min|, |z_max|) + W` in
/// size: the quad lies within `scale·sqrt(W² + (max|z| + W)²)` of the base.
///
/// Under octahedral views (`octahedral`, issue 32) the quad is a square of half side `S·scale`
/// about the sphere centre (`S` the mesh's sphere radius), so its corners lie within
/// `|centre - base| + √2·S·scale` of the base (√2 rounded up by one ulp).
pub fn tree_footprint_radius(instance: &Instance, mesh: &MeshMeta, octahedral: bool) -> f32 {
    let (center, radius) = tree_sphere(instance, mesh);
    let to_centre = (Vec3::from(center) - Vec3::from(instance.position)).length();
    let mesh_r = to_centre + radius;
    let w = mesh.billboard_half_width.abs();
    let z = mesh.bbox_min[2].abs().max(mesh.bbox_max[2].abs()) + w;
    let quad_r = (w * w + z * z).sqrt() * instance.scale.abs();
    if octahedral {
        mesh_r.max(to_centre + core::f32::consts::SQRT_2 * (1.0 + f32::EPSILON) * radius)
    } else {
        mesh_r.max(quad_r)
    }
}

/// Pixels of slack around a tree's projected footprint ([`tree_footprint_meets_mask`]): a pixel
/// whose centre lies half a pixel outside the projected box is never covered, and f32 rounding
/// of the projection is far below a pixel; two pixels cover both with room.
const FOOTPRINT_SLACK_PX: f32 = 2.0;

/// Relative slack on the footprint radius: the vertex stage's world positions are rounded f32
/// sums (a few ulps of the coordinates' size), the radius and the box corners too.
const FOOTPRINT_SLACK_REL: f32 = 1.0e-3;

/// Whether a convex shape with clip-space corners `corners` may cover a pixel of `mask` in a
/// `width x height` target (conservative: true when in doubt). When every corner lies in front
/// of the eye (clip `w` above `min_w > 0`), the shape's projection, and every clipped piece of
/// it, lies in the corners' screen rectangle, which is widened by [`FOOTPRINT_SLACK_PX`] and
/// looked up in the mask's summed-area table. A corner at or behind `min_w`, or a non-finite
/// value, counts as the whole screen. A rectangle wholly off screen meets nothing: what lies in
/// it is clipped away or covers no pixel centre.
fn projection_meets_mask(
    corners: impl IntoIterator<Item = Vec4>,
    min_w: f32,
    mask: &MaskCounts,
    width: u32,
    height: u32,
) -> bool {
    let (half_w, half_h) = (width as f32 * 0.5, height as f32 * 0.5);
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (f32::MAX, f32::MIN, f32::MAX, f32::MIN);
    for clip in corners {
        // `w <= min_w` or NaN: in doubt.
        if !clip.is_finite() || clip.w <= min_w {
            return mask.any_in(0, 0, width, height);
        }
        // The viewport transform of `raster` (module docs, step 2).
        let x = (clip.x / clip.w) * half_w + half_w;
        let y = half_h - (clip.y / clip.w) * half_h;
        (x_lo, x_hi) = (x_lo.min(x), x_hi.max(x));
        (y_lo, y_hi) = (y_lo.min(y), y_hi.max(y));
    }
    let to_px = |v: f32, size: u32| v.clamp(0.0, size as f32) as u32;
    let x0 = to_px((x_lo - FOOTPRINT_SLACK_PX).floor(), width);
    let x1 = to_px((x_hi + FOOTPRINT_SLACK_PX).ceil(), width);
    let y0 = to_px((y_lo - FOOTPRINT_SLACK_PX).floor(), height);
    let y1 = to_px((y_hi + FOOTPRINT_SLACK_PX).ceil(), height);
    mask.any_in(x0, y0, x1, y1)
}

/// Whether a tree whose vertices lie within `radius` of `base` may cover a pixel of `mask`
/// ([`projection_meets_mask`] of the eight corners of the sphere's axis-aligned box, widened by
/// [`FOOTPRINT_SLACK_REL`]): a box reaching behind half the near plane (a tree at or around the
/// eye) counts as the whole screen.
fn tree_footprint_meets_mask(
    view_proj: &Mat4,
    near: f32,
    base: Vec3,
    radius: f32,
    mask: &MaskCounts,
    width: u32,
    height: u32,
) -> bool {
    let r = radius * (1.0 + FOOTPRINT_SLACK_REL) + base.abs().max_element() * FOOTPRINT_SLACK_REL;
    if !(r.is_finite() && base.is_finite()) {
        return mask.any_in(0, 0, width, height);
    }
    let corners = (0..8).map(|corner| {
        let sign = |bit: u32| if corner & bit != 0 { r } else { -r };
        let p = base + Vec3::new(sign(1), sign(2), sign(4));
        *view_proj * Vec4::new(p.x, p.y, p.z, 1.0)
    });
    projection_meets_mask(corners, 0.5 * near, mask, width, height)
}

/// Whether one tree triangle may cover a pixel of `mask` ([`projection_meets_mask`] of its
/// three vertices; any vertex within half the near distance of the eye plane keeps it).
fn triangle_meets_mask(
    tri: &Triangle<TREE_VARYINGS>,
    near: f32,
    mask: &MaskCounts,
    width: u32,
    height: u32,
) -> bool {
    let corners = tri.iter().map(|v| Vec4::from(v.clip));
    projection_meets_mask(corners, 0.5 * near, mask, width, height)
}

/// Triangles per parallel work item of [`TreeTriangles`] (an upper bound, from the commands'
/// index counts; an item holds at least one tree): one output vector per item, not per tree.
const TREE_RUN_TRIANGLES: usize = 1024;

/// [`tree_triangles`] handed to the rasterizer a piece at a time ([`TriangleSource`]), leaving
/// out, when `mask` is given, what cannot write a pixel of it: the trees within the draw
/// distance whose footprint misses it ([`tree_footprint_meets_mask`], as if they had no
/// triangles: before their vertex stage), then the triangles of the trees kept whose screen box
/// misses it ([`triangle_meets_mask`], before clipping and setup). Trees beyond the draw
/// distance are still counted as discarded.
///
/// Memory and speed (issue 14, session 11): a piece holds the trees, in draw order, whose
/// triangles number at most [`SETUP_CHUNK`] (at least one tree), shaded in parallel in items of
/// [`TREE_RUN_TRIANGLES`], and is drawn before the next is shaded. Before, the whole frame's
/// triangles were assembled first: `stress`' close camera has 10.7 M (1.15 GB), and allocating,
/// faulting in and copying them was over a third of its reference frame. The pieces
/// concatenate to exactly that list (the same trees in the same order), so the draw is the same
/// ([`draw_passes_streamed`]).
struct TreeTriangles<'a> {
    res: &'a DrawResources<'a>,
    selection: &'a Selection,
    camera: &'a Camera,
    uniform: DrawUniform<'a>,
    mask: Option<&'a MaskCounts>,
    /// Per command, the smallest and largest index it reads (the vertex cache's range).
    index_ranges: Vec<(u32, u32)>,
    /// The next tree: (command, instance within the command).
    next: (usize, u32),
    /// The current piece.
    piece: Vec<Triangle<TREE_VARYINGS>>,
    /// Trees discarded by the vertex stage so far.
    discarded: u64,
    /// Point records drawn so far (issue 33; 0 without the point LOD).
    points: u64,
    /// The point LOD's `[k_min, k_max]` ([`forestlod_shared::points::point_thresholds`] of
    /// `params.point_detail`).
    point_k: [f32; 2],
    /// `params.point_select`.
    point_mode: u32,
    /// The point LOD when `params` draw points ([`forestlod_shared::points::draws_points`]).
    points_lod: Option<&'a crate::points::PointLod>,
    /// The camera's frame: a point's square lies in its `right`, `up` plane.
    basis: forestlod_shared::CameraBasis,
}

impl<'a> TreeTriangles<'a> {
    fn new(
        res: &'a DrawResources<'a>,
        selection: &'a Selection,
        camera: &'a Camera,
        params: &'a Params,
        mask: Option<&'a MaskCounts>,
    ) -> Self {
        let index_ranges = selection
            .commands
            .iter()
            .map(|cmd| {
                let indices = &res.geometry.indices
                    [cmd.first_index as usize..(cmd.first_index + cmd.index_count) as usize];
                let lo = indices.iter().copied().min().unwrap_or(0);
                let hi = indices.iter().copied().max().unwrap_or(0);
                (lo, hi)
            })
            .collect();
        TreeTriangles {
            res,
            selection,
            camera,
            uniform: DrawUniform::new(camera, params),
            mask,
            index_ranges,
            next: (0, 0),
            piece: Vec::new(),
            discarded: 0,
            points: 0,
            point_k: forestlod_shared::points::DetailPreset::from_id(params.point_detail).map_or(
                [0.0; 2],
                |d| {
                    forestlod_shared::points::point_thresholds(
                        forestlod_shared::metric::metric_constant(camera, false),
                        &d.sizes(),
                    )
                },
            ),
            point_mode: params.point_select,
            points_lod: res
                .points
                .filter(|_| forestlod_shared::points::draws_points(params)),
            basis: camera.basis(),
        }
    }

    /// The point LOD of command `c`, when it draws points (a LOD1 command under `lod1 = points`).
    fn points_of(&self, c: u32) -> Option<&'a crate::points::PointLod> {
        let data = &self.selection.data[c as usize];
        self.points_lod
            .filter(|_| data.billboard != 0 && data.lod != LOD_FAR)
    }

    /// Upper bound of the triangles one instance of command `c` gives: its index count's, or
    /// under the point LOD two per record of its mesh.
    fn instance_triangles(&self, c: usize) -> usize {
        match self.points_of(c as u32) {
            Some(p) => {
                let mesh = self.selection.data[c].mesh as usize;
                2 * p.sets.get(mesh).map_or(0, |s| s.records.len())
            }
            None => self.selection.commands[c].index_count as usize / 3,
        }
    }

    /// [`Self::shade_instance`] for a point command (issue 33, `forestlod_shared::points`'s
    /// module docs): the tree's share of the vertex stage ([`tree_stage`]: the draw distance,
    /// the subset, the fade word), then per record of its range that
    /// [`forestlod_shared::points::point_keep`] keeps at the tree's centre depth and drawn scale,
    /// a square of half side [`forestlod_shared::points::point_half_side`] in the camera's
    /// `right`, `up` plane about [`forestlod_shared::points::point_centre`]: six vertices
    /// ([`sprite_corner`]), two triangles, its colour word (sRGB RGB, 24 bits, exact in an
    /// `f32`) in the first varying, lightness 1 (unlit), the per-vertex depth clamped to the
    /// tree's sphere interval as a billboard's. `None` when the tree is discarded, else the
    /// records drawn.
    fn shade_points(
        &self,
        points: &crate::points::PointLod,
        c: u32,
        instance: u32,
        out: &mut Vec<Triangle<TREE_VARYINGS>>,
    ) -> Option<u64> {
        use forestlod_shared::points::{point_centre, point_half_side};
        let (res, uniform) = (self.res, &self.uniform);
        let tree = tree_stage(res, self.selection, uniform, c, instance)?;
        let t = &res.scene.instances[res.indirection[instance as usize] as usize];
        let set = &points.sets[t.mesh as usize];
        let (sin, cos) = t.yaw.sin_cos();
        let (depth_lo, depth_hi) = match tree.kind {
            TreeKind::Billboard {
                depth_lo, depth_hi, ..
            } => (depth_lo, depth_hi),
            _ => (f32::NEG_INFINITY, f32::INFINITY),
        };
        let eye = Vec3::from(uniform.camera.eye);
        let forward = Vec3::from(uniform.select.forward);
        let (right, up) = (self.basis.right, self.basis.up);
        let mut kept = 0;
        for i in kept_records(points, self.point_mode, &tree, t.mesh, self.point_k) {
            let r = &set.records[i as usize];
            kept += 1;
            let centre = Vec3::from(point_centre(
                tree.base.to_array(),
                sin,
                cos,
                tree.scale,
                r.pos,
            ));
            let half = point_half_side(r.area, tree.scale);
            let word = (r.rgba8 & 0x00ff_ffff) as f32;
            let v: [Vertex<TREE_VARYINGS>; 6] = core::array::from_fn(|local| {
                let q = sprite_corner(local as u32);
                let world = centre + right * (q[0] * half) + up * (q[1] * half);
                let depth = (world - eye).dot(forward).max(depth_lo).min(depth_hi);
                let clip = uniform.view_proj * Vec4::new(world.x, world.y, world.z, 1.0);
                Vertex::new(
                    clip.to_array(),
                    [
                        word,
                        0.0,
                        depth,
                        0.0,
                        c as f32,
                        tree.fade_word,
                        tree.subset,
                        1.0,
                    ],
                )
            });
            out.push([v[0], v[1], v[2]]);
            out.push([v[3], v[4], v[5]]);
        }
        Some(kept)
    }

    /// Appends the triangles of `instance` of command `c` to `out` (those meeting the mask,
    /// when there is one); `false`, appending nothing, when the vertex stage discards the tree.
    ///
    /// Speed-up (issue 14): the vertex stage runs once per distinct index of an instance, not
    /// once per index (a mesh vertex is shared by several triangles; a GPU's post-transform
    /// cache does the same). [`vertex_stage`] is a pure function of its arguments, so the cached
    /// vertex is the one a second call would return, bit for bit. The cache is per work item.
    fn shade_instance(
        &self,
        cache: &mut Vec<Option<Vertex<TREE_VARYINGS>>>,
        c: u32,
        instance: u32,
        out: &mut Vec<Triangle<TREE_VARYINGS>>,
    ) -> Option<u64> {
        // A point command's trees are not culled by the mask: a record's square may reach past
        // the billboard's footprint.
        if let Some(points) = self.points_of(c) {
            return self.shade_points(points, c, instance, out);
        }
        let (res, camera, uniform) = (self.res, self.camera, &self.uniform);
        let cmd = &self.selection.commands[c as usize];
        let indices = &res.geometry.indices
            [cmd.first_index as usize..(cmd.first_index + cmd.index_count) as usize];
        let far = self.selection.data[c as usize].lod == LOD_FAR;
        if let Some(mask) = self.mask.filter(|_| !far) {
            let t = &res.scene.instances[res.indirection[instance as usize] as usize];
            let meta = &res.geometry.meshes[t.mesh as usize];
            let base = Vec3::from(t.position);
            // Beyond the draw distance the vertex stage discards the tree (and counts it).
            if tree_within_draw_distance(&uniform.select, tree_sphere(t, meta).0)
                && !tree_footprint_meets_mask(
                    &uniform.view_proj,
                    camera.near,
                    base,
                    tree_footprint_radius(t, meta, res.billboards.views().octahedral()),
                    mask,
                    camera.width,
                    camera.height,
                )
            {
                return Some(0);
            }
        }
        let (lo, hi) = self.index_ranges[c as usize];
        cache.clear();
        cache.resize((hi - lo) as usize + 1, None);
        let start = out.len();
        // The tree's share of the vertex stage, once per tree ([`vertex_stage`] is
        // `tree_stage` then `TreeStage::vertex`; every vertex of a command has the command's
        // bits, checked per vertex all the same).
        let mut tree: Option<TreeStage> = None;
        for t in indices.chunks_exact(3) {
            let mut tri = [Vertex::new([0.0; 4], [0.0; TREE_VARYINGS]); 3];
            for (k, &index) in t.iter().enumerate() {
                let slot = &mut cache[(index - lo) as usize];
                tri[k] = match slot {
                    Some(v) => *v,
                    None => {
                        let vertex_index = (index as i32 + cmd.base_vertex) as u32;
                        let command = vertex_index >> COMMAND_SHIFT;
                        let local = vertex_index & (MAX_MESH_VERTICES - 1);
                        if tree.is_none_or(|tree| tree.command() != command) {
                            tree = tree_stage(res, self.selection, uniform, command, instance);
                        }
                        let Some(tree) = &tree else {
                            out.truncate(start);
                            return None;
                        };
                        let v = tree.vertex(res, uniform, local);
                        *slot = Some(v);
                        v
                    }
                };
            }
            if self.mask.is_none_or(|mask| {
                triangle_meets_mask(&tri, camera.near, mask, camera.width, camera.height)
            }) {
                out.push(tri);
            }
        }
        Some(0)
    }
}

/// The records (area-order indices) a staged tree of `mesh` draws under the point LOD, in draw
/// order: those of its range ([`crate::points::PointLod::tree_records`]) that
/// [`forestlod_shared::points::point_keep`] keeps at its centre depth and drawn scale.
fn kept_records<'p>(
    points: &'p crate::points::PointLod,
    mode: u32,
    tree: &TreeStage,
    mesh: u32,
    k: [f32; 2],
) -> impl Iterator<Item = u32> + 'p {
    let set = &points.sets[mesh as usize];
    let (scale, depth) = (tree.scale, tree.depth);
    points
        .tree_records(mode, mesh, depth, scale, k)
        .filter(move |&i| {
            forestlod_shared::points::point_keep(&set.records[i as usize], mode, scale, depth, k)
        })
}

/// What the point LOD draws in a frame (issue 33; empty without it): per instance of every point
/// command, in draw order, the tree and the records it draws (area-order indices into its mesh's
/// [`crate::points::PointLod::sets`]); trees the vertex stage discards are left out. The draw's
/// own selection ([`TreeTriangles`]), exposed for the properties: their total is
/// [`DrawnFrame::points_drawn`].
pub fn drawn_point_records(
    res: &DrawResources,
    selection: &Selection,
    camera: &Camera,
    params: &Params,
) -> Vec<(u32, Vec<u32>)> {
    let source = TreeTriangles::new(res, selection, camera, params, None);
    let Some(points) = source.points_lod else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (c, cmd) in selection.commands.iter().enumerate() {
        if source.points_of(c as u32).is_none() {
            continue;
        }
        for j in 0..cmd.instance_count {
            let instance = cmd.first_instance + j;
            if let Some(tree) = tree_stage(res, selection, &source.uniform, c as u32, instance) {
                let t = res.indirection[instance as usize];
                let mesh = res.scene.instances[t as usize].mesh;
                let kept = kept_records(points, source.point_mode, &tree, mesh, source.point_k);
                out.push((t, kept.collect()));
            }
        }
    }
    out
}

impl TriangleSource<TREE_VARYINGS> for TreeTriangles<'_> {
    fn next_triangles(&mut self) -> Option<&[Triangle<TREE_VARYINGS>]> {
        use rayon::prelude::*;
        let commands = &self.selection.commands;
        // The piece's trees, in draw order, cut into work items.
        let mut trees: Vec<(u32, u32)> = Vec::new();
        let mut items: Vec<std::ops::Range<usize>> = Vec::new();
        let (mut piece_bound, mut item_bound) = (0usize, 0usize);
        while let Some(cmd) = commands.get(self.next.0) {
            if self.next.1 >= cmd.instance_count {
                self.next = (self.next.0 + 1, 0);
                continue;
            }
            let tris = self.instance_triangles(self.next.0);
            if !trees.is_empty() && piece_bound + tris > SETUP_CHUNK {
                break;
            }
            if items.is_empty() || item_bound + tris > TREE_RUN_TRIANGLES {
                items.push(trees.len()..trees.len());
                item_bound = 0;
            }
            trees.push((self.next.0 as u32, cmd.first_instance + self.next.1));
            items.last_mut().expect("an item").end = trees.len();
            piece_bound += tris;
            item_bound += tris;
            self.next.1 += 1;
        }
        if trees.is_empty() {
            return None;
        }
        let this = &*self;
        let shaded: Vec<(Vec<Triangle<TREE_VARYINGS>>, u64, u64)> = items
            .par_iter()
            .map_init(Vec::new, |cache, item| {
                let mut out = Vec::new();
                let (mut discarded, mut points) = (0, 0);
                for &(c, instance) in &trees[item.clone()] {
                    match this.shade_instance(cache, c, instance, &mut out) {
                        Some(n) => points += n,
                        None => discarded += 1,
                    }
                }
                (out, discarded, points)
            })
            .collect();
        self.piece.clear();
        for (tris, discarded, points) in shaded {
            self.piece.extend_from_slice(&tris);
            self.discarded += discarded;
            self.points += points;
        }
        Some(&self.piece)
    }
}

/// Draws one frame: sky, ground, then every command of `selection` (module docs). `params`
/// must be valid ([`Params::validate`]).
pub fn draw_frame(
    res: &DrawResources,
    selection: &Selection,
    camera: &Camera,
    params: &Params,
) -> DrawnFrame {
    let mut frames =
        draw_frame_cutoffs(res, selection, camera, params, &[params.alpha_cutoff], None);
    frames.pop().expect("one cutoff, one frame")
}

/// [`draw_frame`] once per alpha-test cutoff of `cutoffs` (every other parameter `params`'),
/// restricted to the pixels of `mask` when given ([`RenderTarget::with_pixel_mask`]). The vertex
/// stage, clipping, setup, binning and the walk over the quads are done once for all
/// ([`draw_passes`]: the cutoff enters only the fragment shader, whose texture sample, fade
/// weight and LOD id are shared too, [`TreeShader`]); each frame's buffers are those of its own [`draw_frame`] (at the masked
/// pixels when masked; the others keep the sky's clear values), and so are its counters when
/// unmasked. Under a mask, the trees and then the triangles whose screen box misses it are left
/// out before the vertex stage and before setup ([`TreeTriangles`]; they could write no masked
/// pixel): the tree counters' `triangles_in` and clipping and setup counts cover only what was
/// kept; `trees_discarded` is a plain draw's. What it is for: the parity's alternative
/// frames, the cutoff moved within the GPU's precision (issue 14). `params` must be valid
/// ([`Params::validate`]).
pub fn draw_frame_cutoffs(
    res: &DrawResources,
    selection: &Selection,
    camera: &Camera,
    params: &Params,
    cutoffs: &[f32],
    mask: Option<Vec<bool>>,
) -> Vec<DrawnFrame> {
    draw_frame_with(res, selection, camera, params, cutoffs, mask, 1.0)
}

/// [`draw_frame`] with the texture-space noise level's `ρ²` multiplied by `rho2_scale`
/// ([`forestlod_shared::noise_level_scaled`]), restricted to `mask` when given: the parity test's
/// alternative frames, whose noise levels move where a quad's `ρ²` lies within that factor of a
/// level boundary (the twins' derivatives differ by rounding, `shared/src/noise.rs`). At 1 it is
/// [`draw_frame`]. `params` must be valid ([`Params::validate`]).
pub fn draw_frame_noise_scaled(
    res: &DrawResources,
    selection: &Selection,
    camera: &Camera,
    params: &Params,
    rho2_scale: f32,
    mask: Option<Vec<bool>>,
) -> DrawnFrame {
    let mut frames = draw_frame_with(
        res,
        selection,
        camera,
        params,
        &[params.alpha_cutoff],
        mask,
        rho2_scale,
    );
    frames.pop().expect("one cutoff, one frame")
}

/// [`draw_frame_cutoffs`] with the noise level's `ρ²` scaled ([`draw_frame_noise_scaled`]).
fn draw_frame_with(
    res: &DrawResources,
    selection: &Selection,
    camera: &Camera,
    params: &Params,
    cutoffs: &[f32],
    mask: Option<Vec<bool>>,
    rho2_scale: f32,
) -> Vec<DrawnFrame> {
    // The sky and ground do not depend on the cutoff: drawn once, copied (issue 14).
    let mut grounds: Vec<(RenderTarget, DrawStats)> =
        vec![sky_and_ground_masked(res.scene, camera, mask.clone()); cutoffs.len()];
    let counts = mask
        .as_ref()
        .map(|m| MaskCounts::new(m, camera.width, camera.height));
    let mut source = TreeTriangles::new(res, selection, camera, params, counts.as_ref());
    let shader = TreeShader::new(res, selection, camera, params, cutoffs, rho2_scale);
    let state = DrawState {
        depth_write: true,
        ..DrawState::TRANSPARENT
    };
    let mut targets: Vec<&mut RenderTarget> =
        grounds.iter_mut().map(|(target, _)| target).collect();
    let stats = draw_passes_streamed(&mut targets, &shader, &mut source, &state);
    let (trees_discarded, points_drawn) = (source.discarded, source.points);
    grounds
        .into_iter()
        .zip(stats)
        .map(|((target, terrain_stats), tree_stats)| DrawnFrame {
            target,
            terrain_stats,
            tree_stats,
            trees_discarded,
            points_drawn,
        })
        .collect()
}

/// Draws every command of `selection` into `target`, which already holds what was drawn before
/// (no sky or ground; one cutoff, no mask): the two passes of a frame with occlusion culling
/// (issue 31, `forestlod_shared::occlusion`), whose tree draws are [`draw_frame`]'s split in two.
/// Returns the tree counters, the trees the draw distance discarded and the point records drawn. `params` must be valid.
pub fn draw_trees_into(
    res: &DrawResources,
    selection: &Selection,
    camera: &Camera,
    params: &Params,
    target: &mut RenderTarget,
) -> (DrawStats, u64, u64) {
    let mut source = TreeTriangles::new(res, selection, camera, params, None);
    let cutoffs = [params.alpha_cutoff];
    let shader = TreeShader::new(res, selection, camera, params, &cutoffs, 1.0);
    let state = DrawState {
        depth_write: true,
        ..DrawState::TRANSPARENT
    };
    let stats = draw_passes_streamed(&mut [target], &shader, &mut source, &state);
    (stats[0], source.discarded, source.points)
}

/// A `camera`-sized target cleared to the sky (colour [`SKY_SRGB`], depth 1, id
/// [`LOD_ID_BACKGROUND`]) with `scene`'s ground drawn (id [`LOD_ID_TERRAIN`]), and the ground's
/// work counters: how every rasterized frame starts.
pub fn sky_and_ground(scene: &Scene, camera: &Camera) -> (RenderTarget, DrawStats) {
    sky_and_ground_masked(scene, camera, None)
}

/// [`sky_and_ground`] into a target restricted to `mask` ([`RenderTarget::with_pixel_mask`]).
fn sky_and_ground_masked(
    scene: &Scene,
    camera: &Camera,
    mask: Option<Vec<bool>>,
) -> (RenderTarget, DrawStats) {
    let sky = SKY_SRGB.map(srgb_to_linear);
    let mut target = RenderTarget::new(
        camera.width,
        camera.height,
        ClearValues {
            color: [sky[0], sky[1], sky[2], 1.0],
            depth: 1.0,
            aux: LOD_ID_BACKGROUND,
        },
    );
    if let Some(mask) = mask {
        target = target.with_pixel_mask(mask);
    }
    let ground = terrain_triangles(scene, &camera.view_projection());
    let ground_shader = |f: &Fragment<3>| {
        Some(FragmentOutput {
            color: [f.varyings[0], f.varyings[1], f.varyings[2], 1.0],
            id: LOD_ID_TERRAIN,
            depth: None,
        })
    };
    let terrain_stats = target.draw(&ground, &ground_shader, &DrawState::OPAQUE);
    (target, terrain_stats)
}

/// Colour of each LOD-id in the debug view (E Fig. 3.1: green LOD0, blue LOD1, red transition).
pub fn lod_id_color(id: u32) -> [u8; 4] {
    match id {
        LOD_ID_MESH => [40, 200, 60, 255],
        LOD_ID_BILLBOARD => [50, 90, 230, 255],
        LOD_ID_TRANSITION => [230, 40, 40, 255],
        LOD_ID_TERRAIN => [90, 90, 90, 255],
        LOD_ID_FAR => [200, 150, 30, 255],
        _ => [20, 20, 20, 255],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Terrain;

    /// The ground drawn the plain way: [`forestlod_shared::terrain_grid`] evaluated now, each
    /// triangle corner projected on its own.
    fn plain_terrain_triangles(scene: &Scene, view_proj: &Mat4) -> Vec<Triangle<3>> {
        scene
            .ground_triangles()
            .into_iter()
            .map(|t| {
                t.map(|(p, color)| {
                    let clip = *view_proj * Vec4::new(p[0], p[1], p[2], 1.0);
                    Vertex::new(clip.to_array(), color)
                })
            })
            .collect()
    }

    /// Relative slack on [`tree_footprint_radius`] in its containment test: the corners are `f32`
    /// sums of products of the same few metres (ulps); a radius that leaves out a quad corner is
    /// short by metres (a good fraction of the crown).
    const FOOTPRINT_TEST_REL: f32 = 1e-5;

    /// [`tree_footprint_radius`] against its doc: every vertex the vertex stage can give a tree
    /// lies within it of the base, the mesh's box corners (any yaw, the tree's scale) and its
    /// billboard quad's corners `base + R·a + U·b` (built as `tree_stage` builds them) at every
    /// elevation in `[0, π/2]` (a sweep and every layer of `1..=16` layers) and toward every
    /// horizontal direction. The meshes are asymmetric in `z`: a box standing on its base that
    /// is as wide as it is high (the quad reaches beyond the mesh's sphere at about 35°), one
    /// hanging below its base, one floating above it. Added for issue 36's Rust mutant 1080
    /// (`bbox_min[2].abs().max(bbox_max[2].abs())` -> `.min(..)`: a smaller footprint could drop
    /// a tree from a masked draw; `tiny`'s trees are symmetric enough that no test saw it).
    #[test]
    fn the_footprint_holds_every_mesh_and_billboard_vertex() {
        let meta = |lo: [f32; 3], hi: [f32; 3]| MeshMeta {
            bbox_min: lo,
            bbox_max: hi,
            billboard_half_width: (lo[0].abs().max(hi[0].abs()).powi(2)
                + lo[1].abs().max(hi[1].abs()).powi(2))
            .sqrt(),
            // As `TreeMesh::meta`: half the box diagonal, about the box centre.
            sphere_radius: ((Vec3::from(hi) - Vec3::from(lo)) * 0.5).length(),
            ..bytemuck::Zeroable::zeroed()
        };
        let meshes = [
            ("square", meta([-5.0, -5.0, 0.0], [5.0, 5.0, 10.0])),
            ("hanging", meta([-3.0, -3.0, -12.0], [3.0, 3.0, 1.0])),
            ("floating", meta([-4.0, -2.0, 6.0], [3.0, 2.0, 9.0])),
        ];
        let mut elevations: Vec<f32> = (0..=90).map(|d| (d as f32).to_radians()).collect();
        for k_count in 1..=16 {
            elevations.extend((0..k_count).map(|k| bake_elevation(k, k_count)));
        }
        let mut worst = 0.0f32;
        for (name, mesh) in &meshes {
            for (position, yaw, scale) in [
                ([0.0, 0.0, 0.0], 0.0, 1.0),
                ([120.0, -40.0, 7.5], 2.3, 1.7),
                ([-3.0, 900.0, -2.0], 5.1, 0.4),
            ] {
                let instance = Instance {
                    position,
                    yaw,
                    scale,
                    mesh: 0,
                };
                let r = tree_footprint_radius(&instance, mesh, false);
                let base = Vec3::from(position);
                let mut check = |what: &str, p: Vec3| {
                    let d = (p - base).length();
                    worst = worst.max(d / r);
                    assert!(
                        d <= r * (1.0 + FOOTPRINT_TEST_REL),
                        "{name} (scale {scale}): {what} at {d} m from the base, footprint {r} m"
                    );
                };
                let (s, c) = yaw.sin_cos();
                for corner in 0..8 {
                    let pick = |k: usize| {
                        if corner >> k & 1 == 0 {
                            mesh.bbox_min[k]
                        } else {
                            mesh.bbox_max[k]
                        }
                    };
                    let p = Vec3::new(pick(0), pick(1), pick(2)) * scale;
                    let rotated = Vec3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z);
                    check("box corner", base + rotated);
                }
                for &elevation in &elevations {
                    for j in 0..8 {
                        let a = j as f32 * core::f32::consts::FRAC_PI_4 + 0.3;
                        let h = Vec3::new(a.cos(), a.sin(), 0.0);
                        let right = Vec3::Z.cross(h);
                        let (se, ce) = elevation.sin_cos();
                        let up = Vec3::Z * ce - h * se;
                        let e = billboard_extent(mesh, elevation);
                        for (u, v) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
                            let along_right = (2.0 * u - 1.0) * e.half_width * scale;
                            let along_up = (e.bottom + (1.0 - v) * e.height) * scale;
                            check(
                                &format!("quad corner ({u}, {v}) at elevation {elevation}"),
                                base + right * along_right + up * along_up,
                            );
                        }
                    }
                }
            }
        }
        println!("largest vertex distance over footprint radius: {worst}");
        assert!(
            worst > 0.5,
            "the vertices reach {worst} of the footprint only"
        );
    }

    /// `terrain_triangles` (remembered grid, shared vertices projected once) equals the plain
    /// evaluation bit for bit, for scenes that differ only in their footprint or only in their
    /// terrain, asked for in an order that hits and misses the memo.
    #[test]
    fn the_remembered_ground_grid_is_the_computed_one() {
        let a = crate::scene::builtin::tiny();
        let mut b = a.clone();
        b.terrain = match a.terrain {
            Terrain::Grid(_) => unreachable!("tiny has hills"),
            Terrain::Flat { z } => Terrain::Flat { z: z + 3.0 },
            Terrain::Hills {
                amplitude,
                wavelength,
            } => Terrain::Hills {
                amplitude: amplitude * 1.5,
                wavelength,
            },
        };
        let mut c = a.clone();
        c.bounds[2] += 250.0;
        let mut d = a.clone();
        d.terrain = Terrain::Hills {
            amplitude: 7.0,
            wavelength: 310.0,
        };
        // Two grid terrains (issue 34) of one shape and different heights: the memo must tell
        // them apart (it keys a grid by its `Arc`).
        let grid = |dz: f32| {
            Terrain::Grid(std::sync::Arc::new(crate::scene::HeightGrid {
                nx: 3,
                ny: 2,
                extent: [-50.0, -40.0, 60.0, 70.0],
                heights: vec![0.0, 1.0 + dz, 2.0, 3.0, 4.0 - dz, 5.0],
            }))
        };
        let (mut e, mut f) = (a.clone(), a.clone());
        e.terrain = grid(0.0);
        f.terrain = grid(2.5);
        let camera = Camera::look_at([-80.0, -120.0, 60.0], [40.0, 40.0, 0.0], 60.0, 320, 180);
        let vp = camera.view_projection();
        let bits = |t: &[Triangle<3>]| -> Vec<u32> {
            t.iter()
                .flatten()
                .flat_map(|v| v.clip.into_iter().chain(v.varyings))
                .map(f32::to_bits)
                .collect()
        };
        for scene in [&a, &a, &b, &a, &c, &d, &d, &b, &e, &e, &f, &e] {
            let got = terrain_triangles(scene, &vp);
            let want = plain_terrain_triangles(scene, &vp);
            assert_eq!(got.len(), want.len());
            assert!(
                bits(&got) == bits(&want),
                "terrain triangles differ from the plain evaluation (terrain {:?}, bounds {:?})",
                scene.terrain,
                scene.bounds
            );
        }
    }
}
