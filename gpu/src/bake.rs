//! # bake: billboard layers rendered on the GPU (E Alg. 3.1, E§4.1; SPEC §5.1)
//!
//! The driver of `shaders/bake.wgsl`, twin of `reference/src/bake.rs` (`bake_clip` ↔ WGSL
//! `bake_clip`, `bake_layer` ↔ one render pass of [`GpuBake::bake_level0`], `bake` ↔
//! [`GpuBake::bake`]).
//!
//! ## Contract
//! - Layer `mesh * K + k` of an `r x r` billboard array texture
//!   ([`crate::mips::create_billboard_texture`]) holds mesh `mesh` seen at elevation
//!   `bake_elevation(k, K)` from the azimuth `+X`, through the orthographic projection fitted to
//!   its bounding box ([`forestlod_shared::billboard_extent`]): exactly the reference's
//!   `bake_clip`, ported to WGSL operation for operation. `sin`/`cos` of the elevation and the
//!   extent are computed here on the CPU with the reference's own calls ([`BakeLayer::new`]),
//!   since WGSL's transcendental functions have implementation-defined precision.
//! - With `J` azimuth views (issue 30, E§7; [`BillboardViews`]), layer `mesh·K·J + k·J + j`
//!   ([`forestlod_shared::view_layer`]) holds the elevation `k` seen from the mesh-local azimuth
//!   `bake_azimuth(j, J)` (the reference's `bake_clip_view`; its sine and cosine computed on the
//!   CPU like the elevation's). `J = 1` renders today's layers, the same passes in the same order.
//! - One render pass per layer into a single-layer view of level 0: colour cleared to
//!   transparent black, `Rgba8UnormSrgb`, blend REPLACE; a `Depth32Float` attachment cleared to 1,
//!   depth test LESS with writes; no culling. The fragment samples the mesh texture's level 0
//!   bilinearly (`textureSampleLevel(.., 0.0)`, clamp-to-edge; the texture is `Rgba8UnormSrgb`,
//!   so texels are decoded to linear before filtering) and discards alpha 0. These are the
//!   reference rasterizer's rules (`reference/src/raster.rs`): Vulkan coverage with 8 subpixel
//!   bits and the top-left rule, depth tested before a kept fragment writes.
//! - Mesh vertices, uvs and indices are uploaded once, into shared buffers; each mesh's texture
//!   is its own single-level texture.
//! - Then the mips stage ([`crate::mips`]) builds every layer's chain ([`GpuBake::bake`]).
//!
//! ## CPU-input hooks
//! [`GpuBaked::from_cpu_level0`] takes the reference's level-0 layers and runs the GPU mips on
//! them (to test mips alone); [`GpuBaked::from_cpu_chains`] takes the reference's full chains
//! (so the draw stage can run on CPU textures).
//!
//! ## Where the twins may differ (SPEC §8; measured by `tests/tests/parity/bake.rs`)
//! - Coverage: a pixel centre within the 8-bit subpixel ambiguity of an edge.
//! - Interpolation: the reference interpolates varyings and depth from the *snapped* vertices
//!   (`reference/src/raster.rs`, step 6); lavapipe evidently interpolates from the unsnapped
//!   ones (its texels match a model that does). The uv then differ by up to `|∇uv| / 512`
//!   texels: negligible at r >= 64, up to 15 bytes at r = 2, and enough to keep (reference) or
//!   discard (GPU) a fragment on the border of a transparent region.
//! - Filtering: GPUs quantize the bilinear weights (lavapipe to 8 bits), the reference does not.
//! - Depth: where two triangles meet at nearly equal depth (crossed cards on the trunk axis),
//!   either may win the LESS test.
//!
//! Everywhere else the layers agree within ±1 per channel (the sRGB encodes round apart).

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use forestlod_shared::{
    BillboardExtent, BillboardViews, MeshMeta, MipMode, Params, bake_azimuth, bake_elevation,
    billboard_extent,
};
use wgpu::util::DeviceExt;

