//! Occlusion culling of the selected commands on the GPU (issue 31; beyond the seeds: E§7 lists
//! finer culling as future work): the driver of `shaders/occlude.wgsl`, twin of
//! `reference/src/occlude.rs` (`occlude_early`, `occlude_late`). The frame, the formulas and why
//! the test never culls a visible tree: `forestlod_shared::occlusion`.
//!
//! ## Contract
//! Uploaded once per scene ([`GpuOcclude::new`]): every tree's footprint sphere (base position
//! and `reference::draw::tree_footprint_radius`, computed on the CPU so both twins test the very
//! same `f32`s) and a per-tree history of two halves (the previous frame's "passed the test" and
//! this frame's). Per frame, over the frame's commands (after every selection stage) and their
//! indirection of `m` entries:
//! - [`GpuOcclude::encode_early`] copies the indirection to `[4m, 5m)` of a `5m` buffer and the
//!   commands into the early command buffer, then writes, per command, its occluders
//!   (`is_occluder` under `effective_mode`, `single` counting from `nearest_occluder_depth`) in
//!   list order at `occlusion_slot(0, lod, m, first_instance)` and rewrites the
//!   early commands to point there;
//! - [`GpuOcclude::encode_late`], after the early draw and the [`GpuPyramid`] of its depth, tests
//!   the trees against the pyramid (under `single` the early ones are drawn, not tested), writes
//!   those that pass and were not drawn early at `occlusion_slot(1, ..)`, rewrites the late
//!   command buffer, counts ([`OcclusionCounters`]) and marks every tree that passed in this
//!   frame's history half; the halves then swap, so the next frame's `two-phase` early pass
//!   reads it.
//!
//! Six dispatches a phase (seven in the early one: `single`'s nearest occluder depth, a
//! min-reduction both phases read), as `refine` (count, scan, write over chunks of
//! [`OCCLUDE_WORKGROUP_SIZE`] trees: a few large commands do not serialize, and no loop runs past
//! llvmpipe's 65,535 iterations for up to [`MAX_OCCLUDE_TREES`] trees in a command). The early and
//! late selections are [`SelectBuffers`] sharing the frame's data and counters
//! ([`GpuOcclude::early_buffers`], [`GpuOcclude::late_buffers`]); the draw binds
//! [`GpuOcclude::indirection`].
//!
//! ## Invariants
//! - Equal to the reference (the early and late commands, the used ranges of the `4m` lists in
//!   order, the counters and the history) up to trees whose late decision sits within a few ulps
//!   of a threshold (the projection's division and a fused multiply-add may round differently):
//!   `tests/tests/parity/occlusion.rs` counts them under a budget.
//! - Commands are never removed or reordered; base_vertex, index ranges and data are the frame's.
//! - [`GpuOcclude::reset_history`] starts a path: the next frame's `two-phase` early pass is empty
//!   (the reference's `visible_before` of none).

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use forestlod_shared::{
    Camera, DrawCommand, MAX_PYRAMID_LEVELS, OcclusionCounters, Params, SelectCounters,
    effective_mode,
};

use crate::context::{
    Dispatch, READ, Slot, WRITE, buffer_bind_group, compute_pass, compute_pipelines,
};
use crate::pyramid::{GpuPyramid, level_vec};
use crate::readback::{read_buffer, stage_uniform, upload_storage, zeroed_buffer};
use crate::shaders::{StageSource, WgslFile, wgsl_constants};
use crate::{GpuContext, GpuError, GpuSelection, SelectBuffers};

/// Invocations per workgroup, and trees per chunk (generated into `occlude.wgsl`'s module).
pub const OCCLUDE_WORKGROUP_SIZE: u32 = 64;

/// The most trees one command may list: `65535 * 64`, so that the chunk-prefix loop stays within
/// llvmpipe's 65,535 iterations (module docs). [`GpuOcclude::new`] accepts at most this many
/// trees (a command lists each tree at most once).
pub const MAX_OCCLUDE_TREES: u32 = 65_535 * OCCLUDE_WORKGROUP_SIZE;

/// The `occlude` stage's module: `occlude.wgsl`.
pub const SOURCE: StageSource = StageSource {
    own: WgslFile {
        name: "occlude.wgsl",
        wgsl: include_str!("shaders/occlude.wgsl"),
        constants: wgsl_constants![OCCLUDE_WORKGROUP_SIZE],
    },
    parts: &[],
};

