//! Per-batch LOD selection and draw-command generation on the GPU (E§3.5, §4.3; SPEC §5.4): the
//! driver of `shaders/select.wgsl`, twin of `reference/src/select.rs`.
//!
//! ## Contract
//! For each batch, exactly the reference's rule: project the bounding sphere onto the view
//! direction (`[d - r - m, d + r + m]`, E§3.5), cull it beyond the draw distance or outside a
//! frustum plane, otherwise emit one indexed indirect command per LOD the interval needs, with
//! its [`CommandData`]. Outputs are three GPU buffers ([`SelectBuffers`]) usable directly by the
//! draw stage: `commands` as the `INDIRECT` argument of `multi_draw_indexed_indirect(_count)`,
//! `counters` as its count buffer (at [`SelectBuffers::COUNT_OFFSET`]), `data` as a storage buffer.
//!
//! Two compactions ([`Compaction`]):
//! - **Stable** (three dispatches: decide, scan, write): batch order, LOD0 before LOD1, command `i`
//!   with `base_vertex = i << COMMAND_SHIFT`. Equal to the reference bit for bit (SPEC §8), up to
//!   decisions within ε of a threshold, where the GPU may round differently (fused multiply-add).
//! - **Atomic** (one dispatch, as the thesis, E§4.3): each batch reserves its slots with one
//!   `atomicAdd` on the command counter; the order is arbitrary, so parity is judged as a multiset
//!   after masking `base_vertex` (which is still `slot << COMMAND_SHIFT`).
//!
//! Either way the CPU records O(1) dispatches per frame whatever the batch count (batches beyond
//! `65535 * 64` spill into a second dispatch dimension, not into more dispatches). The per-frame
//! constants are derived on the CPU by the reference's own `forestlod_shared::ViewUniform::new`
//! (eye, unit forward, frustum planes, fade band), so only the per-batch arithmetic runs on the GPU.
//!
//! The draw stage can also take the reference's output instead ([`SelectBuffers::from_cpu`]), to
//! test it in isolation (`--stage-from-cpu`).

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use forestlod_shared::{
    BatchMeta, COMMAND_SHIFT, Camera, CommandData, DrawCommand, MAX_COMMANDS, MeshMeta, Params,
    SelectCounters, ViewUniform,
};

use crate::context::{
    Dispatch, READ, Slot, WRITE, buffer_bind_group, compute_pass, compute_pipelines,
};
use crate::readback::{read_buffer, stage_uniform, upload_storage, zeroed_buffer};
use crate::shaders::{StageSource, WgslFile, wgsl_constants};
use crate::{GpuContext, GpuError};

/// Invocations per workgroup of the per-batch passes (generated into `select.wgsl`'s module).
pub const SELECT_WORKGROUP_SIZE: u32 = 64;
/// Invocations of the single scan workgroup (generated with [`SCAN`]).
pub const SCAN_WORKGROUP_SIZE: u32 = 256;

/// The stable compaction's exclusive prefix sum (`scan.wgsl`: `scan_offsets`), appended to the
/// modules that scan an `offsets` array: this stage's, `hier_select`'s and `coalesce`'s.
pub const SCAN: WgslFile = WgslFile {
    name: "scan.wgsl",
    wgsl: include_str!("shaders/scan.wgsl"),
    constants: wgsl_constants![SCAN_WORKGROUP_SIZE],
};

/// The `select` stage's module: `select.wgsl`, then [`SCAN`].
pub const SOURCE: StageSource = StageSource {
    own: WgslFile {
        name: "select.wgsl",
        wgsl: include_str!("shaders/select.wgsl"),
        constants: wgsl_constants![SELECT_WORKGROUP_SIZE],
    },
    parts: &[SCAN],
};

/// Per-batch (and, in `cull`, per-tree) decision codes: defined with
/// [`forestlod_shared::Decision`] (`Decision::code` / `Decision::from_code`), mirrored in
/// `common.wgsl`; re-exported at their old paths.
pub use forestlod_shared::{
    DECISION_CULLED_DISTANCE, DECISION_CULLED_FRUSTUM, DECISION_DRAW, DECISION_KIND_MASK,
    DECISION_LOD0, DECISION_LOD1,
};

/// Which compaction writes the commands (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Compaction {
    /// Prefix-sum compaction: deterministic, equal to the reference.
    Stable,
    /// Atomic-counter compaction as in the thesis (E§4.3): arbitrary order.
    Atomic,
}

impl Compaction {
    /// Both variants.
    pub const ALL: [Compaction; 2] = [Compaction::Stable, Compaction::Atomic];
    /// Name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Compaction::Stable => "stable",
            Compaction::Atomic => "atomic",
        }
    }
}

