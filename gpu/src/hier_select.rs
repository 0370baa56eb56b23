//! The hierarchical cut on the GPU (issue 13; G§3 Fig. 4, C§4.5): the driver of
//! `shaders/hier_select.wgsl`, twin of `reference/src/hier_select.rs`.
//!
//! ## Contract
//! Exactly the reference's cut: per node `node_code` (`forestlod_shared::cut`), visited when every
//! ancestor recursed, emitted when visited, drawn and not recursing; emitted nodes' commands in
//! node order, LOD0 before LOD1, `base_vertex = slot << COMMAND_SHIFT`. Four dispatches per frame
//! (decide, resolve, scan, write) whatever the hierarchy's size or depth, no CPU recursion; the
//! ancestor walk is bounded by `MAX_HIERARCHY_DEPTH` (llvmpipe stops loops after 65,535
//! iterations). The output is the raw cut, a [`SelectBuffers`] of one command per emitted node
//! and LOD: the frame's next stages read it (`crate::coalesce` binds it as its input, and
//! `crate::command_order` reads its data and [`GpuHierSelect::nodes`]); this driver runs no
//! other stage (the frame records them, `harness/src/gpu_frame/selection.rs`, in the order
//! `forestlod_shared::FramePlan` gives). Equal to the reference's raw cut
//! (`reference/src/hier_select.rs`) bit for bit up to decisions within ε of a threshold (fused
//! multiply-add on the GPU), which the parity tests classify and count.

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use forestlod_shared::{
    Camera, FarNode, FarUniform, MeshMeta, NodeMeta, Params, SelectCounters, ViewUniform,
};

use crate::context::{
    Dispatch, READ, Slot, WRITE, buffer_bind_group, compute_pass, compute_pipelines,
};
use crate::readback::{read_buffer, stage_uniform, upload_storage, zeroed_buffer};
use crate::select::{
    GpuSelection, SelectBuffers, check_command_capacity, check_mesh_indices, check_scale_count,
};
use crate::{GpuContext, GpuError};

/// Invocations per workgroup of the per-node passes (generated into `hier_select.wgsl`'s module).
pub const HIER_WORKGROUP_SIZE: u32 = 64;

/// The `hier_select` stage's module: `hier_select.wgsl`, then [`crate::select::SCAN`].
pub const SOURCE: crate::shaders::StageSource = crate::shaders::StageSource {
    own: crate::shaders::WgslFile {
        name: "hier_select.wgsl",
        wgsl: include_str!("shaders/hier_select.wgsl"),
        constants: crate::shaders::wgsl_constants![HIER_WORKGROUP_SIZE],
    },
    parts: &[crate::select::SCAN],
};

/// The per-frame uniform of `hier_select.wgsl`. Keep in sync with `struct HierUniform` there.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct HierUniform {
    /// The shared view constants ([`ViewUniform::new`]).
    pub view: ViewUniform,
    /// Number of nodes.
    pub node_count: u32,
    /// [`forestlod_shared::Hierarchy`] id: the per-node rule.
    pub mode: u32,
    /// `Params::max_cull_depth`.
    pub max_cull_depth: u32,
    /// First index of the billboard quad.
    pub billboard_first_index: u32,
    /// Index count of the billboard quad.
    pub billboard_index_count: u32,
    /// [`forestlod_shared::FarUniform::kind`] (issue 32): 0 without a far level.
    pub far_kind: u32,
    /// [`forestlod_shared::FarUniform::start`].
    pub far_start: f32,
    /// [`forestlod_shared::FarUniform::ratio`].
    pub far_ratio: f32,
    /// First index of the packed geometry's far iota range.
    pub far_first_index: u32,
    /// Explicit padding.
    pub _pad0: u32,
    /// Explicit padding.
    pub _pad1: u32,
    /// Explicit padding.
    pub _pad2: u32,
}
const _: () = assert!(size_of::<HierUniform>() == 208);

compute_pipelines! {
    /// The compiled pipelines of `hier_select.wgsl`, one set per [`GpuContext`] (cached there).
    pub struct HierSelectPipelines = "hier_select", SOURCE.module(), [
        Slot::Uniform(size_of::<HierUniform>() as u64),
        READ, READ, WRITE, WRITE, WRITE, WRITE, WRITE,
        Slot::Write(size_of::<SelectCounters>() as u64),
        READ, READ,
    ],
    {
        decide: "hier_decide",
        resolve: "hier_resolve",
        scan: "hier_scan",
        write: "hier_write",
    }
}