/// The per-phase uniform of `occlude.wgsl`. Keep in sync with `struct OccludeUniform` there.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct OccludeUniform {
    /// `camera.view_projection()`, column-major (the reference's projection).
    pub view_proj: [[f32; 4]; 4],
    /// The pyramid's levels, `(width, height, offset, 0)`; `level_count` are used.
    pub levels: [[u32; 4]; MAX_PYRAMID_LEVELS as usize],
    /// `camera.eye`.
    pub eye: [f32; 3],
    /// `camera.near`.
    pub near: f32,
    /// `camera.basis().forward` (unit).
    pub forward: [f32; 3],
    /// `params.occluder_depth`.
    pub occluder_depth: f32,
    /// `forestlod_shared::effective_mode` of `params.occlusion` (the driver sets it: it knows
    /// whether a history exists).
    pub mode: u32,
    /// 0 early, 1 late.
    pub phase: u32,
    /// Entries `m` of the frame's indirection.
    pub m: u32,
    /// Trees `n` (footprints, each history half).
    pub tree_count: u32,
    /// `params.fade_mode`.
    pub fade_mode: u32,
    /// `params.subset_mode`.
    pub subset_mode: u32,
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
    /// Pyramid levels.
    pub level_count: u32,
    /// Where the previous frame's history half starts (0 or `n`).
    pub history_read: u32,
    /// Where this frame's history half starts (`n` or 0).
    pub history_write: u32,
    /// The device's `max_compute_workgroups_per_dimension`.
    pub max_workgroups: u32,
    /// 1 when the final pass's lists hold the early trees too
    /// (`forestlod_shared::final_includes_early` of `params.occlusion_order`), else 0.
    pub final_with_early: u32,
    /// Explicit padding.
    pub _pad0: u32,
    /// Explicit padding.
    pub _pad1: u32,
    /// Explicit padding.
    pub _pad2: u32,
}
const _: () = assert!(size_of::<OccludeUniform>() == 416);

impl OccludeUniform {
    /// The uniform of one phase (`history_read` 0, `max_workgroups` 65,535: the driver sets
    /// both).
    pub fn new(camera: &Camera, params: &Params, phase: u32, m: u32, tree_count: u32) -> Self {
        let levels = forestlod_shared::pyramid_levels(camera.width.max(1), camera.height.max(1));
        let mut table = [[0u32; 4]; MAX_PYRAMID_LEVELS as usize];
        for (slot, l) in table.iter_mut().zip(&levels) {
            *slot = level_vec(*l);
        }
        Self {
            view_proj: camera.view_projection().to_cols_array_2d(),
            levels: table,
            eye: camera.eye,
            near: camera.near,
            forward: camera.basis().forward.to_array(),
            occluder_depth: params.occluder_depth,
            mode: params.occlusion,
            phase,
            m,
            tree_count,
            fade_mode: params.fade_mode,
            subset_mode: params.subset_mode,
            width: camera.width,
            height: camera.height,
            level_count: levels.len().min(MAX_PYRAMID_LEVELS as usize) as u32,
            history_read: 0,
            history_write: tree_count,
            max_workgroups: 65_535,
            final_with_early: forestlod_shared::final_includes_early(params.occlusion_order) as u32,
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
        }
    }
}

/// The grid of the count and write passes and the largest chunk count. Keep in sync with
/// `struct OccludeDispatch` in `occlude.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct OccludeDispatch {
    /// Workgroups along `x`: `ceil(max_chunks / 64)`.
    pub x: u32,
    /// Workgroups along `y`: command slots, at most the per-dimension limit.
    pub y: u32,
    /// Workgroups along `z`: rows of `y` slots.
    pub z: u32,
    /// The largest `ceil(len / 64)` of the commands.
    pub max_chunks: u32,
}

/// The stage's state buffer: the frame's counters, the phase's grid and `single`'s nearest
/// occluder depth. Keep in sync with `struct OccludeState` in `occlude.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct OccludeState {
    /// The frame's counters (both phases).
    pub counters: OcclusionCounters,
    /// The current phase's grid.
    pub dispatch: OccludeDispatch,
    /// `forestlod_shared::nearest_occluder_depth` of the frame, as `0x7f800000 - bits` (0: none;
    /// the shader's encoding, so that an atomic maximum is the minimum depth).
    pub nearest: u32,
    /// Explicit padding.
    pub _pad0: u32,
    /// Explicit padding.
    pub _pad1: u32,
    /// Explicit padding.
    pub _pad2: u32,
}
const _: () = assert!(size_of::<OccludeState>() == 64);