/// The per-frame uniform of `select.wgsl`. Keep in sync with `struct SelectUniform` there.
///
/// The shared view constants ([`ViewUniform`], the reference's `select::SelectUniform`) plus the
/// sizes and the billboard range the shader needs.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct SelectUniform {
    /// Eye, forward, frustum, fade band, draw distance, LOD levels ([`ViewUniform::new`]).
    pub view: ViewUniform,
    /// Number of batches.
    pub batch_count: u32,
    /// Number of meshes.
    pub mesh_count: u32,
    /// First index of the billboard quad in the shared index buffer.
    pub billboard_first_index: u32,
    /// Index count of the billboard quad.
    pub billboard_index_count: u32,
}
const _: () = assert!(size_of::<SelectUniform>() == 176);

impl SelectUniform {
    /// The uniform for a camera and parameters ([`ViewUniform::new`], as the reference's).
    pub fn new(
        camera: &Camera,
        params: &Params,
        batch_count: u32,
        mesh_count: u32,
        billboard: &MeshMeta,
    ) -> Self {
        Self {
            view: ViewUniform::new(camera, params),
            batch_count,
            mesh_count,
            billboard_first_index: billboard.first_index,
            billboard_index_count: billboard.index_count,
        }
    }
}

/// What selection emitted for one frame, read back (mirrors `reference::select::Selection`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GpuSelection {
    /// Draw commands, `counters.commands` of them.
    pub commands: Vec<DrawCommand>,
    /// Per-command data, parallel to `commands`.
    pub data: Vec<CommandData>,
    /// Work counters.
    pub counters: SelectCounters,
}

/// The output buffers of `select`, the input of the draw stage.
#[derive(Debug)]
pub struct SelectBuffers {
    /// `DrawCommand`s: `STORAGE | INDIRECT | COPY_SRC | COPY_DST`.
    pub commands: wgpu::Buffer,
    /// `CommandData`s: `STORAGE | COPY_SRC | COPY_DST`.
    pub data: wgpu::Buffer,
    /// One `SelectCounters`: `STORAGE | INDIRECT | COPY_SRC | COPY_DST`; its `commands` field is
    /// the draw count of `multi_draw_indexed_indirect_count`.
    pub counters: wgpu::Buffer,
    /// How many commands the buffers hold at most.
    pub capacity: u32,
}

impl SelectBuffers {
    /// Byte offset of `SelectCounters::commands` in [`SelectBuffers::counters`]: the count-buffer
    /// offset for `multi_draw_indexed_indirect_count`.
    pub const COUNT_OFFSET: u64 = core::mem::offset_of!(SelectCounters, commands) as u64;

    /// Empty buffers for up to `capacity` commands (at least one).
    pub fn with_capacity(ctx: &GpuContext, capacity: u32) -> Self {
        use wgpu::BufferUsages as U;
        let capacity = capacity.max(1);
        let usage = U::STORAGE | U::COPY_SRC | U::COPY_DST;
        Self {
            commands: zeroed_buffer(
                ctx,
                "select commands",
                u64::from(capacity) * size_of::<DrawCommand>() as u64,
                usage | U::INDIRECT,
            ),
            data: zeroed_buffer(
                ctx,
                "select command data",
                u64::from(capacity) * size_of::<CommandData>() as u64,
                usage,
            ),
            counters: zeroed_buffer(
                ctx,
                "select counters",
                size_of::<SelectCounters>() as u64,
                usage | U::INDIRECT,
            ),
            capacity,
        }
    }

    /// Buffers holding a selection computed elsewhere (the reference's `Selection`: pass
    /// `&s.commands, &s.data, &s.counters`), so the draw stage can run on CPU input
    /// (`--stage-from-cpu`). `counters.commands` should equal `commands.len()`.
    pub fn from_cpu(
        ctx: &GpuContext,
        commands: &[DrawCommand],
        data: &[CommandData],
        counters: &SelectCounters,
    ) -> Result<Self, GpuError> {
        if commands.len() != data.len() || counters.commands as usize != commands.len() {
            return Err(GpuError::Input {
                field: "selection",
                value: format!(
                    "{} commands, {} data, counters.commands = {}",
                    commands.len(),
                    data.len(),
                    counters.commands
                ),
                reason: "expected as many commands as data records and counters.commands",
            });
        }
        use wgpu::BufferUsages as U;
        Ok(Self {
            commands: upload_storage(ctx, "select commands (cpu)", commands, U::INDIRECT),
            data: upload_storage(ctx, "select command data (cpu)", data, U::empty()),
            counters: upload_storage(
                ctx,
                "select counters (cpu)",
                std::slice::from_ref(counters),
                U::INDIRECT,
            ),
            capacity: (commands.len() as u32).max(1),
        })
    }

