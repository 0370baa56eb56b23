//! Distance-sorted commands on the GPU (issue 13; E§7 "distance-sorted commands", front to
//! back): the driver of `shaders/command_order.wgsl`, twin of `reference/src/command_order.rs`.
//!
//! ## Contract
//! Reorders a coalesced cut ([`SelectBuffers`], in place) exactly as the reference's
//! [`order`](../../forestlod_reference/command_order/index.html): each run's key is the minimum
//! of `forestlod_shared::command_depth_key` over the nodes of its raw commands (found through the
//! coalescing's exclusive scan of head flags), the runs sorted by `(key, run)` ascending,
//! `base_vertex` renumbered. Integer work but for the keys' view depths, which may differ from
//! the reference's in the last bit (fused multiply-add); the parity test classifies those.
//!
//! The sort is a bitonic sort over `(key, index)` pairs padded to the power of two at or above
//! the capacity, one dispatch per merge step (`log2 P (log2 P + 1) / 2` steps, each picking its
//! `(k, j)` by a dynamic uniform offset), sized on the GPU to the power of two at or above the
//! command count (an indirect dispatch) and skipped past it: no loop in any invocation, so
//! llvmpipe's 65,535-iteration limit does not apply. The shader needs 10 storage buffers and a
//! stage may bind 8, so it has two bind-group layouts (the keys' and the sort's) over one module.
//! With [`CommandOrder::Node`] nothing is recorded.

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use forestlod_shared::{CommandOrder, SelectCounters, ViewUniform};

use crate::context::{Slot, StagePipelines, dynamic_uniform_slot, group_layout};
use crate::readback::{read_buffer, zeroed_buffer};
use crate::select::SelectBuffers;
use crate::{GpuContext, GpuError};

/// Invocations per workgroup (generated into `command_order.wgsl`'s module).
pub const COMMAND_ORDER_WORKGROUP_SIZE: u32 = 64;

/// The `command_order` stage's module: `command_order.wgsl`.
pub const SOURCE: crate::shaders::StageSource = crate::shaders::StageSource {
    own: crate::shaders::WgslFile {
        name: "command_order.wgsl",
        wgsl: include_str!("shaders/command_order.wgsl"),
        constants: crate::shaders::wgsl_constants![COMMAND_ORDER_WORKGROUP_SIZE],
    },
    parts: &[],
};

/// The per-frame uniform of `command_order.wgsl`. Keep in sync with `struct OrderUniform` there.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct OrderUniform {
    /// The shared view constants ([`ViewUniform::new`]): the keys' view depths.
    pub view: ViewUniform,
    /// Command slots of the raw and coalesced buffers.
    pub capacity: u32,
    /// Pair slots: the power of two at or above `capacity`.
    pub pair_capacity: u32,
    /// Explicit padding.
    pub _pad0: u32,
    /// Explicit padding.
    pub _pad1: u32,
}
const _: () = assert!(size_of::<OrderUniform>() == 176);

/// One bitonic merge step `(k, j)`, one per dynamic-offset slot. Keep in sync with `struct
/// OrderStep` in `command_order.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct OrderStep {
    /// Size of the bitonic sequences being merged.
    pub k: u32,
    /// Distance of the compared pairs.
    pub j: u32,
    /// Explicit padding.
    pub _pad0: u32,
    /// Explicit padding.
    pub _pad1: u32,
}
const _: () = assert!(size_of::<OrderStep>() == 16);

/// The bitonic steps `(k, j)` that sort `n` (a power of two) pairs, in order.
pub fn bitonic_steps(n: u32) -> Vec<OrderStep> {
    let mut steps = Vec::new();
    let mut k = 2;
    while k <= n {
        let mut j = k / 2;
        while j > 0 {
            steps.push(OrderStep {
                k,
                j,
                _pad0: 0,
                _pad1: 0,
            });
            j /= 2;
        }
        k *= 2;
    }
    steps
}

/// The compiled pipelines and the two layouts of `command_order.wgsl`.
#[derive(Debug)]
pub struct CommandOrderPipelines {
    keys_layout: wgpu::BindGroupLayout,
    sort_layout: wgpu::BindGroupLayout,
    init: wgpu::ComputePipeline,
    keys: wgpu::ComputePipeline,
    step: wgpu::ComputePipeline,
    gather: wgpu::ComputePipeline,
}