use crate::context::{
    StagePipelines, bind_group, cleared_render_pass, dynamic_uniform_entry, dynamic_uniform_slot,
    group_layout, sampler_entry, shader_module, texture_entry,
};
use crate::mips::{BILLBOARD_FORMAT, GpuMips, MipArray, create_billboard_texture};
use crate::shaders::{StageSource, WgslFile};
use crate::{GpuContext, GpuError};

/// The `bake` stage's module: `bake.wgsl` (it reads only shared constants).
pub const SOURCE: StageSource = StageSource {
    own: WgslFile {
        name: "bake.wgsl",
        wgsl: include_str!("shaders/bake.wgsl"),
        constants: &[],
    },
    parts: &[],
};

/// Format of the bake's depth attachment.
pub const BAKE_DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Format of the meshes' textures as the bake samples them (sRGB colour, linear alpha).
pub const MESH_TEXTURE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// One mesh as the bake needs it: geometry, its texture's level 0, and its metadata (the
/// reference's `TreeMesh` and `TreeMesh::meta()`).
#[derive(Clone, Copy, Debug)]
pub struct BakeMesh<'m> {
    /// Vertex positions, mesh-local.
    pub positions: &'m [[f32; 3]],
    /// Texture coordinates, one per vertex, `(0, 0)` at the texture's top-left.
    pub uvs: &'m [[f32; 2]],
    /// Triangle list of indices into `positions`.
    pub indices: &'m [u32],
    /// Texture width in texels.
    pub texture_width: u32,
    /// Texture height in texels.
    pub texture_height: u32,
    /// `texture_width * texture_height` texels, row-major from the top-left: sRGB colour bytes,
    /// straight linear alpha.
    pub texture: &'m [[u8; 4]],
    /// Bounding box, sphere and billboard half-width.
    pub meta: MeshMeta,
}

/// The per-layer uniform of `bake.wgsl`. Keep in sync with `struct BakeLayer` there.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct BakeLayer {
    /// `MeshMeta::bbox_min`.
    pub bbox_min: [f32; 3],
    /// `MeshMeta::sphere_radius`.
    pub sphere_radius: f32,
    /// `MeshMeta::bbox_max`.
    pub bbox_max: [f32; 3],
    /// `sin` of the elevation.
    pub sin_e: f32,
    /// `cos` of the elevation.
    pub cos_e: f32,
    /// Extent half-width.
    pub half_width: f32,
    /// Extent bottom.
    pub bottom: f32,
    /// Extent height.
    pub height: f32,
    /// `sin` of the view's azimuth ([`bake_azimuth`]; 0 for the `+X` view).
    pub sin_a: f32,
    /// `cos` of the view's azimuth (1 for the `+X` view).
    pub cos_a: f32,
    /// Explicit padding.
    pub _pad0: f32,
    /// Explicit padding.
    pub _pad1: f32,
    /// An octahedral frame's right vector (issue 32, `forestlod_shared::frame_basis`).
    pub frame_right: [f32; 3],
    /// 1 when the layer is an octahedral frame (issue 32): `bake.wgsl` then projects on the
    /// frame's basis about the bounding-box centre (reference `octahedral_clip`).
    pub octahedral: u32,
    /// An octahedral frame's up vector.
    pub frame_up: [f32; 3],
    /// Explicit padding.
    pub _pad2: f32,
    /// An octahedral frame's direction toward the viewer.
    pub frame_dir: [f32; 3],
    /// Explicit padding.
    pub _pad3: f32,
}
const _: () = assert!(size_of::<BakeLayer>() == 112);

impl BakeLayer {
    /// The constants of layer `k` of `angle_count` for a mesh from the azimuth `+X`.
    pub fn new(meta: &MeshMeta, k: u32, angle_count: u32) -> Self {
        Self::view(meta, BillboardViews::elevations(angle_count), k, 0)
    }