/// One frame's occlusion culling, read back.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GpuOccluded {
    /// The early commands (data and counters: the frame's).
    pub early: GpuSelection,
    /// The late commands.
    pub late: GpuSelection,
    /// The `4m` lists (entries outside this frame's ranges are stale).
    pub indirection: Vec<u32>,
    /// The frame's counters.
    pub counters: OcclusionCounters,
    /// Per tree, 1 when it passed this frame's test (the next frame's history).
    pub visible: Vec<u32>,
}

compute_pipelines! {
    /// The compiled pipelines of `occlude.wgsl` (one per pass), one set per [`GpuContext`].
    pub struct OccludePipelines = "occlude", SOURCE.module(), [
        Slot::Uniform(size_of::<OccludeUniform>() as u64),
        READ, WRITE, WRITE, READ,
        Slot::Read(size_of::<SelectCounters>() as u64),
        Slot::Write(size_of::<OccludeState>() as u64),
        WRITE, READ, WRITE,
    ],
    {
        prepare: "occlude_prepare",
        args: "occlude_args",
        nearest: "occlude_nearest",
        count: "occlude_count",
        scan: "occlude_scan",
        write: "occlude_write",
        finalize: "occlude_finalize",
    }
}

/// The buffers sized by the frame's indirection (`m`) and command capacity.
struct Lists {
    m: u32,
    capacity: u32,
    /// `5m`: the early and late lists, then the frame's indirection.
    indirection: wgpu::Buffer,
    /// `4m` chunk counts and prefixes.
    chunk_counts: wgpu::Buffer,
    /// The early and late command buffers.
    commands: [wgpu::Buffer; 2],
}

/// One scene's footprints and history on the GPU (module docs).
pub struct GpuOcclude<'a> {
    ctx: &'a GpuContext,
    pipelines: Arc<OccludePipelines>,
    uniforms: [wgpu::Buffer; 2],
    footprints: wgpu::Buffer,
    history: wgpu::Buffer,
    /// Which half the next frame reads: 0 (`[0, n)`) or 1 (`[n, 2n)`).
    history_half: u32,
    /// Clear both halves at the next early phase (a new path).
    clear_history: bool,
    /// Whether the half the next frame reads was written by a frame of this path (the
    /// reference's non-empty `visible_before`).
    has_history: bool,
    state: wgpu::Buffer,
    dispatch_args: wgpu::Buffer,
    lists: Option<Lists>,
    tree_count: u32,
}

impl<'a> GpuOcclude<'a> {
    /// Uploads the trees' footprint spheres (`[x, y, z, radius]` for tree `t`) and a zeroed
    /// history. Fails on more than [`MAX_OCCLUDE_TREES`] trees or a non-finite footprint radius
    /// below zero (the test would be meaningless).
    pub fn new(ctx: &'a GpuContext, footprints: &[[f32; 4]]) -> Result<Self, GpuError> {
        let n = footprints.len();
        if n > MAX_OCCLUDE_TREES as usize {
            return Err(GpuError::Input {
                field: "footprints",
                value: n.to_string(),
                reason: "at most MAX_OCCLUDE_TREES (65535 * 64) trees: a larger command would run occlude.wgsl's chunk loop past llvmpipe's 65,535 iterations",
            });
        }
        if let Some((t, f)) = footprints.iter().enumerate().find(|(_, f)| f[3] < 0.0) {
            return Err(GpuError::Input {
                field: "footprints",
                value: format!("tree {t}: radius {}", f[3]),
                reason: "expected a footprint radius of at least 0",
            });
        }
        let pipelines = ctx.pipelines::<OccludePipelines>()?;
        use wgpu::BufferUsages as U;
        Ok(Self {
            ctx,
            pipelines,
            uniforms: [
                stage_uniform::<OccludeUniform>(ctx, "occlude uniform (early)"),
                stage_uniform::<OccludeUniform>(ctx, "occlude uniform (late)"),
            ],
            footprints: upload_storage(ctx, "occlude footprints", footprints, U::empty()),
            history: zeroed_buffer(
                ctx,
                "occlude history",
                2 * 4 * n as u64,
                U::STORAGE | U::COPY_SRC | U::COPY_DST,
            ),
            history_half: 0,
            clear_history: true,
            has_history: false,
            state: zeroed_buffer(
                ctx,
                "occlude state",
                size_of::<OccludeState>() as u64,
                U::STORAGE | U::COPY_SRC | U::COPY_DST,
            ),
            dispatch_args: zeroed_buffer(
                ctx,
                "occlude dispatch args",
                size_of::<OccludeDispatch>() as u64,
                U::INDIRECT | U::COPY_DST,
            ),
            lists: None,
            tree_count: n as u32,
        })
    }

