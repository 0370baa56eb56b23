//! The selection chain of a GPU frame: the drivers of the frame plan's selection stages
//! (`forestlod_shared::FramePlan::selection_stages`), each bound at creation to the buffers the
//! stage before it writes, recorded in the plan's order. The flat plan is `select.wgsl`; a cut is
//! `hier_select.wgsl`, then `coalesce.wgsl` (bound to the raw cut), then `command_order.wgsl`
//! (reading the nodes, the raw cut and the coalescing's run offsets, reordering the coalesced
//! commands in place) — three drivers, none owning another (before issue 27, `GpuHierSelect`
//! owned the other two, so neither could be fed from the reference or judged alone).
//!
//! A link of the chain is either its GPU driver or the reference's output of that stage uploaded
//! ([`super::StagesFromCpu`]): the reference computes a prefix of the chain, the GPU the rest. `refine`
//! is not part of the chain: it rewrites the chain's output in place, and the frame
//! (`super::GpuScene`) keeps one for the scene and records it after the chain when the plan has it.

use forestlod_gpu::command_order::OrderInputs;
use forestlod_gpu::hier_select::FarNodes;
use forestlod_gpu::readback::upload_storage;

use crate::bridge::OrderFromCpu;
use forestlod_gpu::{
    Compaction, GpuCoalesce, GpuCommandOrder, GpuContext, GpuError, GpuHierSelect, GpuSelect,
    GpuSelection, SelectBuffers,
};
use forestlod_reference::frame::SelectionTrace;
use forestlod_reference::pipeline::Prepared;
use forestlod_reference::select::Selection;
use forestlod_shared::{
    Camera, FramePlan, MeshMeta, NodeMeta, Params, SelectionPlan, StageId, ViewUniform,
};

/// The first link: the flat selection or the raw cut, on the GPU or uploaded.
enum First<'a> {
    Select(GpuSelect<'a>),
    Hier(GpuHierSelect<'a>),
    Cpu(SelectBuffers),
}

/// The coalescing link of a cut: on the GPU, or its output and run offsets uploaded.
enum CoalesceLink<'a> {
    Gpu(GpuCoalesce<'a>),
    Cpu {
        out: SelectBuffers,
        // Kept alive with the chain for readers; also bound into the order's bind group.
        #[allow(
            dead_code,
            reason = "owned so the order stage's binding outlives the frame"
        )]
        offsets: wgpu::Buffer,
    },
}

/// One frame's selection chain (module docs).
pub struct SelectionChain<'a> {
    ctx: &'a GpuContext,
    first: First<'a>,
    coalesce: Option<CoalesceLink<'a>>,
    order: Option<GpuCommandOrder<'a>>,
    /// The stages this chain records on the GPU, in order.
    gpu_stages: Vec<StageId>,
}

impl<'a> SelectionChain<'a> {
    /// The whole chain on the GPU for `prepared`: `select.wgsl` over its batches, or the cut's
    /// three drivers over its hierarchy when it was prepared with one.
    pub fn gpu(ctx: &'a GpuContext, prepared: &Prepared) -> Result<Self, GpuError> {
        let g = &prepared.geometry;
        Ok(match &prepared.hierarchy {
            None => Self {
                ctx,
                first: First::Select(GpuSelect::new(
                    ctx,
                    &prepared.batches.metas,
                    &prepared.batches.scales,
                    &g.meshes,
                    &g.billboard,
                )?),
                coalesce: None,
                order: None,
                gpu_stages: vec![StageId::Select],
            },
            Some(h) => Self::cut(
                ctx,
                &h.nodes,
                &h.scales,
                h.mode as u32,
                &g.meshes,
                &g.billboard,
                prepared.far.as_ref().map(|f| FarNodes {
                    nodes: &f.nodes,
                    first_index: g.far.first_index,
                }),
            )?,
        })
    }

    /// The whole cut on the GPU over `nodes` (a hierarchy built for `mode`, a
    /// `forestlod_shared::Hierarchy` id): `hier_select`, then `coalesce` bound to its raw cut,
    /// then `command_order` on the coalesced commands.
    pub fn cut(
        ctx: &'a GpuContext,
        nodes: &[NodeMeta],
        scales: &[[f32; 2]],
        mode: u32,
        meshes: &[MeshMeta],
        billboard: &MeshMeta,
        far: Option<FarNodes<'_>>,
    ) -> Result<Self, GpuError> {
        let hier = GpuHierSelect::new(ctx, nodes, scales, mode, meshes, billboard, far)?;
        let coalesce = GpuCoalesce::new(ctx, hier.buffers())?;
        let order = GpuCommandOrder::new(
            ctx,
            OrderInputs {
                nodes: hier.nodes(),
                raw: hier.buffers(),
                run_offsets: coalesce.run_offsets(),
                out: coalesce.buffers(),
            },
        )?;
        Ok(Self {
            ctx,
            first: First::Hier(hier),
            coalesce: Some(CoalesceLink::Gpu(coalesce)),
            order: Some(order),
            gpu_stages: vec![
                StageId::HierSelect,
                StageId::Coalesce,
                StageId::CommandOrder,
            ],
        })
    }