    /// Reads the counters, then that many commands and data records. Blocks.
    pub fn read(&self, ctx: &GpuContext) -> Result<GpuSelection, GpuError> {
        let counters = read_buffer::<SelectCounters>(ctx, &self.counters, 0, 1)?[0];
        let n = counters.commands;
        if n > self.capacity {
            return Err(GpuError::Input {
                field: "counters.commands",
                value: n.to_string(),
                reason: "exceeds the command buffers' capacity: the GPU wrote out of range",
            });
        }
        Ok(GpuSelection {
            commands: read_buffer(ctx, &self.commands, 0, n as usize)?,
            data: read_buffer(ctx, &self.data, 0, n as usize)?,
            counters,
        })
    }
}

/// Refuses `count` selectable items (batches, hierarchy nodes) whose two commands each (LOD0 and
/// LOD1) could exceed [`MAX_COMMANDS`], naming `field` and `reason`; else the command capacity,
/// two per item.
pub(crate) fn check_command_capacity(
    field: &'static str,
    count: usize,
    reason: &'static str,
) -> Result<usize, GpuError> {
    let capacity = count.saturating_mul(2);
    if capacity > MAX_COMMANDS as usize {
        return Err(GpuError::Input {
            field,
            value: count.to_string(),
            reason,
        });
    }
    Ok(capacity)
}

/// Fails with [`GpuError::Input`] on `field` unless there is one scale range per group
/// (`groups` batches or nodes, `scales` ranges given).
pub(crate) fn check_scale_count(
    field: &'static str,
    groups: usize,
    scales: usize,
) -> Result<(), GpuError> {
    if groups == scales {
        return Ok(());
    }
    Err(GpuError::Input {
        field,
        value: format!("{scales} scale ranges for {groups} groups"),
        reason: "expected one [min, max] tree scale range per group",
    })
}

/// Fails with [`GpuError::Input`] on `field` (`"{item}.mesh"`) at the first `item` whose mesh
/// index (`mesh_indices`, in order) is not below `mesh_count`.
pub(crate) fn check_mesh_indices(
    field: &'static str,
    item: &str,
    mesh_indices: impl IntoIterator<Item = u32>,
    mesh_count: usize,
) -> Result<(), GpuError> {
    match (0..)
        .zip(mesh_indices)
        .find(|&(_, mesh)| mesh as usize >= mesh_count)
    {
        Some((i, mesh)) => Err(GpuError::Input {
            field,
            value: format!("{item} {i} mesh {mesh} of {mesh_count} meshes"),
            reason: "expected a mesh index below the mesh count",
        }),
        None => Ok(()),
    }
}

compute_pipelines! {
    /// The compiled pipelines of `select.wgsl` (its four passes), one set per [`GpuContext`]
    /// (cached there).
    pub struct SelectPipelines = "select", SOURCE.module(), [
        Slot::Uniform(size_of::<SelectUniform>() as u64),
        READ, READ, WRITE, WRITE, WRITE, WRITE,
        Slot::Write(size_of::<SelectCounters>() as u64),
        READ,
    ],
    {
        decide: "select_decide",
        scan: "select_scan",
        write: "select_write",
        atomic: "select_atomic",
    }
}

/// One scene's batches on the GPU, ready to select for any camera and parameters.
pub struct GpuSelect<'a> {
    ctx: &'a GpuContext,
    /// The stage's pipelines, from the context's cache.
    pipelines: Arc<SelectPipelines>,
    uniform: wgpu::Buffer,
    decisions: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    out: SelectBuffers,
    batch_count: u32,
    mesh_count: u32,
    billboard: MeshMeta,
}