    /// Trees `n`.
    pub fn tree_count(&self) -> u32 {
        self.tree_count
    }

    /// Forgets the history: the next frame starts a path (its `two-phase` early pass is empty).
    pub fn reset_history(&mut self) {
        self.clear_history = true;
        self.has_history = false;
    }

    /// The `5m` buffer the early and late commands index (`DrawInputs::indirection`). Panics
    /// before the first [`GpuOcclude::encode_early`].
    pub fn indirection(&self) -> &wgpu::Buffer {
        &self.lists.as_ref().expect("encode_early ran").indirection
    }

    /// The frame's counters and grid ([`OccludeState`]: the counters are its first 32 bytes).
    pub fn state(&self) -> &wgpu::Buffer {
        &self.state
    }

    /// The early (`phase` 0) or late (1) selection: the phase's commands with the frame's data
    /// and counters. Panics before the first [`GpuOcclude::encode_early`].
    fn phase_buffers(&self, selection: &SelectBuffers, phase: usize) -> SelectBuffers {
        let lists = self.lists.as_ref().expect("encode_early ran");
        SelectBuffers {
            commands: lists.commands[phase].clone(),
            data: selection.data.clone(),
            counters: selection.counters.clone(),
            capacity: selection.capacity,
        }
    }

    /// The early selection over [`GpuOcclude::indirection`] (module docs).
    pub fn early_buffers(&self, selection: &SelectBuffers) -> SelectBuffers {
        self.phase_buffers(selection, 0)
    }

    /// The late selection over [`GpuOcclude::indirection`] (module docs).
    pub fn late_buffers(&self, selection: &SelectBuffers) -> SelectBuffers {
        self.phase_buffers(selection, 1)
    }

    /// (Re)creates the per-frame buffers when `m` or the capacity changed.
    fn ensure_lists(&mut self, m: u32, capacity: u32) -> Result<(), GpuError> {
        if let Some(l) = &self.lists
            && l.m == m
            && l.capacity == capacity
        {
            return Ok(());
        }
        let bytes = 5 * 4 * u64::from(m);
        self.ctx.check_storage_binding(
            bytes,
            "indirection length",
            |max| {
                format!("{m} entries: a 5m list buffer of {bytes} bytes, over the device's {max}")
            },
            "occlude.wgsl's lists must fit one storage binding",
        )?;
        use wgpu::BufferUsages as U;
        let commands = |label| {
            zeroed_buffer(
                self.ctx,
                label,
                u64::from(capacity) * size_of::<DrawCommand>() as u64,
                U::STORAGE | U::INDIRECT | U::COPY_SRC | U::COPY_DST,
            )
        };
        self.lists = Some(Lists {
            m,
            capacity,
            indirection: zeroed_buffer(
                self.ctx,
                "occlude lists",
                bytes,
                U::STORAGE | U::COPY_SRC | U::COPY_DST,
            ),
            chunk_counts: zeroed_buffer(
                self.ctx,
                "occlude chunk counts",
                4 * 4 * u64::from(m),
                U::STORAGE,
            ),
            commands: [
                commands("occlude early commands"),
                commands("occlude late commands"),
            ],
        });
        Ok(())
    }