/// One scene's hierarchy on the GPU, ready to cut for any camera and parameters.
pub struct GpuHierSelect<'a> {
    ctx: &'a GpuContext,
    pipelines: Arc<HierSelectPipelines>,
    uniform: wgpu::Buffer,
    codes: wgpu::Buffer,
    states: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    /// The hierarchy's nodes (read again by `crate::command_order`).
    nodes: wgpu::Buffer,
    /// The cut's commands, one per emitted node and LOD: the stage's output.
    raw: SelectBuffers,
    node_count: u32,
    mode: u32,
    billboard: MeshMeta,
    /// The far iota range's first index, when a far level was uploaded.
    far_first_index: Option<u32>,
    /// The far level's node records (one zeroed record without a far level).
    far_nodes: wgpu::Buffer,
}

/// A hierarchy's far level as the cut reads it (issue 32): its per-node records and the packed
/// geometry's far iota range's first index.
#[derive(Clone, Copy, Debug)]
pub struct FarNodes<'f> {
    /// One record per hierarchy node.
    pub nodes: &'f [FarNode],
    /// `PackedGeometry::far`'s first index.
    pub first_index: u32,
}

impl<'a> GpuHierSelect<'a> {
    /// Uploads the nodes (of a hierarchy built for `mode`, a `forestlod_shared::Hierarchy` id)
    /// and meshes, and allocates two commands per node. Fails on a node whose mesh index is out of
    /// range, on more commands than `base_vertex` can address, or on a far level whose records
    /// do not match the nodes one for one.
    pub fn new(
        ctx: &'a GpuContext,
        nodes: &[NodeMeta],
        scales: &[[f32; 2]],
        mode: u32,
        meshes: &[MeshMeta],
        billboard: &MeshMeta,
        far: Option<FarNodes<'_>>,
    ) -> Result<Self, GpuError> {
        if let Some(f) = far
            && f.nodes.len() != nodes.len()
        {
            return Err(GpuError::Input {
                field: "far level node records",
                value: format!("{} for {} hierarchy nodes", f.nodes.len(), nodes.len()),
                reason: "expected one FarNode per hierarchy node",
            });
        }
        check_scale_count("node scales", nodes.len(), scales.len())?;
        check_mesh_indices(
            "node.mesh",
            "node",
            nodes.iter().map(|n| n.mesh),
            meshes.len(),
        )?;
        let capacity = check_command_capacity(
            "nodes",
            nodes.len(),
            "two commands per node exceed MAX_COMMANDS (base_vertex is an i32)",
        )?;
        let pipelines = ctx.pipelines::<HierSelectPipelines>()?;
        use wgpu::BufferUsages as U;
        let n = (nodes.len() as u64).max(1);
        let node_buffer = upload_storage(ctx, "hier nodes", nodes, U::empty());
        let mesh_buffer = upload_storage(ctx, "hier meshes", meshes, U::empty());
        let scale_buffer = upload_storage(ctx, "hier scales", scales, U::empty());
        let far_buffer = upload_storage(
            ctx,
            "hier far nodes",
            far.map_or(&[][..], |f| f.nodes),
            U::empty(),
        );
        let uniform = stage_uniform::<HierUniform>(ctx, "hier uniform");
        let codes = zeroed_buffer(ctx, "hier codes", n * 4, U::STORAGE | U::COPY_SRC);
        let states = zeroed_buffer(ctx, "hier states", n * 4, U::STORAGE | U::COPY_SRC);
        let offsets = zeroed_buffer(ctx, "hier offsets", n * 4, U::STORAGE | U::COPY_SRC);
        let raw = SelectBuffers::with_capacity(ctx, capacity as u32);
        let bind_group = ctx.checked("hier bind group", || {
            buffer_bind_group(
                &ctx.device,
                "hier_select",
                &pipelines.layout,
                &[
                    &uniform,
                    &node_buffer,
                    &mesh_buffer,
                    &codes,
                    &states,
                    &offsets,
                    &raw.commands,
                    &raw.data,
                    &raw.counters,
                    &scale_buffer,
                    &far_buffer,
                ],
            )
        })?;
        Ok(Self {
            ctx,
            pipelines: pipelines.clone(),
            uniform,
            codes,
            states,
            bind_group,
            nodes: node_buffer,
            raw,
            node_count: nodes.len() as u32,
            mode,
            billboard: *billboard,
            far_first_index: far.map(|f| f.first_index),
            far_nodes: far_buffer,
        })
    }

