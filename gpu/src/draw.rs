//! Draw execution on the GPU (E§4.4; SPEC §5.5): the driver of `shaders/draw.wgsl`, twin of
//! `reference/src/draw.rs`.
//!
//! ## Contract
//! One render pass into three targets: colour ([`COLOR_FORMAT`], sRGB8, blended in linear light),
//! depth ([`DEPTH_FORMAT`], test LESS, written) and the LOD-id view of E Fig. 3.1
//! ([`LOD_ID_FORMAT`], not blended). The pass clears to the reference's values (sky
//! [`SKY_SRGB`], depth 1, id [`LOD_ID_BACKGROUND`]), draws the ground grid
//! ([`terrain_vertices`], opaque, one plain draw) and then **every** selected command with one
//! indirect call:
//! - `multi_draw_indexed_indirect_count` when the adapter has `MULTI_DRAW_INDIRECT_COUNT`, its
//!   count read by the GPU from the `select` counters ([`SelectBuffers::COUNT_OFFSET`]), so the
//!   CPU never learns how many commands there are (E§4.4);
//! - otherwise `multi_draw_indexed_indirect` over the buffers' whole capacity; the vertex stage
//!   then drops slots at or past `counters.commands` (they may hold an older frame's commands).
//!
//! Either way the CPU records two draw calls per frame whatever the tree and batch counts
//! ([`DrawCalls`]). `INDIRECT_FIRST_INSTANCE` is required (`first_instance` is the batch's offset
//! into the indirection array); [`GpuDraw::new`] fails with [`GpuError::Input`] without it.
//!
//! Under `lod1 = points` (issue 33 item 1, C§4.4, §4.6.3; `forestlod_shared::points`, "the point
//! command path") one compute dispatch (`point_commands.wgsl`) first rewrites a per-frame copy of
//! the commands, each LOD1 command becoming `trees × records` instances of one quad, and the
//! multi-draw reads that copy; the vertex stage decodes tree and record, keeps the record by
//! `point_keep` and draws a camera-facing square in flat colour, the reference's records in the
//! reference's order. The point records ride in the far buffer after the far level
//! ([`point_words`]).
//!
//! Under `far_lod = impostor` (issue 33 item 2, C§4.6.3; `forestlod_shared::impostor`) a far
//! command draws one quad per impostored node: the vertex stage places the corner of the
//! [`forestlod_shared::impostor::ImpostorQuad`] held in the far level's cell and passes its atlas
//! slot; the fragment reads the tile's nearest texel from the atlas, appended to the far buffer
//! ([`far_words`], [`DrawUniform::far_texel_base`]), keeps it where its alpha is at least one half
//! and writes it opaque with the far level's LOD id. The atlas changes every frame of a path:
//! [`DrawScene::write_far`] overwrites the far buffer in place (the tiles are the reference's).
//!
//! The vertex stage pulls everything from storage buffers ([`DrawScene`]): packed vertices
//! ([`DrawVertex`], the reference's `PackedVertex`), instances ([`DrawInstance`]), the
//! indirection array (the scene's, batch by batch, unless [`DrawInputs::indirection`] replaces
//! it: the Vegetation baseline draws the compacted visible trees of `cull.rs`, E§5), mesh
//! metadata, and the per-command data of `select` (or of `cull`). The fragment stage
//! samples one 2D array texture holding every mesh texture (one layer per mesh: binding arrays
//! are not portable, so all mesh textures must share one size; [`upload_texture_array`] says so
//! when they do not) or the billboard array (layer `mesh * K + k`, E Alg. 3.1; `mesh·K·J + k·J +
//! j` with `J` azimuth views, issue 30, whose blend samples a second layer and mixes the two before
//! the alpha test), trilinear with the implicit LOD, alpha-tests, fades and writes the LOD id. Every formula is the reference's,
//! operation for operation; see `draw.wgsl`.
//!
//! ## Where the GPU may differ (judged by `tests/src/image_compare.rs`, SPEC §8)
//! `sin`/`cos`/`asin`/`acos` and the matrix product round differently from the CPU's libm and
//! glam (vertex positions move by ~1e-7 relative, so a pixel centre within that of an edge may
//! flip), the GPU may fuse multiply-adds, and lavapipe filters with 8-bit subtexel weights and an
//! approximate `log2` for λ. None of these is a rule difference; each is classified in the
//! comparison, not hidden by a wider tolerance.

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use forestlod_shared::{Camera, MAX_COMMANDS, MAX_MESH_VERTICES, MeshMeta, Params, ViewUniform};
use wgpu::util::DeviceExt;

use crate::context::{
    Dispatch, Slot, StagePipelines, bind_group, buffer_entry, cleared_render_pass, compute_pass,
    compute_stage, group_layout, sampler_entry, shader_module, texture_entry,
};
use crate::readback::{frame_uniform, read_texture, upload_storage};
use crate::shaders::{StageSource, WgslFile};
use crate::{GpuContext, GpuError, SelectBuffers};

/// The `draw` stage's module: `draw.wgsl` (it reads only shared constants).
pub const SOURCE: StageSource = StageSource {
    own: WgslFile {
        name: "draw.wgsl",
        wgsl: include_str!("shaders/draw.wgsl"),
        constants: &[],
    },
    parts: &[],
};

/// The point LOD's command expansion (issue 33 item 1): `point_commands.wgsl`, run by
/// [`GpuDraw::encode`] before the draw pass under `lod1 = points` (module docs).
pub const POINT_SOURCE: StageSource = StageSource {
    own: WgslFile {
        name: "point_commands.wgsl",
        wgsl: include_str!("shaders/point_commands.wgsl"),
        constants: &[],
    },
    parts: &[],
};

/// The uniform of `point_commands.wgsl` (keep in sync with `PointCommandUniform` there).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PointCommandUniform {
    /// First word of the point header in the far buffer.
    pub point_base: u32,
    /// [`DrawSceneDesc::iota_first_index`].
    pub quad_first_index: u32,
    /// Command slots in the selection's buffers.
    pub capacity: u32,
    /// Meshes in the point header.
    pub mesh_count: u32,
}

crate::context::compute_pipelines! {
    /// The compiled pipeline of `point_commands.wgsl` (issue 33), one per [`GpuContext`].
    pub struct PointCommandPipelines = "point_commands", POINT_SOURCE.module(), [
        crate::context::Slot::Uniform(size_of::<PointCommandUniform>() as u64),
        crate::context::READ,
        crate::context::Slot::Read(size_of::<forestlod_shared::SelectCounters>() as u64),
        crate::context::READ,
        crate::context::WRITE,
    ],
    { expand: "expand_point_commands" }
}

/// Workgroup size of `expand_point_commands` (`point_commands.wgsl`).
const POINT_COMMANDS_WORKGROUP: u32 = 256;

/// The depth read-back by compute ([`DrawTarget::read`]), standalone: neither `common.wgsl` nor a
/// generated constant is prepended.
pub const DEPTH_COPY_WGSL: &str = include_str!("shaders/depth_copy.wgsl");

/// Format of the colour target (the reference's sRGB8 `RenderTarget` colour).
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// Format of the depth target.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Format of the LOD-id target (the reference's `aux` buffer).
pub const LOD_ID_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;
/// Format of the textures [`upload_texture_array`] creates (sRGB RGBA8, SPEC §3).
pub const TEXTURE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

// The LOD-id codes (mirrored in `draw.wgsl`), the sky colour and the ground grid are the
// reference's own, from `forestlod_shared::{color, terrain}`; re-exported at their old paths.
pub use forestlod_shared::{
    LOD_ID_BACKGROUND, LOD_ID_BILLBOARD, LOD_ID_MESH, LOD_ID_TERRAIN, LOD_ID_TRANSITION, SKY_SRGB,
    TERRAIN_CELLS, TERRAIN_MARGIN,
};

/// One vertex of the shared vertex buffer: the reference's `geometry::PackedVertex`, field for
/// field. Keep in sync with `struct DrawVertex` in `draw.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct DrawVertex {
    /// Mesh-local position (unit scale, zero yaw); for the billboard quad, unused.
    pub position: [f32; 3],
    /// Texture coordinate; for the billboard quad, the corner.
    pub uv: [f32; 2],
}
const _: () = assert!(size_of::<DrawVertex>() == 20);

/// One tree as the vertex stage reads it (the reference's `scene::Instance`). Keep in sync with
/// `struct DrawInstance` in `draw.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct DrawInstance {
    /// Base position relative to the scene origin.
    pub position: [f32; 3],
    /// Rotation about +Z, radians.
    pub yaw: f32,
    /// Uniform scale.
    pub scale: f32,
    /// Mesh index.
    pub mesh: u32,
}
const _: () = assert!(size_of::<DrawInstance>() == 24);