    /// The constants of view `(k, j)` of `views` for a mesh, computed as reference
    /// `bake_clip_view` computes them: `elevation.sin_cos()` and `azimuth.sin_cos()` in `f32` and
    /// `billboard_extent`.
    pub fn view(meta: &MeshMeta, views: BillboardViews, k: u32, j: u32) -> Self {
        if views.octahedral() {
            // Frame `k` (issue 32): its direction and basis computed here as the reference
            // computes them (`frame_direction`, `frame_basis`: sqrt and divisions, correctly
            // rounded on both sides).
            let d = forestlod_shared::frame_direction(
                k,
                views.grid,
                forestlod_shared::octahedral::is_hemi(views.sphere),
            );
            let (r, u) = forestlod_shared::frame_basis(d);
            return Self {
                bbox_min: meta.bbox_min,
                sphere_radius: meta.sphere_radius,
                bbox_max: meta.bbox_max,
                frame_right: r,
                octahedral: 1,
                frame_up: u,
                frame_dir: d,
                ..Self::zeroed()
            };
        }
        let elevation = bake_elevation(k, views.angle_count);
        let e = billboard_extent(meta, elevation);
        let (sin_e, cos_e) = elevation.sin_cos();
        let (sin_a, cos_a) = bake_azimuth(j, views.azimuth_count).sin_cos();
        Self {
            bbox_min: meta.bbox_min,
            sphere_radius: meta.sphere_radius,
            bbox_max: meta.bbox_max,
            sin_e,
            cos_e,
            half_width: e.half_width,
            bottom: e.bottom,
            height: e.height,
            sin_a,
            cos_a,
            ..Self::zeroed()
        }
    }
}

/// The extent of every layer, `mesh·K·J + k·J + j` (the draw stage expands billboards with them;
/// every azimuth of an elevation has the elevation's extent).
pub fn layer_extents(metas: &[MeshMeta], views: BillboardViews) -> Vec<BillboardExtent> {
    views
        .views(metas.len())
        .map(|(m, k, _)| views.extent(&metas[m], k))
        .collect()
}

/// The bake's output: the billboard array texture with mips (the twin of the reference's
/// `BakedBillboards`).
#[derive(Debug)]
pub struct GpuBaked {
    /// Angles per mesh, `K`.
    pub angle_count: u32,
    /// Azimuths per angle, `J` (issue 30).
    pub azimuth_count: u32,
    /// Layer side, `r`.
    pub texture_size: u32,
    /// The array texture with every layer's chain.
    pub mips: MipArray,
    /// Extent of every layer.
    pub extents: Vec<BillboardExtent>,
    /// The octahedral impostors' depth channel (issue 32), when
    /// [`forestlod_shared::depth_channel`] asks for it: the same layers' depth, with mips.
    pub depth: Option<MipArray>,
}

impl GpuBaked {
    /// The CPU-input hook for the mips stage: the reference's level-0 layers (`layers[mesh·K·J +
    /// k·J + j]`, `side²` texels each) uploaded, then the GPU mips on them.
    pub fn from_cpu_level0(
        mips: &GpuMips<'_>,
        metas: &[MeshMeta],
        views: BillboardViews,
        side: u32,
        layers: &[&[[u8; 4]]],
        mode: MipMode,
        alpha_ref: f32,
    ) -> Result<Self, GpuError> {
        Self::with_mips(metas, views, side, layers.len(), || {
            mips.run_from_cpu(side, layers, mode, alpha_ref)
        })
    }

    /// The CPU-input hook for the draw stage: the reference's full chains
    /// (`chains[layer][level]`, layers in [`forestlod_shared::view_layer`] order) uploaded as they
    /// are.
    #[allow(
        clippy::too_many_arguments,
        reason = "mirrors from_cpu_level0 plus the chain's provenance"
    )]
    pub fn from_cpu_chains(
        ctx: &GpuContext,
        metas: &[MeshMeta],
        views: BillboardViews,
        side: u32,
        chains: &[Vec<&[[u8; 4]]>],
        mode: MipMode,
        alpha_ref: f32,
    ) -> Result<Self, GpuError> {
        Self::with_mips(metas, views, side, chains.len(), || {
            MipArray::from_cpu_chains(ctx, side, chains, mode, alpha_ref)
        })
    }

    /// The baked billboards of `metas` with `views` and side `side`, whose `layers` layers
    /// `mips` makes once their count is checked (`metas.len() · K · J`).
    fn with_mips(
        metas: &[MeshMeta],
        views: BillboardViews,
        side: u32,
        layers: usize,
        mips: impl FnOnce() -> Result<MipArray, GpuError>,
    ) -> Result<Self, GpuError> {
        check_layer_count(metas.len(), views, layers)?;
        Ok(Self {
            angle_count: views.angle_count,
            azimuth_count: views.azimuth_count,
            texture_size: side,
            mips: mips()?,
            extents: layer_extents(metas, views),
            depth: None,
        })
    }
}