    /// Records one phase's six dispatches (module docs) over `selection`'s commands copied into
    /// the phase's command buffer.
    fn encode_phase(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        selection: &SelectBuffers,
        uniform: &OccludeUniform,
        pyramid: &wgpu::Buffer,
    ) {
        let phase = uniform.phase as usize;
        let lists = self.lists.as_ref().expect("ensure_lists ran");
        self.ctx
            .queue
            .write_buffer(&self.uniforms[phase], 0, bytemuck::bytes_of(uniform));
        encoder.copy_buffer_to_buffer(
            &selection.commands,
            0,
            &lists.commands[phase],
            0,
            u64::from(selection.capacity) * size_of::<DrawCommand>() as u64,
        );
        let grid_at = size_of::<OcclusionCounters>() as u64;
        let grid_size = size_of::<OccludeDispatch>() as u64;
        encoder.clear_buffer(&self.state, grid_at, Some(grid_size));
        let pipelines = &self.pipelines;
        let bind_group = buffer_bind_group(
            &self.ctx.device,
            "occlude",
            &pipelines.layout,
            &[
                &self.uniforms[phase],
                &self.footprints,
                &lists.indirection,
                &lists.commands[phase],
                &selection.data,
                &selection.counters,
                &self.state,
                &lists.chunk_counts,
                pyramid,
                &self.history,
            ],
        );
        let (x, y) = self
            .ctx
            .workgroup_grid(selection.capacity.div_ceil(OCCLUDE_WORKGROUP_SIZE));
        compute_pass(
            encoder,
            "occlude grid",
            &bind_group,
            &[
                (&pipelines.prepare, Dispatch::Groups(x, y)),
                (&pipelines.args, Dispatch::Groups(1, 1)),
            ],
        );
        encoder.copy_buffer_to_buffer(
            &self.state,
            grid_at,
            &self.dispatch_args,
            0,
            size_of::<OccludeDispatch>() as u64,
        );
        let indirect = Dispatch::Indirect(&self.dispatch_args);
        if phase == 0 {
            // `single`'s nearest occluder depth, read by both phases' early rule.
            compute_pass(
                encoder,
                "occlude nearest",
                &bind_group,
                &[(&pipelines.nearest, indirect)],
            );
        }
        compute_pass(
            encoder,
            if phase == 0 {
                "occlude early"
            } else {
                "occlude late"
            },
            &bind_group,
            &[
                (&pipelines.count, indirect),
                (&pipelines.scan, Dispatch::Groups(x, y)),
                (&pipelines.write, indirect),
                (&pipelines.finalize, Dispatch::Groups(x, y)),
            ],
        );
    }

    /// The uniform of `phase` for this frame, with the driver's history halves and limits.
    fn uniform(&self, camera: &Camera, params: &Params, phase: u32, m: u32) -> OccludeUniform {
        let n = self.tree_count;
        let read = self.history_half * n;
        OccludeUniform {
            mode: effective_mode(params.occlusion, self.has_history),
            history_read: read,
            history_write: n - read,
            max_workgroups: self.ctx.limits.max_compute_workgroups_per_dimension,
            ..OccludeUniform::new(camera, params, phase, m, n)
        }
    }

