//! Per-tree refinement of the selected commands on the GPU, beyond the thesis (its future work,
//! "tighter culling", E§7, on top of grouped selection, E§3.5): the driver of
//! `shaders/refine.wgsl`, twin of `reference/src/refine.rs` (`refine`, `refine_command`).
//!
//! ## Contract
//! Uploaded once per scene ([`GpuRefine::new`]): every tree's bounding sphere ([`CullTree`], the
//! reference's `tree_sphere`, computed on the CPU so both sides decide on the very same `f32`s; the
//! mesh field is not read) and an indirection buffer of `3n` entries whose last third,
//! `[2n, 3n)`, is a copy of the batch indirection of `n` trees. Per frame, after `select`
//! ([`GpuRefine::encode`]: six dispatches, below, whatever the trees and batches: constant CPU
//! work), command `i < counters.commands` of LOD `L = data[i].lod` whose batch starts at
//! `off = first_instance`:
//! - when `params.tree_cull` refines `L` (`TreeCull::refines`): keeps, **in batch order**, the
//!   trees of its batch whose own sphere is decided *Draw* with LOD `L` needed (`decide_sphere`,
//!   the selection rule, the per-tree oracle's) and whose centre passes the draw stage's per-tree
//!   draw-distance discard; writes them to `L·n + off + k` (`k = 0..`, a stable compaction) and
//!   rewrites the command to `first_instance = L·n + off`, `instance_count = kept`;
//! - otherwise points it at the copy: `first_instance = 2n + off`, count unchanged.
//!
//! The commands are rewritten **in place** in the selection's buffers, so `GpuDraw` draws them as
//! before, given `DrawInputs { indirection: Some(refine.indirection()), .. }`.
//!
//! ## Passes
//! Chunk-parallel, so that a few large batches do not serialize (one workgroup per command
//! walking its batch took 54–188 ms on llvmpipe for the stress scene's ~18k-tree batches):
//! 1. `refine_prepare` (one invocation per command slot of the [`SelectBuffers`]' capacity): the
//!    largest chunk count `ceil(len / 64)` of the refined commands;
//! 2. `refine_args` (one invocation): from it and `counters.commands`, the grid of passes 3 and 5,
//!    one invocation per (chunk of [`REFINE_WORKGROUP_SIZE`] trees, slot), copied to an
//!    indirect-argument buffer (so neither the command count nor the batch lengths need to be
//!    known on the CPU: [`GpuRefine::new`] only has the batch indirection);
//! 3. `refine_count`: each invocation tests its chunk's trees in a loop of at most 64 and stores
//!    how many it keeps in a `4n`-entry scratch buffer, at the command's own range
//!    `L·2n + 2·off ..` (at most `2·len` entries, disjoint across (batch, LOD) pairs);
//! 4. `refine_scan` (one invocation per slot): the exclusive prefix of the command's chunk
//!    counts in place, and their total;
//! 5. `refine_write`: each invocation repeats its tests in the same order and writes its kept
//!    trees from the chunk's prefix on;
//! 6. `refine_finalize` (one invocation per slot): rewrites the command and adds to the
//!    counters.
//!
//! No pass uses workgroup memory or barriers: one workgroup per chunk with a workgroup scan
//! measured 270–610 ms on the stress scene under llvmpipe, several times the serial walk it was to
//! replace (not profiled; workgroups with barriers appear to carry a high fixed cost there).
//!
//! ## Invariants
//! - Equal to the reference bit for bit (commands, the used ranges of the indirection, in order,
//!   and the counters [`RefineCounters`] = the reference's `Refined::trees_tested` /
//!   `trees_kept`), up to trees whose decision sits within ε of a threshold, where the GPU may
//!   round differently (fused multiply-add; `tests/tests/parity/refine.rs` classifies them).
//! - Commands are never removed or reordered: `counters`, `base_vertex`, the index ranges and the
//!   data stay the selection's.
//! - Encode it **once** per selection: it reads `first_instance` as the batch offset, which it
//!   overwrites. Entries of `[0, 2n)` outside the ranges of this frame's refined commands hold
//!   stale values of earlier frames (nothing reads them).
//! - With `TreeCull::None` callers do not run it (the draw reads the batch indirection); if run
//!   anyway it points every command at the copy, which draws the same trees.
//! - llvmpipe stops any shader loop after 65,535 iterations: pass 4's loop over a command's
//!   chunks runs `ceil(batch length / 64)` times, so [`GpuRefine::new`] accepts at most
//!   [`MAX_REFINE_TREES`] trees (a batch holds at most all of them); the loops over a chunk's
//!   trees (passes 3 and 5) run at most 64 times.

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use forestlod_shared::{Camera, Params, SelectCounters, ViewUniform};

