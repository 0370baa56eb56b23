//! # far_bake: the far level's bake on the GPU (issue 32 item 2; G§2.2-2.4)
//!
//! The driver of `shaders/far_bake.wgsl`, twin of `reference/src/far_bake.rs`. The contract is
//! `forestlod_shared::far_bake`'s module docs (cell grid, views, reduction, dropping, parent
//! rules); this driver does its GPU part and hands the rest to the same shared code:
//!
//! - **Leaves on the GPU** ([`GpuFarBake::leaf_cells`]): per leaf, side and slice, one render
//!   pass (`far_bake_vs`/`far_bake_fs`, the constants of [`FarView::with_cutoff`] at a dynamic
//!   offset) into a layer of a `(cs · FAR_BAKE_PIXELS)²` `Rgba8UnormSrgb` array, then one compute
//!   dispatch (`far_bake_reduce`) sums each layer's pixel blocks; the sums come back and are
//!   packed and placed on the CPU ([`block_colour`], [`FarView::block_cell`]), as the reference
//!   packs its own sums. Passes run in batches of at most [`FAR_BAKE_LAYERS`] layers.
//! - **The leaves' geometry** is given world-space ([`FarBakeVertex`], placed with
//!   `forestlod_shared::far_bake::tree_point`, as the reference places its trees); every pass
//!   draws all of its leaf's triangles (the reference skips trees whose sphere misses the slice,
//!   which clipping would remove anyway).
//! - **Parents on the CPU** ([`GpuFarBake::far_bake`]): dropping, `average` and `composite` run
//!   from the GPU's leaf cells through `forestlod_shared::far_bake::assemble_far_level` (not
//!   ported to WGSL: a short sequential pass over kept cells, with an `O(m³)` arrangement that
//!   would need a loop bound that grows with the input).
//!
//! ## Where the twins may differ (`tests/tests/parity/far_bake.rs` measures it)
//! The bake renders of `gpu/src/bake.rs`: coverage within the 8-bit subpixel ambiguity of an
//! edge, varyings interpolated from unsnapped vertices, quantized bilinear weights, `f32`
//! contraction of the clip formula. A pixel whose coverage flips moves a block's alpha by
//! `1/64` (4 in 8 bits) and its mean colour by up to `1/n` of the pixel's difference.

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use forestlod_shared::far_bake::{
    FarBakeVertex, FarView, assemble_far_level, block_colour, cell_count,
};
use forestlod_shared::{FAR_BAKE_PIXELS, FarLevel, NodeMeta, Params, SIDE_COUNT};
use wgpu::util::DeviceExt;

use crate::context::{
    StagePipelines, bind_group, buffer_entry, cleared_render_pass, dynamic_uniform_entry,
    dynamic_uniform_slot, group_layout, sampler_entry, shader_module, texture_entry,
};
use crate::readback::{read_buffer, zeroed_buffer};
use crate::shaders::{StageSource, WgslFile, wgsl_constants};
use crate::{GpuContext, GpuError};

/// Invocations per workgroup of `far_bake_reduce`.
pub const FAR_REDUCE_WORKGROUP: u32 = 64;

/// Most slice images rendered before one reduction (the array's layers; WebGPU's minimum
/// `max_texture_array_layers` is 256).
pub const FAR_BAKE_LAYERS: u32 = 256;

/// The `far_bake` stage's module: `far_bake.wgsl`.
pub const SOURCE: StageSource = StageSource {
    own: WgslFile {
        name: "far_bake.wgsl",
        wgsl: include_str!("shaders/far_bake.wgsl"),
        constants: wgsl_constants![FAR_REDUCE_WORKGROUP, FAR_BAKE_PIXELS],
    },
    parts: &[],
};

/// Format of the slice images (sRGB colour, as the reference's render target).
pub const FAR_SLICE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// The reduction's uniform. Keep in sync with `struct FarReduce` in `far_bake.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct FarReduce {
    /// Blocks per image side, `cs`.
    pub cs: u32,
    /// Layers of the dispatch.
    pub layers: u32,
    /// Padding.
    pub _pad0: u32,
    /// Padding.
    pub _pad1: u32,
}
const _: () = assert!(size_of::<FarReduce>() == 16);

/// One leaf as the bake needs it: its box and its trees' world-space triangle list.
#[derive(Clone, Copy, Debug)]
pub struct FarLeaf<'a> {
    /// `NodeMeta::box_center`.
    pub center: [f32; 3],
    /// `NodeMeta::extent`.
    pub extent: [f32; 3],
    /// Three corners per triangle.
    pub vertices: &'a [FarBakeVertex],
}