/// One ground vertex: world position and linear RGB colour.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct TerrainVertex {
    /// Position relative to the scene origin.
    pub position: [f32; 3],
    /// Linear RGB.
    pub color: [f32; 3],
}
const _: () = assert!(size_of::<TerrainVertex>() == 24);

/// The per-frame uniform of `draw.wgsl` (the reference's `DrawUniform`). Keep in sync with
/// `struct DrawUniform` there (layout checked by this module's tests).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct DrawUniform {
    /// `projection * view`, column-major.
    pub view_proj: [[f32; 4]; 4],
    /// The view constants ([`ViewUniform::new`]; the reference's `DrawUniform::select`): eye,
    /// unit forward and draw distance are what the draw reads.
    pub view: ViewUniform,
    /// Billboard angles K.
    pub angle_count: u32,
    /// `FadeMode` as `u32`.
    pub fade_mode: u32,
    /// `AngleIndexMode` as `u32`.
    pub angle_index_mode: u32,
    /// Alpha-test reference.
    pub alpha_cutoff: f32,
    /// First vertex of the billboard quad in the shared vertex buffer.
    pub billboard_first_vertex: u32,
    /// The frame pixel of the viewport's pixel (0, 0) (`Camera::pixel_origin`: non-zero for a
    /// tile camera): the dither threshold is the frame pixel's.
    pub pixel_origin_x: u32,
    /// See `pixel_origin_x`.
    pub pixel_origin_y: u32,
    /// `Shading` as `u32` (issue 30, `forestlod_shared::light`).
    pub shading: u32,
    /// `DitherSpace` as `u32` (issue 30, G§4): the dithered fades' threshold from the frame
    /// pixel or from the texture-space noise (`forestlod_shared::noise`).
    pub dither_space: u32,
    /// `FadeGranularity` as `u32` (issue 30, G§4): under `tree` the vertex stage passes the
    /// tree's progress in place of its scale.
    pub fade_granularity: u32,
    /// The texture-space noise's side, `Params::noise_size`.
    pub noise_size: u32,
    /// The ambient level of sun-depth shading.
    pub ambient: f32,
    /// The unit direction towards the sun ([`Params::sun_dir`]).
    pub sun: [f32; 3],
    /// [`forestlod_shared::depth_channel`] as 0/1 (issue 32): the octahedral blend re-projects
    /// the nearest frame's surface point from the depth channel (binding 11).
    pub octahedral_depth: u32,
    /// Billboard azimuth views `J` (issue 30, `Params::azimuth_count`).
    pub azimuth_count: u32,
    /// `AzimuthMode` as `u32`.
    pub azimuth_mode: u32,
    /// [`forestlod_shared::ViewSphere`] as `u32` (issue 32): elevation views or octahedral frames.
    pub billboard_views: u32,
    /// Octahedral grid side `N` (issue 32).
    pub octahedral_grid: u32,
    /// `AzimuthMode` as `u32` (issue 32): the nearest octahedral frame or the three blended.
    pub octahedral_blend: u32,
    /// The far level's primitive (issue 32, [`forestlod_shared::FarUniform::kind`]): 0 without
    /// a far level, else `1 + FarLod`.
    pub far_kind: u32,
    /// First word of the far level's node records in the far buffer ([`far_words`]).
    pub far_nodes_base: u32,
    /// First word of the far level's hull vertices in the far buffer.
    pub far_hull_base: u32,
    /// The camera's unit right vector (issue 33: a point's square lies in the camera's
    /// `right`, `up` plane, `Camera::basis`).
    pub cam_right: [f32; 3],
    /// [`forestlod_shared::points::draws_points`] as 0/1 (issue 33): LOD1 commands draw points.
    pub points: u32,
    /// The camera's unit up vector (issue 33).
    pub cam_up: [f32; 3],
    /// `PointSelect` as `u32` (`Params::point_select`).
    pub point_mode: u32,
    /// The point LOD's `[k_min, k_max]` ([`forestlod_shared::points::point_thresholds`] of
    /// `Params::point_detail`).
    pub point_k: [f32; 2],
    /// First word of the point header in the far buffer ([`point_words`]).
    pub point_base: u32,
    /// First word of the impostor atlas in the far buffer ([`far_words`]; issue 33 item 2).
    pub far_texel_base: u32,
    /// The impostor tile side (`Params::impostor_pixels`) under `far_lod = impostor`, else 0.
    pub impostor_side: u32,
    /// Explicit padding.
    pub _pad_impostor0: u32,
    /// Explicit padding.
    pub _pad_impostor1: u32,
    /// Explicit padding.
    pub _pad_impostor2: u32,
}
const _: () = assert!(size_of::<DrawUniform>() == 384);

impl DrawUniform {
    /// The uniform of a validated camera and parameters, derived as the reference derives its
    /// own (`DrawUniform::new` there: `SelectUniform`, i.e. [`ViewUniform::new`], and
    /// `Camera::view_projection`).
    pub fn new(camera: &Camera, params: &Params, billboard_first_vertex: u32) -> Self {
        Self {
            view_proj: camera.view_projection().to_cols_array_2d(),
            view: ViewUniform::new(camera, params),
            angle_count: params.angle_count,
            fade_mode: params.fade_mode,
            angle_index_mode: params.angle_index_mode,
            alpha_cutoff: params.alpha_cutoff,
            billboard_first_vertex,
            pixel_origin_x: camera.pixel_origin()[0],
            pixel_origin_y: camera.pixel_origin()[1],
            shading: params.shading,
            dither_space: params.dither_space,
            fade_granularity: params.fade_granularity,
            noise_size: params.noise_size,
            ambient: params.ambient,
            sun: params.sun_dir(),
            octahedral_depth: u32::from(forestlod_shared::depth_channel(params)),
            azimuth_count: params.azimuth_count,
            azimuth_mode: params.azimuth_mode,
            billboard_views: params.billboard_views,
            octahedral_grid: params.octahedral_grid,
            octahedral_blend: params.octahedral_blend,
            far_kind: 0,
            far_nodes_base: 0,
            far_hull_base: 0,
            cam_right: camera.basis().right.to_array(),
            points: u32::from(forestlod_shared::points::draws_points(params)),
            cam_up: camera.basis().up.to_array(),
            point_mode: params.point_select,
            point_k: point_k(camera, params),
            point_base: 0,
            far_texel_base: 0,
            impostor_side: 0,
            _pad_impostor0: 0,
            _pad_impostor1: 0,
            _pad_impostor2: 0,
        }
    }
}

/// The point LOD's `[k_min, k_max]` of a frame (the reference draw's `point_k`): the thresholds
/// of `Params::point_detail` at the camera's metric constant; `[0, 0]` for an unknown preset.
fn point_k(camera: &Camera, params: &Params) -> [f32; 2] {
    forestlod_shared::points::DetailPreset::from_id(params.point_detail).map_or([0.0; 2], |d| {
        forestlod_shared::points::point_thresholds(
            forestlod_shared::metric::metric_constant(camera, false),
            &d.sizes(),
        )
    })
}

/// The point LOD's words (issue 33), appended to the far buffer: per mesh `i` a header of three
/// words at `3·i` (first word of its records, record count, first word of its cut order, all
/// relative to the header's start), then each mesh's records ([`PointRecord`], 12 words each,
/// area order) and its cut order (area-order indices sorted by parent area). Empty for no meshes.
///
/// [`PointRecord`]: forestlod_shared::points::PointRecord
pub fn point_words(sets: &[(&[forestlod_shared::points::PointRecord], &[u32])]) -> Vec<u32> {
    let mut words = vec![0u32; 3 * sets.len()];
    for (i, (records, cut)) in sets.iter().enumerate() {
        words[3 * i] = words.len() as u32;
        words[3 * i + 1] = records.len() as u32;
        words.extend_from_slice(bytemuck::cast_slice(records));
        words[3 * i + 2] = words.len() as u32;
        words.extend_from_slice(cut);
    }
    words
}

/// Where a far level's parts start in its words ([`far_words`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FarBases {
    /// First word of the node records (4 words each).
    pub nodes: u32,
    /// First word of the hull vertices (4 words each).
    pub hull: u32,
    /// First word of the impostor atlas (issue 33 item 2: RGBA8 words, slot by slot).
    pub texels: u32,
    /// Words in all.
    pub len: u32,
}