use crate::context::{
    Dispatch, READ, Slot, WRITE, buffer_bind_group, compute_pass, compute_pipelines,
};
use crate::readback::{read_buffer, stage_uniform, upload_storage, zeroed_buffer};
use crate::shaders::{StageSource, WgslFile, wgsl_constants};
use crate::{CullTree, GpuContext, GpuError, GpuSelection, SelectBuffers};

/// Invocations per workgroup, and trees per chunk (generated into `refine.wgsl`'s module).
pub const REFINE_WORKGROUP_SIZE: u32 = 64;

/// The `refine` stage's module: `refine.wgsl`.
pub const SOURCE: StageSource = StageSource {
    own: WgslFile {
        name: "refine.wgsl",
        wgsl: include_str!("shaders/refine.wgsl"),
        constants: wgsl_constants![REFINE_WORKGROUP_SIZE],
    },
    parts: &[],
};

/// The most trees [`GpuRefine`] accepts: `65535 * 64`, so that no batch makes the chunk-prefix
/// loop run past llvmpipe's 65,535 iterations (module docs); 4n indices then fit a `u32` as well.
pub const MAX_REFINE_TREES: u32 = 65_535 * REFINE_WORKGROUP_SIZE;

/// The per-frame uniform of `refine.wgsl`. Keep in sync with `struct RefineUniform` there.
///
/// The shared view constants ([`ViewUniform`], the reference's `select::SelectUniform`) plus the
/// tree count, the mode and the device's per-dimension workgroup limit.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct RefineUniform {
    /// Eye, forward, frustum, fade band, draw distance, LOD levels ([`ViewUniform::new`]).
    pub view: ViewUniform,
    /// Number of trees `n` (the batch indirection's length).
    pub tree_count: u32,
    /// `forestlod_shared::TreeCull` as `u32` (`params.tree_cull`).
    pub tree_cull: u32,
    /// The device's `max_compute_workgroups_per_dimension` (caps the slot rows of the grid).
    pub max_workgroups: u32,
    /// Explicit padding.
    pub _pad0: u32,
}
const _: () = assert!(size_of::<RefineUniform>() == 176);

impl RefineUniform {
    /// The uniform for a camera and parameters ([`ViewUniform::new`], as the reference's)
    /// (`max_workgroups` is 65,535, WebGPU's default limit: [`GpuRefine::encode`] sets the
    /// device's).
    pub fn new(camera: &Camera, params: &Params, tree_count: u32) -> Self {
        Self {
            view: ViewUniform::new(camera, params),
            tree_count,
            tree_cull: params.tree_cull,
            max_workgroups: 65_535,
            _pad0: 0,
        }
    }
}

/// What `refine` counts per frame (the reference's `Refined::trees_tested` / `trees_kept`). Keep
/// in sync with `struct RefineCounters` in `refine.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct RefineCounters {
    /// Trees tested one by one: the instances of the refined commands before refinement.
    pub trees_tested: u32,
    /// Trees kept by the refined commands.
    pub trees_kept: u32,
}
const _: () = assert!(size_of::<RefineCounters>() == 8);