fn check_layer_count(meshes: usize, views: BillboardViews, layers: usize) -> Result<(), GpuError> {
    if views.per_mesh() >= 1 && views.layers(meshes) == layers as u64 {
        Ok(())
    } else {
        Err(GpuError::Input {
            field: "billboard layers",
            value: format!(
                "{layers} layers for {meshes} meshes x {} angles x {} azimuths",
                views.angle_count, views.azimuth_count
            ),
            reason: "expected meshes * angle_count * azimuth_count layers, both counts >= 1",
        })
    }
}

/// Checks one mesh's arrays against each other.
fn validate_mesh(i: usize, m: &BakeMesh<'_>, max_dim: u32) -> Result<(), GpuError> {
    let bad = |field: &'static str, value: String, reason: &'static str| {
        Err(GpuError::Input {
            field,
            value: format!("mesh {i}: {value}"),
            reason,
        })
    };
    if m.uvs.len() != m.positions.len() {
        return bad(
            "mesh uvs",
            format!("{} uvs, {} positions", m.uvs.len(), m.positions.len()),
            "expected one uv per vertex",
        );
    }
    if !m.indices.len().is_multiple_of(3) {
        return bad(
            "mesh indices",
            format!("{} indices", m.indices.len()),
            "expected a triangle list (a multiple of 3)",
        );
    }
    if let Some(&v) = m.indices.iter().find(|&&v| v as usize >= m.positions.len()) {
        return bad(
            "mesh indices",
            format!("index {v} of {} vertices", m.positions.len()),
            "expected indices below the vertex count",
        );
    }
    let (w, h) = (m.texture_width, m.texture_height);
    if w == 0 || h == 0 || w > max_dim || h > max_dim || m.texture.len() != (w * h) as usize {
        return bad(
            "mesh texture",
            format!("{w}x{h} with {} texels", m.texture.len()),
            "expected a non-empty texture within the device's size limit holding width * height texels",
        );
    }
    Ok(())
}

/// The compiled bake pipeline.
#[derive(Debug)]
struct BakePipelines {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    /// The depth channel's (issue 32): the same render through `bake_depth_fs`.
    depth_pipeline: wgpu::RenderPipeline,
    sampler: wgpu::Sampler,
}