    /// The chain of one frame whose first stages, up to `last_cpu` (a stage of `plan`'s
    /// selection), the reference computed (`trace`, kept with `keep = true`): their output is
    /// uploaded, the GPU drivers of the stages after it are bound to it. For `refine`, the
    /// refined selection is uploaded and no GPU stage runs.
    pub fn from_cpu(
        ctx: &'a GpuContext,
        prepared: &Prepared,
        plan: &FramePlan,
        trace: &SelectionTrace,
        last_cpu: StageId,
    ) -> Result<Self, GpuError> {
        let output = |stage: StageId| -> Result<&Selection, GpuError> {
            trace.output(stage).ok_or_else(|| GpuError::Input {
                field: "stage-from-cpu",
                value: stage.name().into(),
                reason: "the reference's trace holds no output of this stage (it was not kept, or the plan does not run it)",
            })
        };
        let upload =
            |s: &Selection| SelectBuffers::from_cpu(ctx, &s.commands, &s.data, &s.counters);
        let whole = |stage| -> Result<Self, GpuError> {
            Ok(Self {
                ctx,
                first: First::Cpu(upload(output(stage)?)?),
                coalesce: None,
                order: None,
                gpu_stages: Vec::new(),
            })
        };
        let SelectionPlan::Cut { coalesce: mode, .. } = plan.selection else {
            // Flat: the selection (or its refinement) is the whole chain.
            return whole(last_cpu);
        };
        let nodes = prepared
            .hierarchy
            .as_ref()
            .map(|h| &h.nodes[..])
            .ok_or(GpuError::Input {
                field: "prepared.hierarchy",
                value: "none".into(),
                reason: "the frame's plan is a cut: the scene must be prepared with its hierarchy",
            })?;
        match last_cpu {
            StageId::HierSelect => {
                let raw = upload(output(StageId::HierSelect)?)?;
                let nodes =
                    upload_storage(ctx, "hier nodes (cpu)", nodes, wgpu::BufferUsages::empty());
                let coalesce = GpuCoalesce::new(ctx, &raw)?;
                let order = GpuCommandOrder::new(
                    ctx,
                    OrderInputs {
                        nodes: &nodes,
                        raw: &raw,
                        run_offsets: coalesce.run_offsets(),
                        out: coalesce.buffers(),
                    },
                )?;
                Ok(Self {
                    ctx,
                    first: First::Cpu(raw),
                    coalesce: Some(CoalesceLink::Gpu(coalesce)),
                    order: Some(order),
                    gpu_stages: vec![StageId::Coalesce, StageId::CommandOrder],
                })
            }
            StageId::Coalesce => {
                let OrderFromCpu {
                    raw,
                    out,
                    offsets,
                    order,
                } = OrderFromCpu::new(
                    ctx,
                    nodes,
                    output(StageId::HierSelect)?,
                    output(StageId::Coalesce)?,
                    mode,
                )?;
                Ok(Self {
                    ctx,
                    first: First::Cpu(raw),
                    coalesce: Some(CoalesceLink::Cpu { out, offsets }),
                    order: Some(order),
                    gpu_stages: vec![StageId::CommandOrder],
                })
            }
            // command_order (the cut's output) or refine: uploaded whole.
            stage => whole(stage),
        }
    }

    /// Replaces the GPU cut's far level node records (issue 33 item 2: the frame's impostor
    /// state, `GpuHierSelect::write_far_nodes`); a chain whose cut is the reference's (uploaded)
    /// or a flat chain has none to replace.
    pub fn write_far_nodes(&self, nodes: &[forestlod_shared::FarNode]) -> Result<(), GpuError> {
        match &self.first {
            First::Hier(h) => h.write_far_nodes(nodes),
            First::Select(_) | First::Cpu(_) => Ok(()),
        }
    }

    /// The stages this chain records on the GPU, in the plan's order.
    pub fn gpu_stages(&self) -> &[StageId] {
        &self.gpu_stages
    }