    /// Replaces the far level's node records (issue 33 item 2: under `far_lod = impostor` they
    /// are the frame's impostor state, [`forestlod_shared::impostor`]'s per-node far data,
    /// written before each frame). Errors without an uploaded far level or on a record count
    /// other than the node count.
    pub fn write_far_nodes(&self, far_nodes: &[FarNode]) -> Result<(), GpuError> {
        if self.far_first_index.is_none() || far_nodes.len() != self.node_count as usize {
            return Err(GpuError::Input {
                field: "far level node records",
                value: format!(
                    "{} for {} hierarchy nodes (far level uploaded: {})",
                    far_nodes.len(),
                    self.node_count,
                    self.far_first_index.is_some()
                ),
                reason: "expected one FarNode per hierarchy node, on a cut created with a far level",
            });
        }
        self.ctx
            .queue
            .write_buffer(&self.far_nodes, 0, bytemuck::cast_slice(far_nodes));
        Ok(())
    }

    /// The raw cut's buffers, the stage's output (valid after a dispatch).
    pub fn buffers(&self) -> &SelectBuffers {
        &self.raw
    }

    /// The raw cut's buffers, for a later stage of the same frame that rewrites them in place.
    pub fn buffers_mut(&mut self) -> &mut SelectBuffers {
        &mut self.raw
    }

    /// The hierarchy's nodes as uploaded (`crate::command_order` reads their bounds).
    pub fn nodes(&self) -> &wgpu::Buffer {
        &self.nodes
    }

    /// Records one frame's cut into `encoder`: uniform through the queue, counters cleared, four
    /// dispatches. `params` must be valid.
    pub fn encode(&mut self, encoder: &mut wgpu::CommandEncoder, camera: &Camera, params: &Params) {
        // No far level uploaded: the cut has none, whatever `params` say.
        let far = match self.far_first_index {
            Some(_) => FarUniform::new(camera, params),
            None => FarUniform::default(),
        };
        let uniform = HierUniform {
            view: ViewUniform::new(camera, params),
            node_count: self.node_count,
            mode: self.mode,
            max_cull_depth: params.max_cull_depth,
            billboard_first_index: self.billboard.first_index,
            billboard_index_count: self.billboard.index_count,
            far_kind: far.kind,
            far_start: far.start,
            far_ratio: far.ratio,
            far_first_index: self.far_first_index.unwrap_or(0),
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
        };
        self.ctx
            .queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uniform));
        encoder.clear_buffer(&self.raw.counters, 0, None);
        let (x, y) = self
            .ctx
            .workgroup_grid(self.node_count.div_ceil(HIER_WORKGROUP_SIZE));
        let p = &self.pipelines;
        compute_pass(
            encoder,
            "hier_select",
            &self.bind_group,
            &[
                (&p.decide, Dispatch::Groups(x, y)),
                (&p.resolve, Dispatch::Groups(x, y)),
                (&p.scan, Dispatch::Groups(1, 1)),
                (&p.write, Dispatch::Groups(x, y)),
            ],
        );
    }

    /// Runs one frame's cut, leaving the raw commands on the GPU. Does not wait.
    pub fn dispatch(
        &mut self,
        camera: &Camera,
        params: &Params,
    ) -> Result<&SelectBuffers, GpuError> {
        let ctx = self.ctx;
        ctx.submit("hier_select dispatch", "hier_select", |encoder| {
            self.encode(encoder, camera, params)
        })?;
        Ok(&self.raw)
    }

    /// Runs one frame's cut and reads the raw commands back. Blocks.
    pub fn run(&mut self, camera: &Camera, params: &Params) -> Result<GpuSelection, GpuError> {
        self.dispatch(camera, params)?;
        self.raw.read(self.ctx)
    }

    /// The last run's raw commands (one per emitted node and LOD, before coalescing). Blocks.
    pub fn read_uncoalesced(&self) -> Result<GpuSelection, GpuError> {
        self.raw.read(self.ctx)
    }

    /// Per-node codes (`forestlod_shared::node_code`) and states (visited 1, emitted 2) of the
    /// last run.
    pub fn read_codes_and_states(&self) -> Result<(Vec<u32>, Vec<u32>), GpuError> {
        let n = self.node_count as usize;
        Ok((
            read_buffer(self.ctx, &self.codes, 0, n)?,
            read_buffer(self.ctx, &self.states, 0, n)?,
        ))
    }
}