/// Binding numbers of the keys layout and the sort layout (as in `command_order.wgsl`).
const KEYS_SLOTS: [(u32, Slot); 8] = [
    (0, Slot::Uniform(size_of::<OrderUniform>() as u64)),
    (2, Slot::Read(0)),
    (3, Slot::Read(0)),
    (4, Slot::Read(size_of::<SelectCounters>() as u64)),
    (5, Slot::Read(0)),
    (6, Slot::Write(0)),
    (7, Slot::Read(size_of::<SelectCounters>() as u64)),
    (8, Slot::Write(12)),
];
const SORT_SLOTS: [(u32, Slot); 8] = [
    (0, Slot::Uniform(size_of::<OrderUniform>() as u64)),
    (1, Slot::DynamicUniform(size_of::<OrderStep>() as u64)),
    (7, Slot::Read(size_of::<SelectCounters>() as u64)),
    (9, Slot::Write(0)),
    (10, Slot::Read(0)),
    (11, Slot::Read(0)),
    (12, Slot::Write(0)),
    (13, Slot::Write(0)),
];

impl StagePipelines for CommandOrderPipelines {
    fn create(ctx: &GpuContext) -> Result<Self, GpuError> {
        ctx.checked("command_order.wgsl pipelines", || {
            let device = &ctx.device;
            let source = SOURCE.module();
            let module = crate::context::shader_module(device, "command_order.wgsl", &source);
            let layout = |label: &str, slots: &[(u32, Slot)]| {
                let entries: Vec<_> = slots.iter().map(|&(b, s)| s.entry(b)).collect();
                group_layout(device, label, &entries)
            };
            let (keys_layout, keys_pipeline_layout) = layout("command_order keys", &KEYS_SLOTS);
            let (sort_layout, sort_pipeline_layout) = layout("command_order sort", &SORT_SLOTS);
            let pipeline = |entry_point: &str, layout: &wgpu::PipelineLayout| {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry_point),
                    layout: Some(layout),
                    module: &module,
                    entry_point: Some(entry_point),
                    compilation_options: Default::default(),
                    cache: None,
                })
            };
            Self {
                init: pipeline("order_init", &keys_pipeline_layout),
                keys: pipeline("order_keys", &keys_pipeline_layout),
                step: pipeline("order_step", &sort_pipeline_layout),
                gather: pipeline("order_gather", &sort_pipeline_layout),
                keys_layout,
                sort_layout,
            }
        })
    }
}

/// The buffers of the cut that the command order reads and rewrites.
pub struct OrderInputs<'b> {
    /// The hierarchy's nodes.
    pub nodes: &'b wgpu::Buffer,
    /// The cut's raw (uncoalesced) commands.
    pub raw: &'b SelectBuffers,
    /// The coalescing's exclusive scan of head flags (one `u32` per raw slot).
    pub run_offsets: &'b wgpu::Buffer,
    /// The coalesced commands, reordered in place.
    pub out: &'b SelectBuffers,
}

/// The front-to-back order of one cut's coalesced commands (bound at creation).
pub struct GpuCommandOrder<'a> {
    ctx: &'a GpuContext,
    pipelines: Arc<CommandOrderPipelines>,
    uniform: wgpu::Buffer,
    keys_group: wgpu::BindGroup,
    sort_group: wgpu::BindGroup,
    /// `(key, index)` pairs, `2 * pair_capacity` `u32`s.
    pairs: wgpu::Buffer,
    /// The step dispatch's `(x, y, 1)`, written by `order_init`.
    step_args: wgpu::Buffer,
    /// Copies of the coalesced commands and data, gathered from.
    src_commands: wgpu::Buffer,
    src_data: wgpu::Buffer,
    /// Out buffers (to copy from).
    out_commands: wgpu::Buffer,
    out_data: wgpu::Buffer,
    steps: Vec<OrderStep>,
    stride: u32,
    capacity: u32,
    pair_capacity: u32,
}