impl StagePipelines for BakePipelines {
    fn create(ctx: &GpuContext) -> Result<Self, GpuError> {
        ctx.checked("bake.wgsl pipeline", || {
            let device = &ctx.device;
            let module = shader_module(device, "bake.wgsl", &SOURCE.module());
            let layer_size = size_of::<BakeLayer>() as u64;
            let fragment = wgpu::ShaderStages::FRAGMENT;
            let (layout, pipeline_layout) = group_layout(
                device,
                "bake",
                &[
                    dynamic_uniform_entry(0, wgpu::ShaderStages::VERTEX, layer_size),
                    texture_entry(1, fragment, true, wgpu::TextureViewDimension::D2),
                    sampler_entry(2, fragment),
                ],
            );
            let make = |label: &str, fragment_entry: &str| {
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(label),
                    layout: Some(&pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some("bake_vs"),
                        compilation_options: Default::default(),
                        buffers: &[
                            Some(wgpu::VertexBufferLayout {
                                array_stride: 12,
                                step_mode: wgpu::VertexStepMode::Vertex,
                                attributes: &wgpu::vertex_attr_array![0 => Float32x3],
                            }),
                            Some(wgpu::VertexBufferLayout {
                                array_stride: 8,
                                step_mode: wgpu::VertexStepMode::Vertex,
                                attributes: &wgpu::vertex_attr_array![1 => Float32x2],
                            }),
                        ],
                    },
                    primitive: wgpu::PrimitiveState {
                        topology: wgpu::PrimitiveTopology::TriangleList,
                        strip_index_format: None,
                        front_face: wgpu::FrontFace::Ccw,
                        cull_mode: None,
                        unclipped_depth: false,
                        polygon_mode: wgpu::PolygonMode::Fill,
                        conservative: false,
                    },
                    depth_stencil: Some(wgpu::DepthStencilState {
                        format: BAKE_DEPTH_FORMAT,
                        depth_write_enabled: Some(true),
                        depth_compare: Some(wgpu::CompareFunction::Less),
                        stencil: wgpu::StencilState::default(),
                        bias: wgpu::DepthBiasState::default(),
                    }),
                    multisample: wgpu::MultisampleState::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &module,
                        entry_point: Some(fragment_entry),
                        compilation_options: Default::default(),
                        targets: &[Some(wgpu::ColorTargetState {
                            format: BILLBOARD_FORMAT,
                            blend: Some(wgpu::BlendState::REPLACE),
                            write_mask: wgpu::ColorWrites::ALL,
                        })],
                    }),
                    multiview_mask: None,
                    cache: None,
                })
            };
            let pipeline = make("bake", "bake_fs");
            let depth_pipeline = make("bake depth", "bake_depth_fs");
            let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("bake mesh texture"),
                address_mode_u: wgpu::AddressMode::ClampToEdge,
                address_mode_v: wgpu::AddressMode::ClampToEdge,
                address_mode_w: wgpu::AddressMode::ClampToEdge,
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                mipmap_filter: wgpu::MipmapFilterMode::Nearest,
                ..Default::default()
            });
            Self {
                layout,
                pipeline,
                depth_pipeline,
                sampler,
            }
        })
    }
}

/// The bake stage (and the mips stage it ends with), pipelines compiled once.
#[derive(Debug)]
pub struct GpuBake<'a> {
    mips: GpuMips<'a>,
    pipelines: Arc<BakePipelines>,
}

impl<'a> GpuBake<'a> {
    /// Compiles `bake.wgsl` and `mips.wgsl`.
    pub fn new(ctx: &'a GpuContext) -> Result<Self, GpuError> {
        Ok(Self {
            mips: GpuMips::new(ctx)?,
            pipelines: ctx.pipelines::<BakePipelines>()?,
        })
    }