/// A far level (issue 32) as the draw binds it: one `u32` buffer holding the cells
/// ([`forestlod_shared::FarCell`], 12 words each; under `far_lod = impostor` the
/// [`forestlod_shared::impostor::ImpostorQuad`]s) from word 0, then the node records (4 words
/// each), then the hull vertices (4 words each), then the impostor atlas (issue 33 item 2), each
/// from its [`FarBases`] word. One buffer, not four: the draw's vertex stage already binds six
/// storage buffers and WebGPU's default limit is eight per stage.
pub fn far_words(far: &forestlod_shared::FarLevel) -> (Vec<u32>, FarBases) {
    let mut words: Vec<u32> = bytemuck::cast_slice(&far.cells).to_vec();
    let nodes = words.len() as u32;
    words.extend_from_slice(bytemuck::cast_slice(&far.nodes));
    let hull = words.len() as u32;
    words.extend_from_slice(bytemuck::cast_slice(&far.hull));
    let texels = words.len() as u32;
    words.extend_from_slice(&far.texels);
    let len = words.len() as u32;
    (
        words,
        FarBases {
            nodes,
            hull,
            texels,
            len,
        },
    )
}

/// The ground grid as a triangle list in world space: [`forestlod_shared::terrain_grid`] (the
/// reference's `terrain_triangles` before projection: same grid, same vertex order, same colours),
/// [`TERRAIN_CELLS`]² cells over the footprint `bounds = [min_x, min_y, max_x, max_y]` plus
/// [`TERRAIN_MARGIN`], following `height(x, y)` (the scene's terrain), sunk 0.05 m.
pub fn terrain_vertices(bounds: [f32; 4], height: impl Fn(f32, f32) -> f32) -> Vec<TerrainVertex> {
    terrain_vertices_of(forestlod_shared::terrain_grid(bounds, height))
}

/// A ground triangle list (the reference scene's `ground_triangles`: the uniform grid, or an
/// elevation model's own grid, issue 34) as the vertices the ground pipeline draws, in order.
pub fn terrain_vertices_of(triangles: Vec<[([f32; 3], [f32; 3]); 3]>) -> Vec<TerrainVertex> {
    triangles
        .into_iter()
        .flatten()
        .map(|(position, color)| TerrainVertex { position, color })
        .collect()
}

/// One mip level of one layer, for [`upload_texture_array`]: sRGB RGBA8 texels, row-major from
/// the top-left.
#[derive(Clone, Copy, Debug)]
pub struct MipLevel<'a> {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// `width * height` texels.
    pub texels: &'a [[u8; 4]],
}

/// Uploads array layers (`layers[layer][level]`, level 0 first) into one 2D array texture of
/// [`TEXTURE_FORMAT`] with `TEXTURE_BINDING | COPY_DST | COPY_SRC` usage. Every layer must have the
/// same level 0 size and level count, level `k` being `max(1, w0 >> k)` x `max(1, h0 >> k)`;
/// anything else (mesh textures of different sizes, say) is a [`GpuError::Input`] naming the
/// layer, level and sizes. Used for the mesh textures (one layer per mesh) and for billboard
/// arrays computed on the CPU.
pub fn upload_texture_array(
    ctx: &GpuContext,
    label: &str,
    layers: &[Vec<MipLevel>],
) -> Result<wgpu::Texture, GpuError> {
    let bad = |field, value: String, reason| {
        Err(GpuError::Input {
            field,
            value,
            reason,
        })
    };
    let Some(base) = layers.first().and_then(|l| l.first()) else {
        return bad(
            "texture layers",
            format!("{label}: {} layers", layers.len()),
            "expected at least one layer with at least one level",
        );
    };
    let (w0, h0, levels) = (base.width, base.height, layers[0].len());
    if w0 == 0 || h0 == 0 {
        return bad(
            "texture size",
            format!("{label}: {w0}x{h0}"),
            "expected a non-empty level 0",
        );
    }
    let max_levels = (32 - w0.max(h0).leading_zeros()) as usize;
    if levels > max_levels {
        return bad(
            "texture levels",
            format!("{label}: {levels} levels for {w0}x{h0}"),
            "expected at most a full mip chain",
        );
    }
    if layers.len() as u32 > ctx.limits.max_texture_array_layers {
        return bad(
            "texture layers",
            format!(
                "{label}: {} layers, adapter limit {}",
                layers.len(),
                ctx.limits.max_texture_array_layers
            ),
            "expected no more layers than the adapter allows",
        );
    }
    for (layer, chain) in layers.iter().enumerate() {
        if chain.len() != levels {
            return bad(
                "texture levels",
                format!(
                    "{label}: layer {layer} has {} levels, layer 0 has {levels}",
                    chain.len()
                ),
                "expected every layer to have the same mip chain (one array texture)",
            );
        }
        for (level, l) in chain.iter().enumerate() {
            let (ew, eh) = ((w0 >> level).max(1), (h0 >> level).max(1));
            if l.width != ew || l.height != eh || l.texels.len() != (ew * eh) as usize {
                return bad(
                    "texture size",
                    format!(
                        "{label}: layer {layer} level {level} is {}x{} with {} texels, expected {ew}x{eh} (layer 0 level 0 is {w0}x{h0})",
                        l.width,
                        l.height,
                        l.texels.len()
                    ),
                    "expected every layer of one array texture to share its size (all mesh textures must be equally sized)",
                );
            }
        }
    }
    let texture = ctx.checked("texture array", || {
        let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: w0,
                height: h0,
                depth_or_array_layers: layers.len() as u32,
            },
            mip_level_count: levels as u32,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: TEXTURE_FORMAT,
            usage: wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_DST
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        for (layer, chain) in layers.iter().enumerate() {
            for (level, l) in chain.iter().enumerate() {
                ctx.queue.write_texture(
                    wgpu::TexelCopyTextureInfo {
                        texture: &texture,
                        mip_level: level as u32,
                        origin: wgpu::Origin3d {
                            x: 0,
                            y: 0,
                            z: layer as u32,
                        },
                        aspect: wgpu::TextureAspect::All,
                    },
                    bytemuck::cast_slice(l.texels),
                    wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(4 * l.width),
                        rows_per_image: Some(l.height),
                    },
                    wgpu::Extent3d {
                        width: l.width,
                        height: l.height,
                        depth_or_array_layers: 1,
                    },
                );
            }
        }
        texture
    })?;
    Ok(texture)
}

/// What [`DrawScene::new`] uploads: the reference's packed geometry, instances, indirection and
/// the ground, as plain slices.
#[derive(Clone, Copy, Debug)]
pub struct DrawSceneDesc<'a> {
    /// Shared vertex buffer, every mesh then the billboard quad.
    pub vertices: &'a [DrawVertex],
    /// Shared index buffer of mesh-local ids.
    pub indices: &'a [u32],
    /// Mesh metadata with packed offsets, in mesh order.
    pub meshes: &'a [MeshMeta],
    /// The billboard quad's range.
    pub billboard: MeshMeta,
    /// Trees.
    pub instances: &'a [DrawInstance],
    /// Tree indices, batch by batch (E§4.2).
    pub indirection: &'a [u32],
    /// The ground, from [`terrain_vertices`].
    pub terrain: &'a [TerrainVertex],
    /// The far level (issue 32) under `lod_levels = 3`.
    pub far: Option<&'a forestlod_shared::FarLevel>,
    /// The point LOD's records ([`point_words`]; issue 33), empty when the scene has none.
    pub points: &'a [u32],
    /// First index of an iota range (`0, 1, …`) of at least 6 indices in `indices` (the packed
    /// geometry's far range): the point commands' quad (issue 33).
    pub iota_first_index: u32,
}

/// A scene's static draw buffers on the GPU (what E§4.1 uploads once).
#[derive(Debug)]
pub struct DrawScene {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    pub(crate) instances: wgpu::Buffer,
    indirection: wgpu::Buffer,
    meshes: wgpu::Buffer,
    pub(crate) terrain: wgpu::Buffer,
    pub(crate) terrain_vertex_count: u32,
    billboard_first_vertex: u32,
    mesh_count: u32,
    /// The far level's words ([`far_words`]; one zero word without a far level).
    far: wgpu::Buffer,
    /// Whether a far level was uploaded, and where its parts start in `far`.
    far_bases: Option<FarBases>,
    /// The point LOD's header word in `far` and its largest record count, when uploaded.
    point_bases: Option<(u32, u32)>,
    /// [`DrawSceneDesc::iota_first_index`].
    iota_first_index: u32,
}