impl<'a> GpuCommandOrder<'a> {
    /// Buffers for `inputs.out.capacity` commands, bound to `inputs`.
    pub fn new(ctx: &'a GpuContext, inputs: OrderInputs<'_>) -> Result<Self, GpuError> {
        let pipelines = ctx.pipelines::<CommandOrderPipelines>()?;
        use wgpu::BufferUsages as U;
        let capacity = inputs.out.capacity;
        let pair_capacity = capacity.max(1).next_power_of_two();
        let steps = bitonic_steps(pair_capacity);
        let align = ctx.limits.min_uniform_buffer_offset_alignment.max(1);
        let stride = (size_of::<OrderStep>() as u32).next_multiple_of(align);
        let mut step_bytes = vec![0u8; (stride as usize) * steps.len().max(1)];
        for (i, s) in steps.iter().enumerate() {
            let at = i * stride as usize;
            step_bytes[at..at + size_of::<OrderStep>()].copy_from_slice(bytemuck::bytes_of(s));
        }
        let step_uniforms = ctx.checked("command_order steps", || {
            wgpu::util::DeviceExt::create_buffer_init(
                &ctx.device,
                &wgpu::util::BufferInitDescriptor {
                    label: Some("command_order steps"),
                    contents: &step_bytes,
                    usage: U::UNIFORM,
                },
            )
        })?;
        let uniform = crate::readback::stage_uniform::<OrderUniform>(ctx, "command_order uniform");
        let pairs = zeroed_buffer(
            ctx,
            "command_order pairs",
            u64::from(pair_capacity) * 8,
            U::STORAGE | U::COPY_SRC,
        );
        let step_args = zeroed_buffer(
            ctx,
            "command_order step dispatch",
            12,
            U::STORAGE | U::INDIRECT,
        );
        let copy = |label, of: &wgpu::Buffer| {
            zeroed_buffer(ctx, label, of.size(), U::STORAGE | U::COPY_DST)
        };
        let src_commands = copy("command_order source commands", &inputs.out.commands);
        let src_data = copy("command_order source data", &inputs.out.data);
        let (keys_group, sort_group) = ctx.checked("command_order bind groups", || {
            fn whole(b: &wgpu::Buffer) -> wgpu::BindingResource<'_> {
                b.as_entire_binding()
            }
            fn entries(
                list: Vec<(u32, wgpu::BindingResource<'_>)>,
            ) -> Vec<wgpu::BindGroupEntry<'_>> {
                list.into_iter()
                    .map(|(binding, resource)| wgpu::BindGroupEntry { binding, resource })
                    .collect()
            }
            let keys_entries = entries(vec![
                (0, whole(&uniform)),
                (2, whole(inputs.nodes)),
                (3, whole(&inputs.raw.data)),
                (4, whole(&inputs.raw.counters)),
                (5, whole(inputs.run_offsets)),
                (6, whole(&pairs)),
                (7, whole(&inputs.out.counters)),
                (8, whole(&step_args)),
            ]);
            let sort_entries = entries(vec![
                (0, whole(&uniform)),
                (1, dynamic_uniform_slot::<OrderStep>(&step_uniforms)),
                (7, whole(&inputs.out.counters)),
                (9, whole(&pairs)),
                (10, whole(&src_commands)),
                (11, whole(&src_data)),
                (12, whole(&inputs.out.commands)),
                (13, whole(&inputs.out.data)),
            ]);
            let make = |label, layout, entries: &[wgpu::BindGroupEntry<'_>]| {
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some(label),
                    layout,
                    entries,
                })
            };
            (
                make("command_order keys", &pipelines.keys_layout, &keys_entries),
                make("command_order sort", &pipelines.sort_layout, &sort_entries),
            )
        })?;
        Ok(Self {
            ctx,
            pipelines: pipelines.clone(),
            uniform,
            keys_group,
            sort_group,
            pairs,
            step_args,
            src_commands,
            src_data,
            out_commands: inputs.out.commands.clone(),
            out_data: inputs.out.data.clone(),
            steps,
            stride,
            capacity,
            pair_capacity,
        })
    }

    /// Records the reordering of the coalesced commands under `order` (nothing for `node`):
    /// copies of the commands and data, then init, keys, every merge step and the gather.
    pub fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        view: &ViewUniform,
        order: CommandOrder,
    ) {
        if order == CommandOrder::Node {
            return;
        }
        let uniform = OrderUniform {
            view: *view,
            capacity: self.capacity,
            pair_capacity: self.pair_capacity,
            _pad0: 0,
            _pad1: 0,
        };
        self.ctx
            .queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uniform));
        encoder.copy_buffer_to_buffer(&self.out_commands, 0, &self.src_commands, 0, None);
        encoder.copy_buffer_to_buffer(&self.out_data, 0, &self.src_data, 0, None);
        let grid = |n: u32| {
            self.ctx
                .workgroup_grid(n.div_ceil(COMMAND_ORDER_WORKGROUP_SIZE))
        };
        let p = &self.pipelines;
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("command_order"),
            timestamp_writes: None,
        });
        pass.set_bind_group(0, &self.keys_group, &[]);
        let (x, y) = grid(self.pair_capacity);
        pass.set_pipeline(&p.init);
        pass.dispatch_workgroups(x, y, 1);
        let (x, y) = grid(self.capacity);
        pass.set_pipeline(&p.keys);
        pass.dispatch_workgroups(x, y, 1);
        pass.set_pipeline(&p.step);
        for i in 0..self.steps.len() as u32 {
            pass.set_bind_group(0, &self.sort_group, &[i * self.stride]);
            pass.dispatch_workgroups_indirect(&self.step_args, 0);
        }
        pass.set_bind_group(0, &self.sort_group, &[0]);
        pass.set_pipeline(&p.gather);
        pass.dispatch_workgroups(x, y, 1);
    }

    /// The last run's `(key, run)` pairs of the first `n` slots, in the sorted order (valid after
    /// a frame with `front-to-back`). Blocks.
    pub fn read_pairs(&self, n: usize) -> Result<Vec<(u32, u32)>, GpuError> {
        let flat: Vec<u32> = read_buffer(self.ctx, &self.pairs, 0, 2 * n)?;
        Ok(flat.chunks_exact(2).map(|c| (c[0], c[1])).collect())
    }
}