    /// Records the early phase (module docs) of `selection` (the frame's commands, written in an
    /// earlier pass or submit) over `input`, the indirection of `m` entries its commands index.
    /// Clears the frame's counters. `camera` and `params` should be validated.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_early(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        selection: &SelectBuffers,
        input: &wgpu::Buffer,
        m: u32,
        camera: &Camera,
        params: &Params,
    ) -> Result<(), GpuError> {
        if u64::from(m) * 4 > input.size() {
            return Err(GpuError::Input {
                field: "indirection length",
                value: format!("{m} entries in a buffer of {} bytes", input.size()),
                reason: "expected at most the buffer's entries",
            });
        }
        self.ensure_lists(m, selection.capacity)?;
        if self.clear_history {
            encoder.clear_buffer(&self.history, 0, None);
            self.clear_history = false;
        }
        encoder.clear_buffer(&self.state, 0, None);
        let lists = self.lists.as_ref().expect("ensured above");
        if m > 0 {
            encoder.copy_buffer_to_buffer(
                input,
                0,
                &lists.indirection,
                4 * 4 * u64::from(m),
                4 * u64::from(m),
            );
        }
        let uniform = self.uniform(camera, params, 0, m);
        // The early phase reads no pyramid: bind the footprints in its place (read-only).
        self.encode_phase(encoder, selection, &uniform, &self.footprints);
        Ok(())
    }

    /// Records the late phase (module docs) after [`GpuOcclude::encode_early`] of the same frame
    /// and the [`GpuPyramid`] of the early pass's depth, and swaps the history halves.
    pub fn encode_late(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        selection: &SelectBuffers,
        pyramid: &GpuPyramid,
        camera: &Camera,
        params: &Params,
    ) -> Result<(), GpuError> {
        if pyramid.size() != (camera.width, camera.height) {
            return Err(GpuError::Input {
                field: "pyramid size",
                value: format!(
                    "{:?} for a {}x{} camera",
                    pyramid.size(),
                    camera.width,
                    camera.height
                ),
                reason: "expected the pyramid of the camera's target",
            });
        }
        let m = self.lists.as_ref().expect("encode_early ran").m;
        let uniform = self.uniform(camera, params, 1, m);
        let n = u64::from(self.tree_count) * 4;
        if n > 0 {
            encoder.clear_buffer(&self.history, u64::from(uniform.history_write) * 4, Some(n));
        }
        self.encode_phase(encoder, selection, &uniform, pyramid.texels());
        self.history_half = 1 - self.history_half;
        self.has_history = true;
        Ok(())
    }

    /// Reads the last frame back: the early and late commands, the `4m` lists, the counters and
    /// the history half the last [`GpuOcclude::encode_late`] wrote. Blocks.
    pub fn read(&self, selection: &SelectBuffers) -> Result<GpuOccluded, GpuError> {
        let lists = self.lists.as_ref().expect("encode_early ran");
        let n = self.tree_count as usize;
        // After the swap, the half the next frame reads is the one the last frame wrote.
        let written = self.history_half as usize * n;
        let history = read_buffer::<u32>(self.ctx, &self.history, 0, 2 * n)?;
        Ok(GpuOccluded {
            early: self.early_buffers(selection).read(self.ctx)?,
            late: self.late_buffers(selection).read(self.ctx)?,
            indirection: read_buffer(self.ctx, &lists.indirection, 0, 4 * lists.m as usize)?,
            counters: read_buffer::<OcclusionCounters>(self.ctx, &self.state, 0, 1)?[0],
            visible: history[written..written + n].to_vec(),
        })
    }

    /// The frame's counters alone. Blocks.
    pub fn read_counters(&self) -> Result<OcclusionCounters, GpuError> {
        Ok(read_buffer::<OcclusionCounters>(self.ctx, &self.state, 0, 1)?[0])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wgsl_layout::{assert_layout, rust_layout, validate};

    /// `OccludeUniform`, `OccludeDispatch` and `OccludeState` have their WGSL twins' layout
    /// (naga reflection of the full module, which also validates it).
    #[test]
    fn wgsl_layouts_match_rust() {
        let module = validate(&SOURCE.module());
        assert_layout(
            &module,
            &rust_layout!(OccludeUniform {
                view_proj,
                levels,
                eye,
                near,
                forward,
                occluder_depth,
                mode,
                phase,
                m,
                tree_count,
                fade_mode,
                subset_mode,
                width,
                height,
                level_count,
                history_read,
                history_write,
                max_workgroups,
                final_with_early,
                _pad0,
                _pad1,
                _pad2
            }),
        );
        assert_layout(
            &module,
            &rust_layout!(OccludeDispatch {
                x,
                y,
                z,
                max_chunks
            }),
        );
        assert_layout(
            &module,
            &rust_layout!(OccludeState {
                counters,
                dispatch,
                nearest,
                _pad0,
                _pad1,
                _pad2
            }),
        );
    }

    /// The uniform carries the camera's projection, eye and unit forward, the pyramid's levels of
    /// the camera's size and the parameters the stage reads.
    #[test]
    fn uniform_of_camera_and_params() {
        let camera = Camera::look_at([1.0, 2.0, 3.0], [50.0, 20.0, 0.0], 60.0, 5, 3);
        let params = Params {
            occlusion: forestlod_shared::Occlusion::TwoPhase as u32,
            occluder_depth: 42.0,
            ..Params::default()
        };
        let u = OccludeUniform::new(&camera, &params, 1, 9, 4);
        assert_eq!(u.view_proj, camera.view_projection().to_cols_array_2d());
        assert_eq!(u.forward, camera.basis().forward.to_array());
        assert_eq!((u.level_count, u.width, u.height), (4, 5, 3));
        assert_eq!(u.levels[1], [3, 2, 15, 0]);
        assert_eq!(u.levels[3], [1, 1, 23, 0]);
        assert_eq!((u.mode, u.phase, u.m, u.tree_count), (2, 1, 9, 4));
        assert_eq!(u.occluder_depth, 42.0);
    }
}