impl DrawScene {
    /// Validates and uploads. Errors name the first offending mesh, instance or index: a mesh
    /// range outside the buffers or with more than `MAX_MESH_VERTICES` vertices, an instance whose
    /// mesh is out of range, an indirection entry past the instances.
    pub fn new(ctx: &GpuContext, desc: &DrawSceneDesc) -> Result<Self, GpuError> {
        let bad = |field, value: String, reason| {
            Err(GpuError::Input {
                field,
                value,
                reason,
            })
        };
        let ranges = desc
            .meshes
            .iter()
            .enumerate()
            .map(|(i, m)| (format!("mesh {i}"), m))
            .chain(std::iter::once((
                "billboard quad".to_string(),
                &desc.billboard,
            )));
        for (name, m) in ranges {
            let vertex_end = m.first_vertex as u64 + m.vertex_count as u64;
            let index_end = m.first_index as u64 + m.index_count as u64;
            if m.vertex_count > MAX_MESH_VERTICES
                || vertex_end > desc.vertices.len() as u64
                || index_end > desc.indices.len() as u64
            {
                return bad(
                    "mesh range",
                    format!(
                        "{name}: vertices {}+{}, indices {}+{} of {} vertices, {} indices",
                        m.first_vertex,
                        m.vertex_count,
                        m.first_index,
                        m.index_count,
                        desc.vertices.len(),
                        desc.indices.len()
                    ),
                    "expected ranges inside the shared buffers and at most MAX_MESH_VERTICES (256) vertices per mesh",
                );
            }
        }
        if let Some((i, t)) = desc
            .instances
            .iter()
            .enumerate()
            .find(|(_, t)| t.mesh as usize >= desc.meshes.len())
        {
            return bad(
                "instance.mesh",
                format!("instance {i} mesh {} of {}", t.mesh, desc.meshes.len()),
                "expected a mesh index below the mesh count",
            );
        }
        if let Some((i, &t)) = desc
            .indirection
            .iter()
            .enumerate()
            .find(|&(_, &t)| t as usize >= desc.instances.len())
        {
            return bad(
                "indirection",
                format!("entry {i} = {t} of {} instances", desc.instances.len()),
                "expected tree indices below the instance count",
            );
        }
        use wgpu::BufferUsages as U;
        let (mut far_data, far_bases) = match desc.far {
            Some(f) => {
                let (words, bases) = far_words(f);
                (words, Some(bases))
            }
            None => (Vec::new(), None),
        };
        let point_bases = if desc.points.is_empty() {
            None
        } else {
            let meshes = desc.meshes.len();
            let header = desc.points.get(..3 * meshes).unwrap_or_default();
            let most = header.chunks_exact(3).map(|h| h[1]).max().unwrap_or(0);
            let iota = desc.indices.get(desc.iota_first_index as usize..);
            if header.len() != 3 * meshes
                || !iota.is_some_and(|i| i.starts_with(&[0, 1, 2, 3, 4, 5]))
            {
                return bad(
                    "point words",
                    format!(
                        "{} words for {meshes} meshes, iota range at index {}",
                        desc.points.len(),
                        desc.iota_first_index
                    ),
                    "expected a header of three words per mesh (point_words) and an iota range of at least 6 indices",
                );
            }
            let base = far_data.len() as u32;
            far_data.extend_from_slice(desc.points);
            Some((base, most))
        };
        let terrain = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("draw terrain"),
                contents: if desc.terrain.is_empty() {
                    &[0u8; size_of::<TerrainVertex>()]
                } else {
                    bytemuck::cast_slice(desc.terrain)
                },
                usage: U::VERTEX | U::COPY_DST,
            });
        Ok(Self {
            vertices: upload_storage(ctx, "draw vertices", desc.vertices, U::empty()),
            indices: upload_storage(ctx, "draw indices", desc.indices, U::INDEX),
            instances: upload_storage(ctx, "draw instances", desc.instances, U::empty()),
            indirection: upload_storage(ctx, "draw indirection", desc.indirection, U::empty()),
            meshes: upload_storage(ctx, "draw meshes", desc.meshes, U::empty()),
            terrain,
            terrain_vertex_count: desc.terrain.len() as u32,
            billboard_first_vertex: desc.billboard.first_vertex,
            mesh_count: desc.meshes.len() as u32,
            far: upload_storage(ctx, "draw far level", &far_data, U::empty()),
            far_bases,
            point_bases,
            iota_first_index: desc.iota_first_index,
        })
    }

    /// Replaces the uploaded far level's words with `far`'s (issue 33 item 2: under
    /// `far_lod = impostor` the far level is the frame's impostor state, written before each
    /// frame). `far` must have the uploaded level's shape (the same words in each part);
    /// otherwise, or without an uploaded far level, an error names both shapes.
    pub fn write_far(
        &self,
        ctx: &GpuContext,
        far: &forestlod_shared::FarLevel,
    ) -> Result<(), GpuError> {
        let (words, bases) = far_words(far);
        if self.far_bases != Some(bases) {
            return Err(GpuError::Input {
                field: "far level",
                value: format!(
                    "parts at {bases:?}, the scene uploaded {:?}",
                    self.far_bases
                ),
                reason: "expected a far level of the uploaded one's shape (the same node, cell, hull and texel counts)",
            });
        }
        ctx.queue
            .write_buffer(&self.far, 0, bytemuck::cast_slice(&words));
        Ok(())
    }

    /// The batch-by-batch tree indirection ([`DrawSceneDesc::indirection`]) the commands of a
    /// frame without `refine` index (the occlusion stage's input, issue 31).
    pub fn indirection(&self) -> &wgpu::Buffer {
        &self.indirection
    }

    /// Number of meshes.
    pub fn mesh_count(&self) -> u32 {
        self.mesh_count
    }

    /// A fresh uniform buffer labelled `label` holding this frame's [`DrawUniform`] for the scene
    /// (the draw's uniform, and the Primitive's for its terrain).
    pub(crate) fn draw_uniform(
        &self,
        ctx: &GpuContext,
        label: &str,
        camera: &Camera,
        params: &Params,
    ) -> wgpu::Buffer {
        let mut uniform = DrawUniform::new(camera, params, self.billboard_first_vertex);
        if let Some(bases) = self.far_bases {
            uniform.far_kind = forestlod_shared::FarUniform::new(camera, params).kind;
            uniform.far_nodes_base = bases.nodes;
            uniform.far_hull_base = bases.hull;
            uniform.far_texel_base = bases.texels;
            if uniform.far_kind == 1 + forestlod_shared::FarLod::Impostor as u32 {
                uniform.impostor_side = params.impostor_pixels;
            }
        }
        if let Some((base, _)) = self.point_bases {
            uniform.point_base = base;
        }
        frame_uniform(ctx, label, &uniform)
    }
}

/// The textures the fragment stage samples: every mesh texture (one layer per mesh) and the
/// billboard array (layer `mesh * K + k`), both with full mip chains, filterable float formats
/// (sRGB RGBA8 from [`upload_texture_array`] or from the GPU bake).
#[derive(Debug)]
pub struct DrawTextures {
    mesh: wgpu::TextureView,
    billboards: wgpu::TextureView,
    /// The octahedral impostors' depth channel (issue 32), when baked.
    depth: Option<wgpu::TextureView>,
    mesh_layers: u32,
    billboard_layers: u32,
    depth_layers: u32,
}

/// A view of a 2D array texture the draw samples (`TEXTURE_BINDING` usage, a filterable float
/// format), or an error naming `what`.
fn sampled_array_view(
    t: &wgpu::Texture,
    what: &'static str,
) -> Result<wgpu::TextureView, GpuError> {
    let filterable = matches!(
        t.format().sample_type(None, None),
        Some(wgpu::TextureSampleType::Float { filterable: true })
    );
    if !filterable
        || !t.usage().contains(wgpu::TextureUsages::TEXTURE_BINDING)
        || t.dimension() != wgpu::TextureDimension::D2
    {
        return Err(GpuError::Input {
            field: what,
            value: format!("{:?} {:?} {:?}", t.format(), t.dimension(), t.usage()),
            reason: "expected a 2D (array) texture of a filterable float format with TEXTURE_BINDING usage",
        });
    }
    Ok(t.create_view(&wgpu::TextureViewDescriptor {
        label: Some(what),
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    }))
}