impl<'a> GpuSelect<'a> {
    /// Uploads the batches, their trees' scale ranges (`scales`, one `[min, max]` per batch, the
    /// reference's `Batches::scales`: a scaled LOD metric's group bands) and meshes (`meshes`
    /// with their packed index ranges, as the reference's `pack_geometry` gives them;
    /// `billboard` the quad's range) and allocates room for two commands per batch. Fails on a
    /// scale range count other than the batch count, a batch whose mesh index is out of range
    /// or more commands than `base_vertex` can address ([`MAX_COMMANDS`]).
    pub fn new(
        ctx: &'a GpuContext,
        batches: &[BatchMeta],
        scales: &[[f32; 2]],
        meshes: &[MeshMeta],
        billboard: &MeshMeta,
    ) -> Result<Self, GpuError> {
        check_scale_count("batch scales", batches.len(), scales.len())?;
        check_mesh_indices(
            "batch.mesh",
            "batch",
            batches.iter().map(|b| b.mesh),
            meshes.len(),
        )?;
        let capacity = check_command_capacity(
            "batches",
            batches.len(),
            "two commands per batch exceed MAX_COMMANDS (base_vertex is an i32)",
        )?;
        let pipelines = ctx.pipelines::<SelectPipelines>()?;
        use wgpu::BufferUsages as U;
        let n = batches.len() as u64;
        let batch_buffer = upload_storage(ctx, "select batches", batches, U::empty());
        let mesh_buffer = upload_storage(ctx, "select meshes", meshes, U::empty());
        let scale_buffer = upload_storage(ctx, "select scales", scales, U::empty());
        let uniform = stage_uniform::<SelectUniform>(ctx, "select uniform");
        let decisions = zeroed_buffer(ctx, "select decisions", n * 4, U::STORAGE | U::COPY_SRC);
        let offsets = zeroed_buffer(ctx, "select offsets", n * 4, U::STORAGE | U::COPY_SRC);
        let out = SelectBuffers::with_capacity(ctx, capacity as u32);
        let bind_group = ctx.checked("select bind group", || {
            buffer_bind_group(
                &ctx.device,
                "select",
                &pipelines.layout,
                &[
                    &uniform,
                    &batch_buffer,
                    &mesh_buffer,
                    &decisions,
                    &offsets,
                    &out.commands,
                    &out.data,
                    &out.counters,
                    &scale_buffer,
                ],
            )
        })?;
        Ok(Self {
            ctx,
            pipelines: pipelines.clone(),
            uniform,
            decisions,
            bind_group,
            out,
            batch_count: batches.len() as u32,
            mesh_count: meshes.len() as u32,
            billboard: *billboard,
        })
    }

    /// Number of batches.
    pub fn batch_count(&self) -> u32 {
        self.batch_count
    }

    /// The output buffers (valid after a [`GpuSelect::dispatch`] or [`GpuSelect::encode`] has run).
    pub fn buffers(&self) -> &SelectBuffers {
        &self.out
    }

    /// The output buffers, for a later stage of the same frame that rewrites them in place
    /// ([`crate::GpuRefine::encode`]); exclusive, so no other frame can be selecting into them.
    pub fn buffers_mut(&mut self) -> &mut SelectBuffers {
        &mut self.out
    }

    /// Workgroup counts `(x, y)` covering every batch with `SELECT_WORKGROUP_SIZE` invocations
    /// each, spilling into `y` beyond the per-dimension limit.
    fn groups(&self) -> (u32, u32) {
        let groups = self.batch_count.div_ceil(SELECT_WORKGROUP_SIZE);
        self.ctx.workgroup_grid(groups)
    }

    /// Records one frame's selection into `encoder`: writes the uniform (through the queue, so it
    /// lands before the next submit), clears the counters, then three dispatches (stable) or one
    /// (atomic). `camera` and `params` should be validated, as for the reference.
    pub fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        params: &Params,
        compaction: Compaction,
    ) {
        let uniform = SelectUniform::new(
            camera,
            params,
            self.batch_count,
            self.mesh_count,
            &self.billboard,
        );
        self.ctx
            .queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uniform));
        encoder.clear_buffer(&self.out.counters, 0, None);
        let pipelines = &self.pipelines;
        let (x, y) = self.groups();
        let steps = match compaction {
            Compaction::Stable => vec![
                (&pipelines.decide, Dispatch::Groups(x, y)),
                (&pipelines.scan, Dispatch::Groups(1, 1)),
                (&pipelines.write, Dispatch::Groups(x, y)),
            ],
            Compaction::Atomic => vec![(&pipelines.atomic, Dispatch::Groups(x, y))],
        };
        compute_pass(encoder, "select", &self.bind_group, &steps);
    }

    /// Runs one frame's selection and leaves the result on the GPU ([`GpuSelect::buffers`]) for
    /// the draw stage. Does not wait.
    pub fn dispatch(
        &mut self,
        camera: &Camera,
        params: &Params,
        compaction: Compaction,
    ) -> Result<&SelectBuffers, GpuError> {
        let ctx = self.ctx;
        ctx.submit("select dispatch", "select", |encoder| {
            self.encode(encoder, camera, params, compaction)
        })?;
        Ok(&self.out)
    }

    /// Runs one frame's selection and reads the result back. Blocks.
    pub fn run(
        &mut self,
        camera: &Camera,
        params: &Params,
        compaction: Compaction,
    ) -> Result<GpuSelection, GpuError> {
        self.dispatch(camera, params, compaction)?;
        self.out.read(self.ctx)
    }

    /// The per-batch decision codes of the last run (`DECISION_*`), for diagnostics and for
    /// naming the batches where GPU and reference disagree.
    pub fn read_decisions(&self) -> Result<Vec<u32>, GpuError> {
        read_buffer(self.ctx, &self.decisions, 0, self.batch_count as usize)
    }
}

/// `base_vertex` of command `slot`, as both compactions write it.
pub fn base_vertex_of(slot: u32) -> i32 {
    (slot << COMMAND_SHIFT) as i32
}
