//! Command coalescing on the GPU (issue 13; G§3's contiguous octant ranges): the driver of
//! `shaders/coalesce.wgsl`, twin of `reference/src/coalesce.rs`.
//!
//! ## Contract
//! Reads a cut's [`SelectBuffers`] (the *raw* commands, data and counters) and writes its own: the
//! reference's [`coalesce`](../../forestlod_reference/coalesce/index.html) of them, bit for bit
//! (integer work only: head flags, an exclusive scan, copies and one subtraction per run). Four
//! dispatches per frame whatever the command count; the scan's chunk loop runs
//! `capacity / 256` times, within llvmpipe's 65,535 iterations per invocation up to 16 M commands.
//! With [`Coalesce::Off`] every command is a head and the output is a copy of the input.

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use forestlod_shared::{Coalesce, SelectCounters};

use crate::context::{
    Dispatch, READ, Slot, WRITE, buffer_bind_group, compute_pass, compute_pipelines,
};
use crate::readback::{stage_uniform, zeroed_buffer};
use crate::select::SelectBuffers;
use crate::{GpuContext, GpuError};

/// Invocations per workgroup of the per-slot passes (generated into `coalesce.wgsl`'s module).
pub const COALESCE_WORKGROUP_SIZE: u32 = 64;

/// The `coalesce` stage's module: `coalesce.wgsl`, then [`crate::select::SCAN`].
pub const SOURCE: crate::shaders::StageSource = crate::shaders::StageSource {
    own: crate::shaders::WgslFile {
        name: "coalesce.wgsl",
        wgsl: include_str!("shaders/coalesce.wgsl"),
        constants: crate::shaders::wgsl_constants![COALESCE_WORKGROUP_SIZE],
    },
    parts: &[crate::select::SCAN],
};

/// The uniform of `coalesce.wgsl`. Keep in sync with `struct CoalesceUniform` there.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct CoalesceUniform {
    /// Command slots of the input and output buffers.
    pub capacity: u32,
    /// [`Coalesce`] id.
    pub mode: u32,
    /// Explicit padding.
    pub _pad0: u32,
    /// Explicit padding.
    pub _pad1: u32,
}
const _: () = assert!(size_of::<CoalesceUniform>() == 16);

compute_pipelines! {
    /// The compiled pipelines of `coalesce.wgsl`, one set per [`GpuContext`] (cached there).
    pub struct CoalescePipelines = "coalesce", SOURCE.module(), [
        Slot::Uniform(size_of::<CoalesceUniform>() as u64),
        READ, READ,
        Slot::Read(size_of::<SelectCounters>() as u64),
        WRITE, WRITE, WRITE,
        Slot::Write(size_of::<SelectCounters>() as u64),
    ],
    {
        heads: "coalesce_heads",
        scan: "coalesce_scan",
        write: "coalesce_write",
        finish: "coalesce_finish",
    }
}

/// Coalescing of one [`SelectBuffers`] (bound at creation) into buffers of its own.
pub struct GpuCoalesce<'a> {
    ctx: &'a GpuContext,
    pipelines: Arc<CoalescePipelines>,
    uniform: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    offsets: wgpu::Buffer,
    out: SelectBuffers,
}

impl<'a> GpuCoalesce<'a> {
    /// Output buffers of `input`'s capacity, bound with `input` as the raw commands.
    pub fn new(ctx: &'a GpuContext, input: &SelectBuffers) -> Result<Self, GpuError> {
        let pipelines = ctx.pipelines::<CoalescePipelines>()?;
        use wgpu::BufferUsages as U;
        let uniform = stage_uniform::<CoalesceUniform>(ctx, "coalesce uniform");
        let offsets = zeroed_buffer(
            ctx,
            "coalesce offsets",
            u64::from(input.capacity) * 4,
            U::STORAGE | U::COPY_SRC,
        );
        let out = SelectBuffers::with_capacity(ctx, input.capacity);
        let bind_group = ctx.checked("coalesce bind group", || {
            buffer_bind_group(
                &ctx.device,
                "coalesce",
                &pipelines.layout,
                &[
                    &uniform,
                    &input.commands,
                    &input.data,
                    &input.counters,
                    &offsets,
                    &out.commands,
                    &out.data,
                    &out.counters,
                ],
            )
        })?;
        Ok(Self {
            ctx,
            pipelines: pipelines.clone(),
            uniform,
            bind_group,
            offsets,
            out,
        })
    }

    /// The exclusive scan of the head flags, one `u32` per raw slot: raw command `j + 1`'s entry
    /// is the number of runs that start at or before `j` (read by `crate::command_order`).
    pub fn run_offsets(&self) -> &wgpu::Buffer {
        &self.offsets
    }

    /// The coalesced buffers (valid after an encoded frame has run).
    pub fn buffers(&self) -> &SelectBuffers {
        &self.out
    }

    /// The coalesced buffers, for a later stage that rewrites them in place (`refine`).
    pub fn buffers_mut(&mut self) -> &mut SelectBuffers {
        &mut self.out
    }

    /// Records the coalescing of the input's current contents (uniform through the queue,
    /// counters cleared, four dispatches).
    pub fn encode(&mut self, encoder: &mut wgpu::CommandEncoder, mode: Coalesce) {
        let capacity = self.out.capacity;
        let uniform = CoalesceUniform {
            capacity,
            mode: mode as u32,
            _pad0: 0,
            _pad1: 0,
        };
        self.ctx
            .queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uniform));
        encoder.clear_buffer(&self.out.counters, 0, None);
        let (x, y) = self
            .ctx
            .workgroup_grid(capacity.div_ceil(COALESCE_WORKGROUP_SIZE));
        let p = &self.pipelines;
        compute_pass(
            encoder,
            "coalesce",
            &self.bind_group,
            &[
                (&p.heads, Dispatch::Groups(x, y)),
                (&p.scan, Dispatch::Groups(1, 1)),
                (&p.write, Dispatch::Groups(x, y)),
                (&p.finish, Dispatch::Groups(x, y)),
            ],
        );
    }
}