impl DrawTextures {
    /// Views of two 2D array textures (`TEXTURE_BINDING` usage, a filterable float format).
    pub fn new(mesh: &wgpu::Texture, billboards: &wgpu::Texture) -> Result<Self, GpuError> {
        Ok(Self {
            mesh: sampled_array_view(mesh, "mesh texture array")?,
            billboards: sampled_array_view(billboards, "billboard texture array")?,
            depth: None,
            mesh_layers: mesh.depth_or_array_layers(),
            billboard_layers: billboards.depth_or_array_layers(),
            depth_layers: 0,
        })
    }

    /// The same with the octahedral impostors' depth channel (issue 32), a layer per billboard
    /// layer, which `octahedral_depth = on` needs.
    pub fn with_depth(mut self, depth: &wgpu::Texture) -> Result<Self, GpuError> {
        self.depth = Some(sampled_array_view(depth, "billboard depth array")?);
        self.depth_layers = depth.depth_or_array_layers();
        Ok(self)
    }
}

/// The three render targets of a frame and their readback.
#[derive(Debug)]
pub struct DrawTarget {
    color: wgpu::Texture,
    depth: wgpu::Texture,
    lod_id: wgpu::Texture,
    width: u32,
    height: u32,
}

/// A frame read back: the GPU twin of the reference's `RenderTarget` buffers, row-major from the
/// top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct DrawnImages {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// sRGB-encoded RGB, linear alpha.
    pub color: Vec<[u8; 4]>,
    /// Depth in `[0, 1]`.
    pub depth: Vec<f32>,
    /// LOD ids (`LOD_ID_*`).
    pub lod_id: Vec<u32>,
}

impl DrawTarget {
    /// Targets of `width` x `height` (1..=the adapter's 2D limit).
    pub fn new(ctx: &GpuContext, width: u32, height: u32) -> Result<Self, GpuError> {
        let max = ctx.limits.max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(GpuError::Input {
                field: "draw target size",
                value: format!("{width}x{height} (adapter limit {max})"),
                reason: "expected 1..=limit pixels per side",
            });
        }
        let make = |label, format| {
            ctx.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::COPY_SRC
                    | wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            })
        };
        Ok(Self {
            color: make("draw colour", COLOR_FORMAT),
            depth: make("draw depth", DEPTH_FORMAT),
            lod_id: make("draw lod id", LOD_ID_FORMAT),
            width,
            height,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The colour target (for callers that keep drawing into it).
    pub fn color_texture(&self) -> &wgpu::Texture {
        &self.color
    }

    /// The depth target (`Depth32Float`; the occlusion pyramid's input, issue 31).
    pub fn depth_texture(&self) -> &wgpu::Texture {
        &self.depth
    }

    /// Reads all three buffers back. Blocks. Depth is copied directly where the device can copy
    /// depth textures to buffers, else through a compute pass that loads it texel by texel
    /// (wgpu's GL backend lacks `DEPTH_TEXTURE_AND_BUFFER_COPIES`).
    pub fn read(&self, ctx: &GpuContext) -> Result<DrawnImages, GpuError> {
        let color = read_texture(ctx, &self.color, 0, 0)?;
        let lod_id = read_texture(ctx, &self.lod_id, 0, 0)?;
        let depth_copies = ctx
            .adapter
            .get_downlevel_capabilities()
            .flags
            .contains(wgpu::DownlevelFlags::DEPTH_TEXTURE_AND_BUFFER_COPIES);
        let depth = if depth_copies {
            read_texture(ctx, &self.depth, 0, 0)?.cast()
        } else {
            self.read_depth_by_compute(ctx)?
        };
        Ok(DrawnImages {
            width: self.width,
            height: self.height,
            color: color
                .data
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect(),
            depth,
            lod_id: lod_id.cast(),
        })
    }

    /// The depth buffer through a compute pass (`shaders/depth_copy.wgsl`: `textureLoad` into a
    /// storage buffer), with the context's [`DepthCopyPipelines`]. [`Self::read`] takes it only
    /// where the device cannot copy depth textures; public so that the parity suite checks it
    /// against the direct copy on adapters that have both (lavapipe has the copy: without that
    /// check no test ran this path, issue 36's WGSL sample survivor 268).
    pub fn read_depth_by_compute(&self, ctx: &GpuContext) -> Result<Vec<f32>, GpuError> {
        let pipelines = ctx.pipelines::<DepthCopyPipelines>()?;
        let n = self.width as u64 * self.height as u64;
        let buffer = crate::readback::zeroed_buffer(
            ctx,
            "depth copy",
            n * 4,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        );
        ctx.submit("depth copy by compute", "copy_depth", |encoder| {
            let view = self.depth.create_view(&wgpu::TextureViewDescriptor {
                aspect: wgpu::TextureAspect::DepthOnly,
                ..Default::default()
            });
            let bind_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("copy_depth"),
                layout: &pipelines.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::TextureView(&view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: buffer.as_entire_binding(),
                    },
                ],
            });
            let groups = Dispatch::Groups(self.width.div_ceil(8), self.height.div_ceil(8));
            compute_pass(
                encoder,
                "copy_depth",
                &bind_group,
                &[(&pipelines.pipeline, groups)],
            );
        })?;
        crate::readback::read_buffer(ctx, &buffer, 0, n as usize)
    }
}

/// The compiled `depth_copy.wgsl` pipeline, one per [`GpuContext`] (cached there).
#[derive(Debug)]
pub struct DepthCopyPipelines {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl StagePipelines for DepthCopyPipelines {
    /// Compiles `depth_copy.wgsl`: a depth texture (bound as unfilterable float: GLSL has no
    /// `textureLoad` of depth textures, but loads from a float view) and the output buffer.
    fn create(ctx: &GpuContext) -> Result<Self, GpuError> {
        let (layout, [pipeline]) = compute_stage(
            ctx,
            "depth_copy",
            // Through the mutation hook like every other module (issue 36: it bypassed it, so
            // `mutate`'s depth_copy.wgsl mutants ran the unmutated shader and "survived").
            &crate::shaders::mutant_or("depth_copy.wgsl", DEPTH_COPY_WGSL),
            &[
                Slot::Texture(wgpu::TextureViewDimension::D2),
                Slot::Write(0),
            ],
            ["copy_depth"],
        )?;
        Ok(Self { layout, pipeline })
    }
}

/// How the tree commands are issued (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum IndirectMode {
    /// `multi_draw_indexed_indirect_count`, count from the select counters.
    Count,
    /// `multi_draw_indexed_indirect` over the whole capacity; the vertex stage drops slots past
    /// the count.
    MaxCount,
}

impl IndirectMode {
    /// The wgpu call's name, for reports.
    pub fn name(self) -> &'static str {
        match self {
            IndirectMode::Count => "multi_draw_indexed_indirect_count",
            IndirectMode::MaxCount => "multi_draw_indexed_indirect",
        }
    }
}

/// What [`GpuDraw::encode_probe`] records: the frame, or the frame with part of the tree work
/// removed so that the draw pass's time can be split by difference (vertex against fragment work,
/// the method and its assumptions in `experiments/results/hierarchy_time/README.md`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DrawProbe {
    /// The frame ([`GpuDraw::encode`]).
    Full,
    /// Clear and ground only: the tree draw call is not recorded.
    NoTrees,
    /// The tree draw call under a 1x1 scissor rectangle (the ground is drawn in full first): every
    /// command, instance and vertex is fetched and shaded, and every triangle clipped and set up,
    /// but no tree triangle outside pixel (0, 0) reaches rasterization or the fragment stage.
    NoTreeFragments,
}

/// The CPU-side draw calls one frame recorded: constant whatever the trees and batches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DrawCalls {
    /// Draw calls recorded for the ground (1).
    pub terrain: u32,
    /// Draw calls recorded for every tree command together (1).
    pub trees: u32,
    /// Which indirect call.
    pub mode: IndirectMode,
    /// The `max_count` / `count` argument: the selection buffers' capacity.
    pub max_commands: u32,
}

/// Everything one frame's draw reads.
#[derive(Clone, Copy, Debug)]
pub struct DrawInputs<'a> {
    /// Static scene buffers.
    pub scene: &'a DrawScene,
    /// Mesh and billboard textures.
    pub textures: &'a DrawTextures,
    /// The `select` output (GPU selection, or the reference's via [`SelectBuffers::from_cpu`]),
    /// or the baselines' per-tree culling (`GpuCull::buffers`).
    pub selection: &'a SelectBuffers,
    /// The tree indices the commands' `first_instance` ranges index, in place of the scene's
    /// batch-by-batch indirection ([`DrawSceneDesc::indirection`]): `None` for our pipeline, the
    /// compacted list of `GpuCull::indirection` for the Vegetation baseline (E§5).
    pub indirection: Option<&'a wgpu::Buffer>,
}