/// The grid of the count and write passes (`x, y, z`, an indirect dispatch's arguments) and the
/// largest chunk count it derives from (module docs). Keep in sync with `struct RefineDispatch`
/// in `refine.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct RefineDispatch {
    /// Workgroups along `x`: `ceil(max_chunks / 64)`, one invocation per chunk.
    pub x: u32,
    /// Workgroups along `y`: command slots, at most the per-dimension limit.
    pub y: u32,
    /// Workgroups along `z`: rows of `y` slots.
    pub z: u32,
    /// The largest `ceil(len / 64)` of the refined commands.
    pub max_chunks: u32,
}
const _: () = assert!(size_of::<RefineDispatch>() == 16);

/// One frame's refined selection, read back.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GpuRefined {
    /// The rewritten commands, their (unchanged) data and the selection's counters.
    pub selection: GpuSelection,
    /// The whole `3n` indirection (module docs; entries outside this frame's refined ranges and
    /// the copy are stale).
    pub indirection: Vec<u32>,
    /// Trees tested and kept.
    pub counters: RefineCounters,
}

compute_pipelines! {
    /// The compiled pipelines of `refine.wgsl` (one per pass), one set per [`GpuContext`] (cached
    /// there).
    pub struct RefinePipelines = "refine", SOURCE.module(), [
        Slot::Uniform(size_of::<RefineUniform>() as u64),
        READ, WRITE, WRITE, READ,
        Slot::Read(size_of::<SelectCounters>() as u64),
        Slot::Write(size_of::<RefineCounters>() as u64),
        WRITE,
        Slot::Write(size_of::<RefineDispatch>() as u64),
    ],
    {
        prepare: "refine_prepare",
        args: "refine_args",
        count: "refine_count",
        scan: "refine_scan",
        write: "refine_write",
        finalize: "refine_finalize",
    }
}

/// One scene's tree spheres and batch indirection on the GPU, ready to refine any selection of it
/// (module docs).
pub struct GpuRefine<'a> {
    ctx: &'a GpuContext,
    /// The stage's pipelines, from the context's cache.
    pipelines: Arc<RefinePipelines>,
    uniform: wgpu::Buffer,
    trees: wgpu::Buffer,
    indirection: wgpu::Buffer,
    counters: wgpu::Buffer,
    chunk_counts: wgpu::Buffer,
    dispatch: wgpu::Buffer,
    dispatch_args: wgpu::Buffer,
    tree_count: u32,
}

impl<'a> GpuRefine<'a> {
    /// Uploads the trees' spheres (`trees[t]` for tree `t`) and the `3n` indirection with the batch
    /// indirection (`n` tree indices) copied into `[2n, 3n)`. Fails on more than
    /// [`MAX_REFINE_TREES`] entries, on an indirection entry that names no tree, when the
    /// indirection is longer than the tree list, or when the `4n`-entry chunk scratch buffer
    /// exceeds the device's storage binding or buffer size.
    pub fn new(
        ctx: &'a GpuContext,
        trees: &[CullTree],
        batch_indirection: &[u32],
    ) -> Result<Self, GpuError> {
        let n = batch_indirection.len();
        if n > MAX_REFINE_TREES as usize {
            return Err(GpuError::Input {
                field: "batch indirection",
                value: n.to_string(),
                reason: "at most MAX_REFINE_TREES (65535 * 64) trees: a larger batch would run refine.wgsl's chunk loop past llvmpipe's 65,535 iterations",
            });
        }
        if n > trees.len() {
            return Err(GpuError::Input {
                field: "batch indirection",
                value: format!("{n} entries for {} trees", trees.len()),
                reason: "expected at most one entry per tree",
            });
        }
        if let Some((i, t)) = batch_indirection
            .iter()
            .enumerate()
            .find(|(_, t)| **t as usize >= trees.len())
        {
            return Err(GpuError::Input {
                field: "batch indirection",
                value: format!("entry {i} = tree {t} of {} trees", trees.len()),
                reason: "expected tree indices below the tree count",
            });
        }
        let chunk_bytes = 4 * n as u64 * size_of::<u32>() as u64;
        ctx.check_storage_binding(
            chunk_bytes,
            "batch indirection",
            |max_bytes| format!(
                "{n} trees: a chunk scratch buffer of 4n u32 = {chunk_bytes} bytes, over the device's {max_bytes}"
            ),
            "refine.wgsl's chunk counts must fit one storage binding",
        )?;
        let pipelines = ctx.pipelines::<RefinePipelines>()?;
        use wgpu::BufferUsages as U;
        let mut all = vec![0u32; 3 * n];
        all[2 * n..].copy_from_slice(batch_indirection);
        Ok(Self {
            ctx,
            pipelines: pipelines.clone(),
            uniform: stage_uniform::<RefineUniform>(ctx, "refine uniform"),
            trees: upload_storage(ctx, "refine trees", trees, U::empty()),
            indirection: upload_storage(ctx, "refine indirection", &all, U::empty()),
            counters: zeroed_buffer(
                ctx,
                "refine counters",
                size_of::<RefineCounters>() as u64,
                U::STORAGE | U::COPY_SRC | U::COPY_DST,
            ),
            chunk_counts: zeroed_buffer(ctx, "refine chunk counts", chunk_bytes, U::STORAGE),
            dispatch: zeroed_buffer(
                ctx,
                "refine dispatch",
                size_of::<RefineDispatch>() as u64,
                U::STORAGE | U::COPY_SRC | U::COPY_DST,
            ),
            dispatch_args: zeroed_buffer(
                ctx,
                "refine dispatch args",
                size_of::<RefineDispatch>() as u64,
                U::INDIRECT | U::COPY_DST,
            ),
            tree_count: n as u32,
        })
    }