/// The compiled pipelines.
#[derive(Debug)]
struct FarBakePipelines {
    render_layout: wgpu::BindGroupLayout,
    render: wgpu::RenderPipeline,
    reduce_layout: wgpu::BindGroupLayout,
    reduce: wgpu::ComputePipeline,
    sampler: wgpu::Sampler,
}

impl StagePipelines for FarBakePipelines {
    fn create(ctx: &GpuContext) -> Result<Self, GpuError> {
        ctx.checked("far_bake.wgsl pipelines", || {
            let device = &ctx.device;
            let module = shader_module(device, "far_bake.wgsl", &SOURCE.module());
            let both = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
            let fragment = wgpu::ShaderStages::FRAGMENT;
            let (render_layout, render_pipeline_layout) = group_layout(
                device,
                "far_bake render",
                &[
                    dynamic_uniform_entry(0, both, size_of::<FarView>() as u64),
                    texture_entry(1, fragment, true, wgpu::TextureViewDimension::D2Array),
                    sampler_entry(2, fragment),
                ],
            );
            let render = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("far_bake"),
                layout: Some(&render_pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("far_bake_vs"),
                    compilation_options: Default::default(),
                    buffers: &[Some(wgpu::VertexBufferLayout {
                        array_stride: size_of::<FarBakeVertex>() as u64,
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: &wgpu::vertex_attr_array![
                            0 => Float32x3, 1 => Uint32, 2 => Float32x2
                        ],
                    })],
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
                    format: wgpu::TextureFormat::Depth32Float,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(wgpu::CompareFunction::Less),
                    stencil: wgpu::StencilState::default(),
                    bias: wgpu::DepthBiasState::default(),
                }),
                multisample: wgpu::MultisampleState::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some("far_bake_fs"),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: FAR_SLICE_FORMAT,
                        blend: Some(wgpu::BlendState::REPLACE),
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            });
            let compute = wgpu::ShaderStages::COMPUTE;
            let (reduce_layout, reduce_pipeline_layout) = group_layout(
                device,
                "far_bake reduce",
                &[
                    buffer_entry(
                        3,
                        compute,
                        wgpu::BufferBindingType::Uniform,
                        size_of::<FarReduce>() as u64,
                    ),
                    texture_entry(4, compute, false, wgpu::TextureViewDimension::D2Array),
                    buffer_entry(
                        5,
                        compute,
                        wgpu::BufferBindingType::Storage { read_only: false },
                        0,
                    ),
                ],
            );
            let reduce = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("far_bake_reduce"),
                layout: Some(&reduce_pipeline_layout),
                module: &module,
                entry_point: Some("far_bake_reduce"),
                compilation_options: Default::default(),
                cache: None,
            });
            // Reference `Sampler::TRILINEAR` (the draw's): clamp-to-edge, no bias.
            let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("far_bake trilinear"),
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                mipmap_filter: wgpu::MipmapFilterMode::Linear,
                ..Default::default()
            });
            Self {
                render_layout,
                render,
                reduce_layout,
                reduce,
                sampler,
            }
        })
    }
}

/// The far bake on the GPU (module docs), pipelines compiled once.
#[derive(Debug)]
pub struct GpuFarBake<'a> {
    ctx: &'a GpuContext,
    pipelines: Arc<FarBakePipelines>,
}

impl<'a> GpuFarBake<'a> {
    /// Compiles `far_bake.wgsl`.
    pub fn new(ctx: &'a GpuContext) -> Result<Self, GpuError> {
        Ok(Self {
            ctx,
            pipelines: ctx.pipelines::<FarBakePipelines>()?,
        })
    }