/// The depth state of every pass into a [`DrawTarget`]: test LESS, write.
pub(crate) fn depth_stencil_state() -> wgpu::DepthStencilState {
    wgpu::DepthStencilState {
        format: DEPTH_FORMAT,
        depth_write_enabled: Some(true),
        depth_compare: Some(wgpu::CompareFunction::Less),
        stencil: Default::default(),
        bias: Default::default(),
    }
}

/// Triangle lists, no culling (the reference rasterizer culls nothing).
pub(crate) fn primitive_state() -> wgpu::PrimitiveState {
    wgpu::PrimitiveState {
        topology: wgpu::PrimitiveTopology::TriangleList,
        front_face: wgpu::FrontFace::Ccw,
        cull_mode: None,
        ..Default::default()
    }
}

/// The colour targets of a [`DrawTarget`] pass: colour with `blend`, the LOD id unblended.
pub(crate) fn target_states(
    blend: Option<wgpu::BlendState>,
) -> [Option<wgpu::ColorTargetState>; 2] {
    [
        Some(wgpu::ColorTargetState {
            format: COLOR_FORMAT,
            blend,
            write_mask: wgpu::ColorWrites::ALL,
        }),
        Some(wgpu::ColorTargetState {
            format: LOD_ID_FORMAT,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        }),
    ]
}

/// The ground pipeline: `draw.wgsl`'s `terrain_vertex` / `terrain_fragment` (opaque). `module` is
/// the compiled `draw.wgsl`; `layout`'s group 0 must hold at least binding 0, the [`DrawUniform`]
/// (the only resource the terrain entry points use), so other passes into a [`DrawTarget`] (the
/// Primitive baseline) draw the very same ground.
pub(crate) fn terrain_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layout: &wgpu::PipelineLayout,
) -> wgpu::RenderPipeline {
    let terrain_attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3];
    target_pipeline(
        device,
        "draw terrain",
        layout,
        module,
        ("terrain_vertex", "terrain_fragment"),
        &[Some(wgpu::VertexBufferLayout {
            array_stride: size_of::<TerrainVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &terrain_attributes,
        })],
        None,
    )
}

/// A render pipeline into the three [`DrawTarget`] attachments with the shared states
/// ([`primitive_state`], [`depth_stencil_state`], [`target_states`] with `blend` on colour):
/// what the ground, the trees and the Primitive quads differ in is only their entry points,
/// vertex buffers and colour blend.
pub(crate) fn target_pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    (vertex, fragment): (&str, &str),
    buffers: &[Option<wgpu::VertexBufferLayout>],
    blend: Option<wgpu::BlendState>,
) -> wgpu::RenderPipeline {
    let targets = target_states(blend);
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(vertex),
            compilation_options: Default::default(),
            buffers,
        },
        primitive: primitive_state(),
        depth_stencil: Some(depth_stencil_state()),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(fragment),
            compilation_options: Default::default(),
            targets: &targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// Begins the one render pass of a frame into `target`, cleared to the reference's values: sky
/// [`SKY_SRGB`] (in linear light), depth 1, LOD id [`LOD_ID_BACKGROUND`].
pub(crate) fn begin_target_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    target: &DrawTarget,
    label: &str,
) -> wgpu::RenderPass<'e> {
    let view = |t: &wgpu::Texture| t.create_view(&Default::default());
    let (color, depth, lod_id) = (
        view(&target.color),
        view(&target.depth),
        view(&target.lod_id),
    );
    let sky = SKY_SRGB.map(|c| forestlod_shared::srgb_to_linear(c) as f64);
    let sky = wgpu::Color {
        r: sky[0],
        g: sky[1],
        b: sky[2],
        a: 1.0,
    };
    let background = wgpu::Color {
        r: LOD_ID_BACKGROUND as f64,
        g: 0.0,
        b: 0.0,
        a: 0.0,
    };
    cleared_render_pass(
        encoder,
        label,
        &[(&color, sky), (&lod_id, background)],
        &depth,
        wgpu::StoreOp::Store,
    )
}

/// Begins a render pass labelled `label` that loads and stores every attachment: colour targets
/// `colors` and depth `depth` keep what an earlier pass of the frame drew (the late pass of
/// occlusion culling, [`GpuDraw::encode_late`]).
pub(crate) fn loaded_render_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    colors: &[&wgpu::TextureView],
    depth: &wgpu::TextureView,
) -> wgpu::RenderPass<'e> {
    let load = wgpu::Operations {
        load: wgpu::LoadOp::Load,
        store: wgpu::StoreOp::Store,
    };
    let color_attachments: Vec<_> = colors
        .iter()
        .map(|&view| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: load,
            })
        })
        .collect();
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &color_attachments,
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: depth,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Load,
                store: wgpu::StoreOp::Store,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

/// The compiled `draw.wgsl` pipelines, one set per [`GpuContext`] (cached there).
#[derive(Debug)]
pub struct DrawPipelines {
    layout: wgpu::BindGroupLayout,
    trees: wgpu::RenderPipeline,
    terrain: wgpu::RenderPipeline,
    sampler: wgpu::Sampler,
}

/// The draw stage of one device: the context's [`DrawPipelines`] and how it issues the tree
/// commands. Holds no per-frame state (`&self`, `Sync`).
#[derive(Debug)]
pub struct GpuDraw {
    pipelines: Arc<DrawPipelines>,
    mode: IndirectMode,
}

impl GpuDraw {
    /// Takes the context's compiled `draw.wgsl` pipelines (compiling them on first use,
    /// [`GpuContext::pipelines`]). Fails with [`GpuError::Input`] when the device lacks
    /// `INDIRECT_FIRST_INSTANCE` (the draw stage cannot find a batch's trees without it).
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let mode = if ctx
            .features
            .contains(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT)
        {
            IndirectMode::Count
        } else {
            IndirectMode::MaxCount
        };
        Self::with_indirect_mode(ctx, mode)
    }

    /// As [`GpuDraw::new`] with a chosen [`IndirectMode`] (tests force
    /// [`IndirectMode::MaxCount`] on adapters that have the count variant). `Count` without
    /// `MULTI_DRAW_INDIRECT_COUNT` is a [`GpuError::Input`].
    pub fn with_indirect_mode(ctx: &GpuContext, mode: IndirectMode) -> Result<Self, GpuError> {
        if mode == IndirectMode::Count
            && !ctx
                .features
                .contains(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT)
        {
            return Err(GpuError::Input {
                field: "adapter features",
                value: format!("{} lacks MULTI_DRAW_INDIRECT_COUNT", ctx.info.name),
                reason: "IndirectMode::Count needs it; use IndirectMode::MaxCount",
            });
        }
        if !ctx.has_indirect_first_instance() {
            return Err(GpuError::Input {
                field: "adapter features",
                value: format!("{} lacks INDIRECT_FIRST_INSTANCE", ctx.info.name),
                reason: "the draw stage needs first_instance in indirect draws (it is each batch's offset into the indirection array, E§4.4)",
            });
        }
        Ok(Self {
            pipelines: ctx.pipelines::<DrawPipelines>()?,
            mode,
        })
    }

    /// How this device issues the tree commands.
    pub fn indirect_mode(&self) -> IndirectMode {
        self.mode
    }
}