    /// Number of trees `n` of the batch indirection.
    pub fn tree_count(&self) -> u32 {
        self.tree_count
    }

    /// The `3n` indirection the refined commands index: `DrawInputs::indirection`.
    pub fn indirection(&self) -> &wgpu::Buffer {
        &self.indirection
    }

    /// One [`RefineCounters`] (trees tested and kept by the last frame).
    pub fn counters(&self) -> &wgpu::Buffer {
        &self.counters
    }

    /// Workgroup counts `(x, y)` of the per-slot passes: one invocation per command slot of
    /// `capacity`, spilling into `y` beyond the per-dimension limit.
    fn slot_groups(&self, capacity: u32) -> (u32, u32) {
        self.ctx
            .workgroup_grid(capacity.div_ceil(REFINE_WORKGROUP_SIZE))
    }

    /// Records one frame's refinement of `selection` (written by `select` in an earlier pass or
    /// submit of the same frame) into `encoder`: writes the uniform (through the queue, so it
    /// lands before the next submit), clears the counters, then the six dispatches of the module
    /// docs (two of them indirect, sized on the GPU) in two compute passes around one copy.
    /// Rewrites the commands in place: encode it once per selection. `camera` and `params` should
    /// be validated, as for the reference.
    pub fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        selection: &mut SelectBuffers,
        camera: &Camera,
        params: &Params,
    ) {
        let uniform = RefineUniform {
            max_workgroups: self.ctx.limits.max_compute_workgroups_per_dimension,
            ..RefineUniform::new(camera, params, self.tree_count)
        };
        self.ctx
            .queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uniform));
        encoder.clear_buffer(&self.counters, 0, None);
        encoder.clear_buffer(&self.dispatch, 0, None);
        let pipelines = &self.pipelines;
        let bind_group = buffer_bind_group(
            &self.ctx.device,
            "refine",
            &pipelines.layout,
            &[
                &self.uniform,
                &self.trees,
                &self.indirection,
                &selection.commands,
                &selection.data,
                &selection.counters,
                &self.counters,
                &self.chunk_counts,
                &self.dispatch,
            ],
        );
        let (x, y) = self.slot_groups(selection.capacity);
        compute_pass(
            encoder,
            "refine grid",
            &bind_group,
            &[
                (&pipelines.prepare, Dispatch::Groups(x, y)),
                (&pipelines.args, Dispatch::Groups(1, 1)),
            ],
        );
        // The grid leaves the bound storage buffer for an INDIRECT-only one (a buffer cannot be
        // both in the same dispatch).
        encoder.copy_buffer_to_buffer(
            &self.dispatch,
            0,
            &self.dispatch_args,
            0,
            size_of::<RefineDispatch>() as u64,
        );
        let indirect = Dispatch::Indirect(&self.dispatch_args);
        compute_pass(
            encoder,
            "refine",
            &bind_group,
            &[
                (&pipelines.count, indirect),
                (&pipelines.scan, Dispatch::Groups(x, y)),
                (&pipelines.write, indirect),
                (&pipelines.finalize, Dispatch::Groups(x, y)),
            ],
        );
    }

    /// Refines `selection` for one frame and leaves the result on the GPU. Does not wait.
    pub fn dispatch(
        &mut self,
        selection: &mut SelectBuffers,
        camera: &Camera,
        params: &Params,
    ) -> Result<(), GpuError> {
        let ctx = self.ctx;
        ctx.submit("refine dispatch", "refine", |encoder| {
            self.encode(encoder, selection, camera, params)
        })
    }

    /// Reads the refined selection (`selection`, as refined by the last [`GpuRefine::encode`]),
    /// the whole `3n` indirection and the counters back. Blocks.
    pub fn read(&self, selection: &SelectBuffers) -> Result<GpuRefined, GpuError> {
        Ok(GpuRefined {
            selection: selection.read(self.ctx)?,
            indirection: read_buffer(self.ctx, &self.indirection, 0, 3 * self.tree_count as usize)?,
            counters: read_buffer::<RefineCounters>(self.ctx, &self.counters, 0, 1)?[0],
        })
    }

    /// The grid `refine_args` computed for the last [`GpuRefine::encode`] (pass 2 of the module
    /// docs: the indirect arguments of passes 3 and 5, and the largest chunk count), read back
    /// for tests: nothing else reads it on the CPU. Blocks.
    pub fn read_dispatch(&self) -> Result<RefineDispatch, GpuError> {
        Ok(read_buffer::<RefineDispatch>(self.ctx, &self.dispatch, 0, 1)?[0])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wgsl_layout::{assert_layout, assert_view_uniform, rust_layout, validate};

    /// `RefineUniform` (with its `ViewUniform`), `RefineCounters` and `RefineDispatch` have their WGSL twins' layout (naga reflection of the
    /// full `refine.wgsl` module, which also validates it; `CullTree`, in `common.wgsl`, is
    /// checked by `gpu/tests/layout.rs`).
    #[test]
    fn wgsl_layouts_match_rust() {
        let module = validate(&SOURCE.module());
        assert_layout(
            &module,
            &rust_layout!(RefineUniform {
                view,
                tree_count,
                tree_cull,
                max_workgroups,
                _pad0
            }),
        );
        assert_view_uniform(&module);
        assert_layout(
            &module,
            &rust_layout!(RefineCounters {
                trees_tested,
                trees_kept
            }),
        );
        assert_layout(
            &module,
            &rust_layout!(RefineDispatch {
                x,
                y,
                z,
                max_chunks
            }),
        );
    }

    /// The uniform is derived as the reference's `SelectUniform::new` (same fields, same order of
    /// operations), with the tree count and the mode.
    #[test]
    fn uniform_of_camera_and_params() {
        let camera = Camera::look_at([1.0, 2.0, 3.0], [50.0, 20.0, 0.0], 60.0, 64, 48);
        let params = Params {
            tree_cull: forestlod_shared::TreeCull::Lod0 as u32,
            ..Params::default()
        };
        let u = RefineUniform::new(&camera, &params, 7);
        assert_eq!(u.view, ViewUniform::new(&camera, &params));
        assert_eq!(u.view.frustum.planes, camera.frustum().planes);
        assert_eq!(u.view.forward, camera.basis().forward.to_array());
        assert_eq!(
            (u.view.fade_start, u.view.fade_end),
            (
                params.lod1_transition - params.fade_width,
                params.lod1_transition
            )
        );
        assert_eq!((u.tree_count, u.tree_cull, u.view.lod_levels), (7, 1, 2));
    }
}