    /// Every leaf's `cs³` cells' side colours (cell-number order), rendered and reduced on the
    /// GPU (module docs). `mesh_textures` is the draw's mesh texture array (one layer per mesh,
    /// full mip chains, a filterable float format).
    pub fn leaf_cells(
        &self,
        mesh_textures: &wgpu::Texture,
        leaves: &[FarLeaf<'_>],
        cs: u32,
        alpha_cutoff: f32,
    ) -> Result<Vec<Vec<[u32; SIDE_COUNT]>>, GpuError> {
        let ctx = self.ctx;
        if !(1..=forestlod_shared::MAX_CLUSTER_SIZE).contains(&cs) {
            return Err(GpuError::Input {
                field: "cluster_size",
                value: cs.to_string(),
                reason: "expected 1..=12 cells per axis",
            });
        }
        if let Some((i, l)) = leaves
            .iter()
            .enumerate()
            .find(|(_, l)| !l.vertices.len().is_multiple_of(3))
        {
            return Err(GpuError::Input {
                field: "far bake vertices",
                value: format!("leaf {i}: {} vertices", l.vertices.len()),
                reason: "expected a triangle list (a multiple of 3)",
            });
        }
        let mut out = vec![vec![[0u32; SIDE_COUNT]; cell_count(cs)]; leaves.len()];
        // Every pass: (leaf, view).
        let passes: Vec<(usize, FarView)> = leaves
            .iter()
            .enumerate()
            .flat_map(|(i, l)| {
                (0..SIDE_COUNT).flat_map(move |side| {
                    (0..cs).map(move |slice| {
                        (
                            i,
                            FarView::with_cutoff(l.center, l.extent, cs, side, slice, alpha_cutoff),
                        )
                    })
                })
            })
            .collect();
        if passes.is_empty() {
            return Ok(out);
        }
        let batch = FAR_BAKE_LAYERS.min(ctx.limits.max_texture_array_layers) as usize;
        let side = cs * FAR_BAKE_PIXELS;
        let mut vertices: Vec<FarBakeVertex> = Vec::new();
        let mut ranges = Vec::with_capacity(leaves.len());
        for l in leaves {
            let first = vertices.len() as u32;
            vertices.extend_from_slice(l.vertices);
            ranges.push(first..vertices.len() as u32);
        }
        let align = u64::from(ctx.limits.min_uniform_buffer_offset_alignment.max(1));
        let stride = (size_of::<FarView>() as u64).next_multiple_of(align);
        let mut view_bytes = vec![0u8; (stride * passes.len() as u64) as usize];
        for (p, (_, v)) in passes.iter().enumerate() {
            let at = (stride * p as u64) as usize;
            view_bytes[at..at + size_of::<FarView>()].copy_from_slice(bytemuck::bytes_of(v));
        }
        let blocks = (cs * cs) as usize;
        let sums: Vec<[f32; 4]> = ctx.checked("far_bake", || -> Result<_, GpuError> {
            let device = &ctx.device;
            use wgpu::BufferUsages as U;
            let mut padded = bytemuck::cast_slice::<FarBakeVertex, u8>(&vertices).to_vec();
            padded.resize(padded.len().max(size_of::<FarBakeVertex>()), 0);
            let vertex_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("far_bake vertices"),
                contents: &padded,
                usage: U::VERTEX,
            });
            let views = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("far_bake views"),
                contents: &view_bytes,
                usage: U::UNIFORM,
            });
            let mesh_view = mesh_textures.create_view(&wgpu::TextureViewDescriptor {
                label: Some("far_bake mesh textures"),
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            });
            let render_group = bind_group(
                device,
                "far_bake render",
                &self.pipelines.render_layout,
                [
                    dynamic_uniform_slot::<FarView>(&views),
                    wgpu::BindingResource::TextureView(&mesh_view),
                    wgpu::BindingResource::Sampler(&self.pipelines.sampler),
                ],
            );
            let layers = batch.min(passes.len()) as u32;
            let slices = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("far_bake slices"),
                size: wgpu::Extent3d {
                    width: side,
                    height: side,
                    depth_or_array_layers: layers,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: FAR_SLICE_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            });
            let slices_view = slices.create_view(&wgpu::TextureViewDescriptor {
                label: Some("far_bake slices"),
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            });
            let depth = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("far_bake depth"),
                size: wgpu::Extent3d {
                    width: side,
                    height: side,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Depth32Float,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                view_formats: &[],
            });
            let depth_view = depth.create_view(&wgpu::TextureViewDescriptor::default());
            let out_len = (layers as usize * blocks * 16) as u64;
            let out_buffer = zeroed_buffer(ctx, "far_bake sums", out_len, U::STORAGE | U::COPY_SRC);
            let reduce_uniform = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("far_bake reduce"),
                size: size_of::<FarReduce>() as u64,
                usage: U::UNIFORM | U::COPY_DST,
                mapped_at_creation: false,
            });
            // Bindings 3-5 (the render's are 0-2 in the same module): explicit numbers.
            let reduce_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("far_bake reduce"),
                layout: &self.pipelines.reduce_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: reduce_uniform.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: wgpu::BindingResource::TextureView(&slices_view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 5,
                        resource: out_buffer.as_entire_binding(),
                    },
                ],
            });
            let mut sums = Vec::with_capacity(passes.len() * blocks);
            for (chunk_index, chunk) in passes.chunks(batch).enumerate() {
                let first = chunk_index * batch;
                let uniform = FarReduce {
                    cs,
                    layers: chunk.len() as u32,
                    ..FarReduce::default()
                };
                ctx.queue
                    .write_buffer(&reduce_uniform, 0, bytemuck::bytes_of(&uniform));
                let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("far_bake"),
                });
                for (k, (leaf, _)) in chunk.iter().enumerate() {
                    let layer_view = slices.create_view(&wgpu::TextureViewDescriptor {
                        label: Some("far_bake slice"),
                        dimension: Some(wgpu::TextureViewDimension::D2),
                        base_array_layer: k as u32,
                        array_layer_count: Some(1),
                        ..Default::default()
                    });
                    let mut pass = cleared_render_pass(
                        &mut encoder,
                        "far_bake slice",
                        &[(&layer_view, wgpu::Color::TRANSPARENT)],
                        &depth_view,
                        wgpu::StoreOp::Discard,
                    );
                    let range = ranges[*leaf].clone();
                    if range.is_empty() {
                        continue;
                    }
                    pass.set_pipeline(&self.pipelines.render);
                    pass.set_bind_group(0, &render_group, &[(stride * (first + k) as u64) as u32]);
                    pass.set_vertex_buffer(0, vertex_buffer.slice(..));
                    pass.draw(range, 0..1);
                }
                {
                    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("far_bake reduce"),
                        timestamp_writes: None,
                    });
                    pass.set_pipeline(&self.pipelines.reduce);
                    pass.set_bind_group(0, &reduce_group, &[]);
                    let invocations = (chunk.len() * blocks) as u32;
                    pass.dispatch_workgroups(invocations.div_ceil(FAR_REDUCE_WORKGROUP), 1, 1);
                }
                ctx.queue.submit([encoder.finish()]);
                sums.extend(read_buffer::<[f32; 4]>(
                    ctx,
                    &out_buffer,
                    0,
                    chunk.len() * blocks,
                )?);
            }
            Ok(sums)
        })??;
        for (p, (leaf, view)) in passes.iter().enumerate() {
            for b in 0..blocks as u32 {
                let s = sums[p * blocks + b as usize];
                let cell = view.block_cell(b % cs, b / cs);
                out[*leaf][cell][view.side as usize] = block_colour([s[0], s[1], s[2]], s[3]);
            }
        }
        Ok(out)
    }

    /// The far level of a hierarchy's `nodes` (module docs): `leaves[i]` is the world-space
    /// triangle list of leaf `i` (`child_count == 0`; ignored for interior nodes). Leaves on the
    /// GPU ([`GpuFarBake::leaf_cells`]), the rest by `forestlod_shared::far_bake`. Refuses
    /// invalid `params` naming the field.
    pub fn far_bake(
        &self,
        nodes: &[NodeMeta],
        leaves: &[&[FarBakeVertex]],
        mesh_textures: &wgpu::Texture,
        params: &Params,
    ) -> Result<FarLevel, GpuError> {
        let invalid = |e: forestlod_shared::ParamError| GpuError::Input {
            field: e.field,
            value: e.value,
            reason: "expected a valid parameter (forestlod_shared::registry)",
        };
        params.validate().map_err(invalid)?;
        let rule = params.far_parent_rule().map_err(invalid)?;
        if leaves.len() != nodes.len() {
            return Err(GpuError::Input {
                field: "far bake leaves",
                value: format!("{} triangle lists for {} nodes", leaves.len(), nodes.len()),
                reason: "expected one (possibly empty) list per node",
            });
        }
        let leaf_nodes: Vec<usize> = (0..nodes.len())
            .filter(|&i| nodes[i].child_count == 0)
            .collect();
        let inputs: Vec<FarLeaf<'_>> = leaf_nodes
            .iter()
            .map(|&i| FarLeaf {
                center: nodes[i].box_center,
                extent: nodes[i].extent,
                vertices: leaves[i],
            })
            .collect();
        let cells = self.leaf_cells(
            mesh_textures,
            &inputs,
            params.cluster_size,
            params.alpha_cutoff,
        )?;
        let mut raw: Vec<Option<Vec<[u32; SIDE_COUNT]>>> = vec![None; nodes.len()];
        for (i, c) in leaf_nodes.into_iter().zip(cells) {
            raw[i] = Some(c);
        }
        Ok(assemble_far_level(nodes, params.cluster_size, rule, raw))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wgsl_layout::{assert_layout, rust_layout, validate};

    #[test]
    fn wgsl_far_structs_match_their_rust_twins() {
        let module = validate(&SOURCE.module());
        assert_layout(
            &module,
            &rust_layout!(FarView {
                right,
                up,
                axis,
                cs,
                center,
                inv_extent,
                near,
                far,
                depth_scale,
                side,
                slice,
                alpha_cutoff,
                _pad
            }),
        );
        assert_layout(
            &module,
            &rust_layout!(FarReduce {
                cs,
                layers,
                _pad0,
                _pad1
            }),
        );
    }
}