impl StagePipelines for DrawPipelines {
    /// Compiles `draw.wgsl`: the tree and ground pipelines and the trilinear sampler.
    fn create(ctx: &GpuContext) -> Result<Self, GpuError> {
        ctx.checked("draw.wgsl pipelines", || {
            let device = &ctx.device;
            let module = shader_module(device, "draw.wgsl", &SOURCE.module());
            use wgpu::ShaderStages as S;
            let storage = wgpu::BufferBindingType::Storage { read_only: true };
            let texture = |binding| {
                texture_entry(
                    binding,
                    S::FRAGMENT,
                    true,
                    wgpu::TextureViewDimension::D2Array,
                )
            };
            let (layout, pipeline_layout) = group_layout(
                device,
                "draw",
                &[
                    buffer_entry(
                        0,
                        S::VERTEX_FRAGMENT,
                        wgpu::BufferBindingType::Uniform,
                        size_of::<DrawUniform>() as u64,
                    ),
                    buffer_entry(1, S::VERTEX, storage, 0),
                    buffer_entry(2, S::VERTEX, storage, 0),
                    buffer_entry(3, S::VERTEX, storage, 0),
                    buffer_entry(4, S::VERTEX, storage, 0),
                    buffer_entry(5, S::VERTEX_FRAGMENT, storage, 0),
                    buffer_entry(
                        6,
                        S::VERTEX,
                        storage,
                        size_of::<forestlod_shared::SelectCounters>() as u64,
                    ),
                    texture(7),
                    texture(8),
                    sampler_entry(9, S::FRAGMENT),
                    // The fragment reads the impostor atlas (issue 33 item 2).
                    buffer_entry(10, S::VERTEX_FRAGMENT, storage, 0),
                    texture(11),
                ],
            );
            // Straight-alpha source-over (reference raster `Blend::AlphaBlend`).
            let source_over = wgpu::BlendState {
                color: wgpu::BlendComponent {
                    src_factor: wgpu::BlendFactor::SrcAlpha,
                    dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
                    operation: wgpu::BlendOperation::Add,
                },
                alpha: wgpu::BlendComponent {
                    src_factor: wgpu::BlendFactor::One,
                    dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
                    operation: wgpu::BlendOperation::Add,
                },
            };
            let trees = target_pipeline(
                device,
                "draw trees",
                &pipeline_layout,
                &module,
                ("tree_vertex", "tree_fragment"),
                &[],
                Some(source_over),
            );
            let terrain = terrain_pipeline(device, &module, &pipeline_layout);
            // Reference `Sampler::TRILINEAR`: clamp-to-edge, no bias, default LOD clamps.
            let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("draw trilinear"),
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                mipmap_filter: wgpu::MipmapFilterMode::Linear,
                ..Default::default()
            });
            Self {
                layout,
                trees,
                terrain,
                sampler,
            }
        })
    }
}