    /// The mips stage it runs after baking.
    pub fn mips(&self) -> &GpuMips<'a> {
        &self.mips
    }

    /// E Alg. 3.1 (and E§7's azimuths): renders level 0 of every layer
    /// `mesh·K·J + k·J + j` of `views` at `side x side` (a power of two); the other levels are
    /// left for [`GpuMips::run`]. Submits the work.
    pub fn bake_level0(
        &self,
        meshes: &[BakeMesh<'_>],
        views: BillboardViews,
        side: u32,
    ) -> Result<wgpu::Texture, GpuError> {
        self.bake_layers(meshes, views, side, false)
    }

    /// The octahedral impostors' depth channel at level 0 (issue 32; reference
    /// `bake_depth_view`): every layer of [`Self::bake_level0`] rendered through
    /// `bake_depth_fs`, red = the kept fragment's depth, alpha = its texel's.
    pub fn bake_depth_level0(
        &self,
        meshes: &[BakeMesh<'_>],
        views: BillboardViews,
        side: u32,
    ) -> Result<wgpu::Texture, GpuError> {
        self.bake_layers(meshes, views, side, true)
    }

    fn bake_layers(
        &self,
        meshes: &[BakeMesh<'_>],
        views: BillboardViews,
        side: u32,
        depth_channel: bool,
    ) -> Result<wgpu::Texture, GpuError> {
        let ctx = self.mips.context();
        let (angle_count, azimuth_count) = (views.angle_count, views.azimuth_count);
        if meshes.is_empty() || angle_count == 0 || azimuth_count == 0 {
            return Err(GpuError::Input {
                field: "bake",
                value: format!(
                    "{} meshes x {angle_count} angles x {azimuth_count} azimuths",
                    meshes.len()
                ),
                reason: "expected at least one mesh, one angle and one azimuth",
            });
        }
        let max_dim = ctx.limits.max_texture_dimension_2d;
        for (i, m) in meshes.iter().enumerate() {
            validate_mesh(i, m, max_dim)?;
        }
        let layer_count = u32::try_from(views.layers(meshes.len())).unwrap_or(u32::MAX);
        let label = if depth_channel {
            "billboard depth (gpu bake)"
        } else {
            "billboards (gpu bake)"
        };
        let texture = create_billboard_texture(ctx, side, layer_count, label)?;

        // Shared geometry buffers; each mesh draws with its own base vertex and index range.
        let (mut positions, mut uvs, mut indices) = (Vec::new(), Vec::new(), Vec::new());
        let mut ranges = Vec::with_capacity(meshes.len());
        for m in meshes {
            let first_index = indices.len() as u32;
            let base_vertex = positions.len() as i32;
            positions.extend_from_slice(m.positions);
            uvs.extend_from_slice(m.uvs);
            indices.extend_from_slice(m.indices);
            ranges.push((first_index..indices.len() as u32, base_vertex));
        }
        // Per-layer uniforms at the dynamic-offset stride.
        let align = u64::from(ctx.limits.min_uniform_buffer_offset_alignment.max(1));
        let stride = (size_of::<BakeLayer>() as u64).next_multiple_of(align);
        let mut layer_bytes = vec![0u8; (stride * u64::from(layer_count)) as usize];
        for (mesh, k, j) in views.views(meshes.len()) {
            let index = views.layer(mesh as u32, k, j);
            let at = (stride * u64::from(index)) as usize;
            let layer = BakeLayer::view(&meshes[mesh].meta, views, k, j);
            layer_bytes[at..at + size_of::<BakeLayer>()]
                .copy_from_slice(bytemuck::bytes_of(&layer));
        }

        ctx.checked("bake", || {
            let device = &ctx.device;
            use wgpu::BufferUsages as U;
            let init = |label: &str, contents: &[u8], usage: U| {
                // Empty slices still need a valid (non-zero) buffer.
                let mut padded = contents.to_vec();
                padded.resize(contents.len().max(16).next_multiple_of(4), 0);
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: &padded,
                    usage,
                })
            };
            let position_buffer = init(
                "bake positions",
                bytemuck::cast_slice(&positions),
                U::VERTEX,
            );
            let uv_buffer = init("bake uvs", bytemuck::cast_slice(&uvs), U::VERTEX);
            let index_buffer = init("bake indices", bytemuck::cast_slice(&indices), U::INDEX);
            let uniforms = init("bake layers", &layer_bytes, U::UNIFORM);
            let bind_groups: Vec<wgpu::BindGroup> = meshes
                .iter()
                .map(|m| {
                    let size = wgpu::Extent3d {
                        width: m.texture_width,
                        height: m.texture_height,
                        depth_or_array_layers: 1,
                    };
                    let tex = device.create_texture_with_data(
                        &ctx.queue,
                        &wgpu::TextureDescriptor {
                            label: Some("bake mesh texture"),
                            size,
                            mip_level_count: 1,
                            sample_count: 1,
                            dimension: wgpu::TextureDimension::D2,
                            format: MESH_TEXTURE_FORMAT,
                            usage: wgpu::TextureUsages::TEXTURE_BINDING
                                | wgpu::TextureUsages::COPY_DST,
                            view_formats: &[],
                        },
                        wgpu::util::TextureDataOrder::LayerMajor,
                        bytemuck::cast_slice(m.texture),
                    );
                    let view = tex.create_view(&wgpu::TextureViewDescriptor::default());
                    bind_group(
                        device,
                        "bake mesh",
                        &self.pipelines.layout,
                        [
                            dynamic_uniform_slot::<BakeLayer>(&uniforms),
                            wgpu::BindingResource::TextureView(&view),
                            wgpu::BindingResource::Sampler(&self.pipelines.sampler),
                        ],
                    )
                })
                .collect();
            let depth = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("bake depth"),
                size: wgpu::Extent3d {
                    width: side,
                    height: side,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: BAKE_DEPTH_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                view_formats: &[],
            });
            let depth_view = depth.create_view(&wgpu::TextureViewDescriptor::default());
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("bake"),
            });
            for (mesh, (range, base_vertex)) in ranges.iter().enumerate() {
                for layer in mesh as u32 * views.per_mesh()..(mesh as u32 + 1) * views.per_mesh() {
                    let view = texture.create_view(&wgpu::TextureViewDescriptor {
                        label: Some("bake layer"),
                        dimension: Some(wgpu::TextureViewDimension::D2),
                        base_mip_level: 0,
                        mip_level_count: Some(1),
                        base_array_layer: layer,
                        array_layer_count: Some(1),
                        ..Default::default()
                    });
                    let mut pass = cleared_render_pass(
                        &mut encoder,
                        "bake layer",
                        &[(&view, wgpu::Color::TRANSPARENT)],
                        &depth_view,
                        wgpu::StoreOp::Discard,
                    );
                    if range.is_empty() {
                        continue;
                    }
                    pass.set_pipeline(if depth_channel {
                        &self.pipelines.depth_pipeline
                    } else {
                        &self.pipelines.pipeline
                    });
                    pass.set_bind_group(
                        0,
                        &bind_groups[mesh],
                        &[(stride * u64::from(layer)) as u32],
                    );
                    pass.set_vertex_buffer(0, position_buffer.slice(..));
                    pass.set_vertex_buffer(1, uv_buffer.slice(..));
                    pass.set_index_buffer(index_buffer.slice(..), wgpu::IndexFormat::Uint32);
                    pass.draw_indexed(range.clone(), *base_vertex, 0..1);
                }
            }
            ctx.queue.submit([encoder.finish()]);
        })?;
        Ok(texture)
    }

    /// E Alg. 3.1 then E Alg. 3.2: every layer baked at `params.texture_size` from
    /// `params.angle_count` angles and `params.azimuth_count` azimuths, then mipmapped in
    /// `params.mips()` mode with `params.alpha_cutoff` as the alpha-test reference.
    pub fn bake(&self, meshes: &[BakeMesh<'_>], params: &Params) -> Result<GpuBaked, GpuError> {
        let mode = params.mips().map_err(|e| GpuError::Input {
            field: "params.mip_mode",
            value: e.to_string(),
            reason: "expected a MipMode id",
        })?;
        let (views, r) = (BillboardViews::of(params), params.texture_size);
        let texture = self.bake_level0(meshes, views, r)?;
        let metas: Vec<MeshMeta> = meshes.iter().map(|m| m.meta).collect();
        let depth = if forestlod_shared::depth_channel(params) {
            let level0 = self.bake_depth_level0(meshes, views, r)?;
            Some(self.mips.run(level0, mode, params.alpha_cutoff)?)
        } else {
            None
        };
        Ok(GpuBaked {
            angle_count: views.angle_count,
            azimuth_count: views.azimuth_count,
            texture_size: r,
            mips: self.mips.run(texture, mode, params.alpha_cutoff)?,
            extents: layer_extents(&metas, views),
            depth,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wgsl_layout::{assert_layout, rust_layout, validate};

    #[test]
    fn wgsl_bake_layer_matches_its_rust_twin() {
        let module = validate(&SOURCE.module());
        assert_layout(
            &module,
            &rust_layout!(BakeLayer {
                bbox_min,
                sphere_radius,
                bbox_max,
                sin_e,
                cos_e,
                half_width,
                bottom,
                height,
                sin_a,
                cos_a,
                _pad0,
                _pad1,
                frame_right,
                octahedral,
                frame_up,
                _pad2,
                frame_dir,
                _pad3
            }),
        );
    }
}