    /// Records the chain's GPU stages for one frame (`compaction` applies to the flat selection
    /// only: the cut has no atomic compaction). `params` must be valid and its plan this chain's.
    pub fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        params: &Params,
        compaction: Compaction,
    ) {
        match &mut self.first {
            First::Select(s) => s.encode(encoder, camera, params, compaction),
            First::Hier(h) => h.encode(encoder, camera, params),
            First::Cpu(_) => {}
        }
        if let Some(CoalesceLink::Gpu(c)) = &mut self.coalesce {
            let mode = params
                .coalescing()
                .expect("parameters are validated before selection");
            c.encode(encoder, mode);
        }
        if let Some(o) = &mut self.order {
            let order = params
                .command_ordering()
                .expect("parameters are validated before selection");
            o.encode(encoder, &ViewUniform::new(camera, params), order);
        }
    }

    /// Runs the chain for one frame, leaving its output on the GPU. Does not wait.
    pub fn dispatch(
        &mut self,
        camera: &Camera,
        params: &Params,
        compaction: Compaction,
    ) -> Result<&SelectBuffers, GpuError> {
        let ctx = self.ctx;
        let encoder = ctx.checked("selection dispatch", || {
            let mut encoder = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("selection"),
                });
            self.encode(&mut encoder, camera, params, compaction);
            encoder
        })?;
        ctx.queue.submit([encoder.finish()]);
        Ok(self.buffers())
    }

    /// Runs the chain for one frame and reads its output back. Blocks.
    pub fn run(
        &mut self,
        camera: &Camera,
        params: &Params,
        compaction: Compaction,
    ) -> Result<GpuSelection, GpuError> {
        self.dispatch(camera, params, compaction)?;
        self.buffers().read(self.ctx)
    }

    /// The last run's raw cut (before coalescing). Blocks. Errors on a flat chain.
    pub fn read_uncoalesced(&self) -> Result<GpuSelection, GpuError> {
        self.raw().ok_or_else(not_a_cut)?.read(self.ctx)
    }

    /// The last run's per-node codes and states (`GpuHierSelect::read_codes_and_states`).
    /// Blocks. Errors unless the cut ran on the GPU.
    pub fn read_codes_and_states(&self) -> Result<(Vec<u32>, Vec<u32>), GpuError> {
        self.hier().ok_or_else(not_a_cut)?.read_codes_and_states()
    }

    /// The last run's front-to-back `(key, run)` pairs of the first `n` output slots
    /// (`GpuCommandOrder::read_pairs`). Blocks. Errors unless the order ran on the GPU.
    pub fn read_order_pairs(&self, n: usize) -> Result<Vec<(u32, u32)>, GpuError> {
        self.order().ok_or_else(not_a_cut)?.read_pairs(n)
    }

    /// The chain's output: the last link's buffers (valid after a run).
    pub fn buffers(&self) -> &SelectBuffers {
        match (&self.coalesce, &self.first) {
            (Some(CoalesceLink::Gpu(c)), _) => c.buffers(),
            (Some(CoalesceLink::Cpu { out, .. }), _) => out,
            (None, First::Select(s)) => s.buffers(),
            (None, First::Hier(h)) => h.buffers(),
            (None, First::Cpu(b)) => b,
        }
    }

    /// The chain's output, for `refine` to rewrite in place.
    pub fn buffers_mut(&mut self) -> &mut SelectBuffers {
        match (&mut self.coalesce, &mut self.first) {
            (Some(CoalesceLink::Gpu(c)), _) => c.buffers_mut(),
            (Some(CoalesceLink::Cpu { out, .. }), _) => out,
            (None, First::Select(s)) => s.buffers_mut(),
            (None, First::Hier(h)) => h.buffers_mut(),
            (None, First::Cpu(b)) => b,
        }
    }

    /// The raw cut's buffers (the first link's, for a cut), for reading.
    pub fn raw(&self) -> Option<&SelectBuffers> {
        match (&self.first, &self.coalesce) {
            (First::Hier(h), _) => Some(h.buffers()),
            (First::Cpu(b), Some(_)) => Some(b),
            _ => None,
        }
    }

    /// The flat selection's driver (for its per-batch decisions).
    pub fn flat(&self) -> Option<&GpuSelect<'a>> {
        match &self.first {
            First::Select(s) => Some(s),
            _ => None,
        }
    }

    /// The cut's driver (for its per-node codes and states).
    pub fn hier(&self) -> Option<&GpuHierSelect<'a>> {
        match &self.first {
            First::Hier(h) => Some(h),
            _ => None,
        }
    }

    /// The command order's driver (for its `(key, run)` pairs).
    pub fn order(&self) -> Option<&GpuCommandOrder<'a>> {
        self.order.as_ref()
    }
}

/// The error of a cut's reader on a chain without that GPU stage.
fn not_a_cut() -> GpuError {
    GpuError::Input {
        field: "selection chain",
        value: "no such GPU stage".into(),
        reason: "this reader needs the cut's stage on the GPU (a chain of SelectionChain::cut)",
    }
}