impl GpuDraw {
    /// Records one frame's pass into `encoder` ([`GpuDraw::encode_probe`] with
    /// [`DrawProbe::Full`]). The frame's uniform is a fresh buffer bound into
    /// this call's bind group ([`frame_uniform`]), so frames recorded from several threads with
    /// one `GpuDraw` never see each other's camera. `camera` and `params` should be validated, as for the reference.
    /// Errors: textures with fewer layers than the meshes (and `K` angles) need, or selection
    /// buffers larger than `base_vertex` can address.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &DrawInputs,
        camera: &Camera,
        params: &Params,
        target: &DrawTarget,
    ) -> Result<DrawCalls, GpuError> {
        self.encode_probe(
            ctx,
            encoder,
            inputs,
            camera,
            params,
            target,
            DrawProbe::Full,
        )
    }

    /// [`GpuDraw::encode`] with a [`DrawProbe`]: the whole frame, or the frame with part of the
    /// tree work removed, for timing the draw pass's parts (`experiments/src/bin/draw_split.rs`).
    /// Only [`DrawProbe::Full`] draws the frame the reference twins; the others are measuring
    /// instruments whose images are not compared.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_probe(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &DrawInputs,
        camera: &Camera,
        params: &Params,
        target: &DrawTarget,
        probe: DrawProbe,
    ) -> Result<DrawCalls, GpuError> {
        let bind_group = self.tree_bind_group(ctx, inputs, camera, params)?;
        let commands = self.point_commands(ctx, encoder, inputs, params)?;
        let DrawInputs {
            scene, selection, ..
        } = *inputs;
        let mut pass = begin_target_pass(encoder, target, "draw");
        pass.set_bind_group(0, &bind_group, &[]);
        pass.set_pipeline(&self.pipelines.terrain);
        pass.set_vertex_buffer(0, scene.terrain.slice(..));
        pass.draw(0..scene.terrain_vertex_count, 0..1);
        match probe {
            DrawProbe::Full => {}
            DrawProbe::NoTrees => {
                return Ok(DrawCalls {
                    terrain: 1,
                    trees: 0,
                    mode: self.mode,
                    max_commands: selection.capacity,
                });
            }
            DrawProbe::NoTreeFragments => pass.set_scissor_rect(0, 0, 1, 1),
        }
        self.draw_trees(&mut pass, inputs, commands.as_ref());
        Ok(DrawCalls {
            terrain: 1,
            trees: 1,
            mode: self.mode,
            max_commands: selection.capacity,
        })
    }

    /// The tree draw's bind group of one frame (a fresh uniform of `camera` and `params`), after
    /// checking the textures' layers and the selection's capacity (the errors of
    /// [`GpuDraw::encode`]).
    fn tree_bind_group(
        &self,
        ctx: &GpuContext,
        inputs: &DrawInputs,
        camera: &Camera,
        params: &Params,
    ) -> Result<wgpu::BindGroup, GpuError> {
        let DrawInputs {
            scene,
            textures,
            selection,
            indirection,
        } = *inputs;
        // The point LOD (issue 33): the scene must carry its records, and an expanded command's
        // `(first_instance + trees) × n` must fit a u32 instance index (point_commands.wgsl).
        if forestlod_shared::points::draws_points(params) {
            let Some((_, most)) = scene.point_bases else {
                return Err(GpuError::Input {
                    field: "lod1",
                    value: forestlod_shared::points::Lod1::Points.name().to_string(),
                    reason: "the scene was uploaded without point records (DrawSceneDesc::points)",
                });
            };
            let trees = indirection.unwrap_or(&scene.indirection).size() / 4;
            if trees * u64::from(most) > u64::from(u32::MAX) {
                return Err(GpuError::Input {
                    field: "point_count",
                    value: format!(
                        "{} (a mesh has {most} records, {trees} indirection entries)",
                        params.point_count
                    ),
                    reason: "expected trees x records per mesh to fit a u32 instance index",
                });
            }
        }
        let views = forestlod_shared::BillboardViews::of(params);
        if textures.mesh_layers < scene.mesh_count
            || u64::from(textures.billboard_layers) < views.layers(scene.mesh_count as usize)
        {
            return Err(GpuError::Input {
                field: "draw textures",
                value: format!(
                    "{} mesh layers, {} billboard layers for {} meshes x {} angles x {} azimuths",
                    textures.mesh_layers,
                    textures.billboard_layers,
                    scene.mesh_count,
                    params.angle_count,
                    params.azimuth_count
                ),
                reason: "expected a layer per mesh and K·J layers per mesh in the billboard array",
            });
        }
        if forestlod_shared::depth_channel(params)
            && textures.depth_layers < textures.billboard_layers
        {
            return Err(GpuError::Input {
                field: "draw textures",
                value: format!(
                    "{} depth layers for {} billboard layers",
                    textures.depth_layers, textures.billboard_layers
                ),
                reason: "octahedral_depth = on needs the depth channel's array (DrawTextures::with_depth), a layer per billboard layer",
            });
        }
        if selection.capacity > MAX_COMMANDS {
            return Err(GpuError::Input {
                field: "selection capacity",
                value: selection.capacity.to_string(),
                reason: "expected at most MAX_COMMANDS (base_vertex is an i32)",
            });
        }
        let uniform = scene.draw_uniform(ctx, "draw uniform", camera, params);
        let bind_group = bind_group(
            &ctx.device,
            "draw",
            &self.pipelines.layout,
            [
                uniform.as_entire_binding(),
                scene.vertices.as_entire_binding(),
                scene.instances.as_entire_binding(),
                indirection
                    .unwrap_or(&scene.indirection)
                    .as_entire_binding(),
                scene.meshes.as_entire_binding(),
                selection.data.as_entire_binding(),
                selection.counters.as_entire_binding(),
                wgpu::BindingResource::TextureView(&textures.mesh),
                wgpu::BindingResource::TextureView(&textures.billboards),
                wgpu::BindingResource::Sampler(&self.pipelines.sampler),
                scene.far.as_entire_binding(),
                wgpu::BindingResource::TextureView(
                    textures.depth.as_ref().unwrap_or(&textures.billboards),
                ),
            ],
        );
        Ok(bind_group)
    }

    /// Under `lod1 = points` (issue 33), records the point commands' expansion into `encoder`: a
    /// copy of the selection's commands (a fresh buffer of this call: no per-frame state behind
    /// `&self`) in which `point_commands.wgsl` turns every LOD1 command into `trees × n`
    /// instances of the quad (module docs of `forestlod_shared::points`); the draw reads the
    /// copy, the selection's own commands stay as `select` wrote them. `None` otherwise.
    fn point_commands(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &DrawInputs,
        params: &Params,
    ) -> Result<Option<wgpu::Buffer>, GpuError> {
        if !forestlod_shared::points::draws_points(params) {
            return Ok(None);
        }
        let DrawInputs {
            scene, selection, ..
        } = *inputs;
        let Some((point_base, _)) = scene.point_bases else {
            return Ok(None);
        };
        let pipelines = ctx.pipelines::<PointCommandPipelines>()?;
        let bytes =
            u64::from(selection.capacity) * size_of::<forestlod_shared::DrawCommand>() as u64;
        let commands = crate::readback::zeroed_buffer(
            ctx,
            "draw point commands",
            bytes.max(size_of::<forestlod_shared::DrawCommand>() as u64),
            wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::INDIRECT
                | wgpu::BufferUsages::COPY_DST,
        );
        if bytes == 0 {
            return Ok(Some(commands));
        }
        encoder.copy_buffer_to_buffer(&selection.commands, 0, &commands, 0, bytes);
        let uniform = frame_uniform(
            ctx,
            "point commands uniform",
            &PointCommandUniform {
                point_base,
                quad_first_index: scene.iota_first_index,
                capacity: selection.capacity,
                mesh_count: scene.mesh_count,
            },
        );
        let bind_group = bind_group(
            &ctx.device,
            "point commands",
            &pipelines.layout,
            [
                uniform.as_entire_binding(),
                selection.data.as_entire_binding(),
                selection.counters.as_entire_binding(),
                scene.far.as_entire_binding(),
                commands.as_entire_binding(),
            ],
        );
        let groups = selection.capacity.div_ceil(POINT_COMMANDS_WORKGROUP);
        compute_pass(
            encoder,
            "point commands",
            &bind_group,
            &[(&pipelines.expand, Dispatch::Groups(groups, 1))],
        );
        Ok(Some(commands))
    }

    /// Records the one multi-draw of `inputs`' tree commands into `pass` (its bind group set),
    /// from `commands` when given (the point expansion, [`GpuDraw::point_commands`]).
    fn draw_trees(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        inputs: &DrawInputs,
        commands: Option<&wgpu::Buffer>,
    ) {
        let DrawInputs {
            scene, selection, ..
        } = *inputs;
        let commands = commands.unwrap_or(&selection.commands);
        pass.set_pipeline(&self.pipelines.trees);
        pass.set_index_buffer(scene.indices.slice(..), wgpu::IndexFormat::Uint32);
        match self.mode {
            IndirectMode::Count => pass.multi_draw_indexed_indirect_count(
                commands,
                0,
                &selection.counters,
                SelectBuffers::COUNT_OFFSET,
                selection.capacity,
            ),
            IndirectMode::MaxCount => {
                pass.multi_draw_indexed_indirect(commands, 0, selection.capacity)
            }
        }
    }

    /// Records the late pass of a frame with occlusion culling (issue 31,
    /// `forestlod_shared::occlusion`, step 4): `inputs`' tree commands drawn into `target` as
    /// [`GpuDraw::encode`] draws them, but **loading** what the target holds (the early pass:
    /// sky, ground and occluders) instead of clearing it, and without the ground. The errors of
    /// [`GpuDraw::encode`].
    pub fn encode_late(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &DrawInputs,
        camera: &Camera,
        params: &Params,
        target: &DrawTarget,
    ) -> Result<DrawCalls, GpuError> {
        let bind_group = self.tree_bind_group(ctx, inputs, camera, params)?;
        let commands = self.point_commands(ctx, encoder, inputs, params)?;
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let (color, depth, lod_id) = (
            view(&target.color),
            view(&target.depth),
            view(&target.lod_id),
        );
        let mut pass = loaded_render_pass(encoder, "draw late", &[&color, &lod_id], &depth);
        pass.set_bind_group(0, &bind_group, &[]);
        self.draw_trees(&mut pass, inputs, commands.as_ref());
        Ok(DrawCalls {
            terrain: 0,
            trees: 1,
            mode: self.mode,
            max_commands: inputs.selection.capacity,
        })
    }

    /// Records and submits one frame (does not wait; read the target to wait).
    pub fn render(
        &self,
        ctx: &GpuContext,
        inputs: &DrawInputs,
        camera: &Camera,
        params: &Params,
        target: &DrawTarget,
    ) -> Result<DrawCalls, GpuError> {
        ctx.checked("draw pass", || {
            let mut encoder = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("draw"),
                });
            let calls = self.encode(ctx, &mut encoder, inputs, camera, params, target)?;
            ctx.queue.submit([encoder.finish()]);
            Ok(calls)
        })?
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::wgsl_layout::{RustLayout, assert_layout, rust_layout, validate, validate_with};

    /// `depth_copy.wgsl` parses and validates (naga), standalone as the driver compiles it.
    #[test]
    fn depth_copy_wgsl_validates() {
        validate(DEPTH_COPY_WGSL);
    }

    /// `DrawInstance`'s layout, which its twins in `draw.wgsl` and `primitive.wgsl` must both
    /// have.
    pub(crate) fn draw_instance_layout() -> RustLayout {
        rust_layout!(DrawInstance {
            position,
            yaw,
            scale,
            mesh
        })
    }

    /// `DrawUniform`, `DrawVertex` and `DrawInstance` have their WGSL twins' layout (naga
    /// reflection of the full `draw.wgsl` module, which also validates it; naga's layouter
    /// agrees on the sizes).
    #[test]
    fn wgsl_layouts_match_rust() {
        let module = validate_with(&SOURCE.module(), naga::valid::Capabilities::all());
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).expect("layout");
        let layouts = [
            rust_layout!(DrawUniform {
                view_proj,
                view,
                angle_count,
                fade_mode,
                angle_index_mode,
                alpha_cutoff,
                billboard_first_vertex,
                pixel_origin_x,
                pixel_origin_y,
                shading,
                dither_space,
                fade_granularity,
                noise_size,
                ambient,
                sun,
                octahedral_depth,
                azimuth_count,
                azimuth_mode,
                billboard_views,
                octahedral_grid,
                octahedral_blend,
                far_kind,
                far_nodes_base,
                far_hull_base,
                cam_right,
                points,
                cam_up,
                point_mode,
                point_k,
                point_base,
                far_texel_base,
                impostor_side,
                _pad_impostor0,
                _pad_impostor1,
                _pad_impostor2
            }),
            rust_layout!(DrawVertex { position, uv }),
            draw_instance_layout(),
        ];
        for rust in &layouts {
            assert_layout(&module, rust);
            let handle = module
                .types
                .iter()
                .find_map(|(h, t)| (t.name.as_deref() == Some(rust.name)).then_some(h))
                .expect("struct in draw.wgsl");
            assert_eq!(
                layouter[handle].size as usize, rust.size,
                "{} size",
                rust.name
            );
        }
    }

    /// `PointCommandUniform` has its WGSL twin's layout (`point_commands.wgsl`, issue 33).
    #[test]
    fn point_command_uniform_matches_wgsl() {
        let module = validate_with(&POINT_SOURCE.module(), naga::valid::Capabilities::all());
        assert_layout(
            &module,
            &rust_layout!(PointCommandUniform {
                point_base,
                quad_first_index,
                capacity,
                mesh_count
            }),
        );
    }

    /// `point_words`: a three-word header per mesh (records' first word, count, cut order's
    /// first word, relative to the header), then each mesh's records and cut order.
    #[test]
    fn point_words_lay_out_headers_records_and_cut_orders() {
        use forestlod_shared::points::PointRecord;
        let r = |a: f32| PointRecord {
            area: a,
            ..bytemuck::Zeroable::zeroed()
        };
        let (a, b) = ([r(1.0), r(2.0)], [r(3.0)]);
        let w = point_words(&[(&a, &[1, 0]), (&b, &[0])]);
        assert_eq!(&w[..6], &[6, 2, 30, 32, 1, 44]);
        assert_eq!(f32::from_bits(w[6 + 3]), 1.0);
        assert_eq!(f32::from_bits(w[6 + 12 + 3]), 2.0);
        assert_eq!(&w[30..32], &[1, 0]);
        assert_eq!(f32::from_bits(w[32 + 3]), 3.0);
        assert_eq!(w[44], 0);
        assert_eq!(w.len(), 45);
    }

    #[test]
    fn terrain_grid_is_two_triangles_per_cell_over_the_margin() {
        let v = terrain_vertices([0.0, 0.0, 100.0, 100.0], |_, _| 1.0);
        assert_eq!(v.len(), (TERRAIN_CELLS * TERRAIN_CELLS * 6) as usize);
        assert_eq!(v[0].position, [-TERRAIN_MARGIN, -TERRAIN_MARGIN, 0.95]);
        let last = v.last().unwrap().position;
        assert_eq!(last[1], 100.0 + TERRAIN_MARGIN);
    }
}
