//! Per-tree culling and compaction of the two baselines of E§5 (SPEC §9) on the GPU: the driver of
//! `shaders/cull.wgsl`, twin of the reference's `baselines::visible_trees` (that is,
//! `select::select_per_tree`) and of Vegetation's compaction (`baselines::vegetation_commands`).
//!
//! ## Contract
//! Uploaded once per scene: every tree's bounding sphere (the reference's `baselines::tree_spheres`,
//! computed on the CPU so both sides decide on the very same `f32`s) and mesh index ([`CullTree`]),
//! and the meshes' packed index ranges ([`MeshMeta`]). Per frame, three dispatches whatever the
//! tree count ([`GpuCull::encode`]):
//! 1. per tree, the reference's `SelectUniform::decide` on the tree's own sphere (draw distance on
//!    the interval's near end, then the six frustum planes; `common.wgsl` `decide_sphere`, the
//!    very function `select.wgsl` runs per batch) plus the draw stage's per-tree draw-distance
//!    discard (`tree_within_draw_distance`, E§4.4); a visible tree reserves a slot within its mesh
//!    with one `atomicAdd`;
//! 2. one invocation over the meshes (at most [`MAX_CULL_MESHES`]): one `DrawCommand` and
//!    `CommandData` per mesh with visible trees, exactly as `render_vegetation` builds them (LOD0,
//!    `fading` 0, `billboard` 0, `fade_start`/`fade_end` of the uniform, `batch` 0,
//!    `base_vertex = i << COMMAND_SHIFT`, `first_instance` = the sum of the counts of the meshes
//!    before it), the counters and the Primitive's [`DrawIndirectArgs`]
//!    `{6, visible trees, 0, 0}`;
//! 3. per visible tree, its index into the compacted indirection buffer at its mesh's offset plus
//!    its slot.
//!
//! **Order.** Meshes, and so commands, come in mesh order, as in the reference. Within one mesh the
//! trees come in the order their invocations won the `atomicAdd`, which is arbitrary (the
//! reference's is ascending): each command's range of the indirection holds exactly the reference's
//! trees, as a set. Only the draw order of one mesh's trees differs, which changes a pixel only
//! where two trees' fragments tie exactly in depth. [`GpuCull::read_visible`] sorts.
//!
//! **Outputs.** [`GpuCull::buffers`] is a [`SelectBuffers`] (capacity: the mesh count) that
//! `GpuDraw` draws as it draws `select`'s output, given [`GpuCull::indirection`] as
//! `DrawInputs::indirection`: that is Vegetation on the GPU. The counters are
//! `SelectCounters`-compatible: `batches_tested` = trees tested, `commands` (at
//! [`SelectBuffers::COUNT_OFFSET`]) = `lod0_commands` = meshes with visible trees, `instances` =
//! visible trees; the culled counts stay 0 (they would cost an atomic per culled tree).
//! [`GpuCull::draw_args`] feeds the Primitive's one `draw_indirect` (`primitive.rs`).

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use forestlod_shared::{Camera, MeshMeta, Params, SelectCounters, ViewUniform};

use crate::context::{
    Dispatch, READ, Slot, WRITE, buffer_bind_group, compute_pass, compute_pipelines,
};
use crate::readback::{read_buffer, stage_uniform, upload_storage, zeroed_buffer};
use crate::select::check_mesh_indices;
use crate::shaders::{StageSource, WgslFile, wgsl_constants};
use crate::{GpuContext, GpuError, SelectBuffers};

/// Invocations per workgroup of the per-tree passes (generated into `cull.wgsl`'s module).
pub const CULL_WORKGROUP_SIZE: u32 = 64;

/// The `cull` stage's module: `cull.wgsl`.
pub const SOURCE: StageSource = StageSource {
    own: WgslFile {
        name: "cull.wgsl",
        wgsl: include_str!("shaders/cull.wgsl"),
        constants: wgsl_constants![CULL_WORKGROUP_SIZE],
    },
    parts: &[],
};

/// The most meshes [`GpuCull`] accepts: its command pass is one invocation looping over the meshes
/// (llvmpipe stops any shader loop after 65,535 iterations, and a loop must not grow with the
/// input anyway); the thesis's scenes have a handful of species.
pub const MAX_CULL_MESHES: u32 = 4096;

/// Storage buffers `cull.wgsl` binds in the compute stage.
const STORAGE_BUFFERS: u32 = 9;

/// One tree as the cull and refine passes read it. Keep in sync with `struct CullTree` in
/// `common.wgsl` (`gpu/tests/layout.rs` checks the layout).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct CullTree {
    /// Bounding-sphere centre (the reference's `scene::tree_sphere`).
    pub center: [f32; 3],
    /// Bounding-sphere radius.
    pub radius: f32,
    /// Mesh index.
    pub mesh: u32,
    /// The tree's scale (`Instance::scale`): what a scaled LOD metric scales the band of the
    /// tree's command by (`refine.wgsl`, issue 29).
    pub scale: f32,
}
const _: () = assert!(size_of::<CullTree>() == 24);

/// `wgpu::util::DrawIndirectArgs` (`VkDrawIndirectCommand`), field for field. Keep in sync with
/// `struct DrawIndirectArgs` in `cull.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct DrawIndirectArgs {
    /// Vertices per instance (6: one quad).
    pub vertex_count: u32,
    /// Instances (visible trees).
    pub instance_count: u32,
    /// First vertex (0).
    pub first_vertex: u32,
    /// First instance (0).
    pub first_instance: u32,
}
const _: () = assert!(size_of::<DrawIndirectArgs>() == 16);

/// The per-frame uniform of `cull.wgsl`. Keep in sync with `struct CullUniform` there.
///
/// The shared view constants ([`ViewUniform`], the reference's `select::SelectUniform`) plus the
/// sizes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct CullUniform {
    /// Eye, forward, frustum, fade band, draw distance, LOD levels ([`ViewUniform::new`]).
    pub view: ViewUniform,
    /// Number of trees.
    pub tree_count: u32,
    /// Number of meshes.
    pub mesh_count: u32,
    /// Explicit padding.
    pub _pad0: u32,
    /// Explicit padding.
    pub _pad1: u32,
}
const _: () = assert!(size_of::<CullUniform>() == 176);

impl CullUniform {
    /// The uniform for a camera and parameters ([`ViewUniform::new`], as the reference's).
    pub fn new(camera: &Camera, params: &Params, tree_count: u32, mesh_count: u32) -> Self {
        Self {
            view: ViewUniform::new(camera, params),
            tree_count,
            mesh_count,
            _pad0: 0,
            _pad1: 0,
        }
    }
}

/// One frame's cull output, read back.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GpuCulled {
    /// Commands and data (one per mesh with visible trees) and counters.
    pub selection: crate::GpuSelection,
    /// The compacted indirection, `counters.instances` tree indices, mesh by mesh (arbitrary
    /// order within a mesh).
    pub indirection: Vec<u32>,
    /// The Primitive's indirect arguments.
    pub draw_args: DrawIndirectArgs,
}

compute_pipelines! {
    /// The compiled pipelines of `cull.wgsl` (its three passes), one set per [`GpuContext`]
    /// (cached there).
    pub struct CullPipelines = "cull", SOURCE.module(), [
        Slot::Uniform(size_of::<CullUniform>() as u64),
        READ, READ, WRITE, WRITE, WRITE, WRITE, WRITE,
        Slot::Write(size_of::<SelectCounters>() as u64),
        Slot::Write(size_of::<DrawIndirectArgs>() as u64),
    ],
    { count: "cull_count", commands: "cull_commands", scatter: "cull_scatter" }
}

/// One scene's trees on the GPU, ready to cull for any camera and parameters (module docs).
pub struct GpuCull<'a> {
    ctx: &'a GpuContext,
    /// The stage's pipelines, from the context's cache.
    pipelines: Arc<CullPipelines>,
    uniform: wgpu::Buffer,
    mesh_counts: wgpu::Buffer,
    indirection: wgpu::Buffer,
    draw_args: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    out: SelectBuffers,
    tree_count: u32,
    mesh_count: u32,
}

impl<'a> GpuCull<'a> {
    /// Uploads the trees and meshes (`meshes` with their packed index ranges, as the reference's
    /// `pack_geometry` gives them). Fails on a tree whose mesh is out of range, on more than
    /// [`MAX_CULL_MESHES`] meshes, or on an adapter with fewer than 9 storage buffers per stage.
    pub fn new(
        ctx: &'a GpuContext,
        trees: &[CullTree],
        meshes: &[MeshMeta],
    ) -> Result<Self, GpuError> {
        check_mesh_indices(
            "tree.mesh",
            "tree",
            trees.iter().map(|t| t.mesh),
            meshes.len(),
        )?;
        if meshes.len() > MAX_CULL_MESHES as usize {
            return Err(GpuError::Input {
                field: "meshes",
                value: meshes.len().to_string(),
                reason: "the cull pass loops over the meshes in one invocation: at most MAX_CULL_MESHES (4096)",
            });
        }
        if trees.len() >= u32::MAX as usize {
            return Err(GpuError::Input {
                field: "trees",
                value: trees.len().to_string(),
                reason: "expected fewer than 2^32 - 1 trees (tree indices are u32)",
            });
        }
        if ctx.limits.max_storage_buffers_per_shader_stage < STORAGE_BUFFERS {
            return Err(GpuError::Input {
                field: "adapter limits",
                value: format!(
                    "{} storage buffers per shader stage",
                    ctx.limits.max_storage_buffers_per_shader_stage
                ),
                reason: "cull.wgsl binds 9 storage buffers in its compute stage",
            });
        }
        let pipelines = ctx.pipelines::<CullPipelines>()?;
        use wgpu::BufferUsages as U;
        let n = trees.len() as u64;
        let tree_buffer = upload_storage(ctx, "cull trees", trees, U::empty());
        let mesh_buffer = upload_storage(ctx, "cull meshes", meshes, U::empty());
        let uniform = stage_uniform::<CullUniform>(ctx, "cull uniform");
        let mesh_counts = zeroed_buffer(
            ctx,
            "cull mesh counts",
            meshes.len() as u64 * 4,
            U::STORAGE | U::COPY_SRC | U::COPY_DST,
        );
        let slots = zeroed_buffer(ctx, "cull slots", n * 4, U::STORAGE);
        let indirection = zeroed_buffer(
            ctx,
            "cull indirection",
            n * 4,
            U::STORAGE | U::COPY_SRC | U::COPY_DST,
        );
        let draw_args = zeroed_buffer(
            ctx,
            "cull draw args",
            size_of::<DrawIndirectArgs>() as u64,
            U::STORAGE | U::INDIRECT | U::COPY_SRC | U::COPY_DST,
        );
        let out = SelectBuffers::with_capacity(ctx, meshes.len() as u32);
        let bind_group = ctx.checked("cull bind group", || {
            buffer_bind_group(
                &ctx.device,
                "cull",
                &pipelines.layout,
                &[
                    &uniform,
                    &tree_buffer,
                    &mesh_buffer,
                    &mesh_counts,
                    &slots,
                    &indirection,
                    &out.commands,
                    &out.data,
                    &out.counters,
                    &draw_args,
                ],
            )
        })?;
        Ok(Self {
            ctx,
            pipelines: pipelines.clone(),
            uniform,
            mesh_counts,
            indirection,
            draw_args,
            bind_group,
            out,
            tree_count: trees.len() as u32,
            mesh_count: meshes.len() as u32,
        })
    }

    /// Number of trees.
    pub fn tree_count(&self) -> u32 {
        self.tree_count
    }

    /// Commands, data and counters for `GpuDraw` (valid after [`GpuCull::encode`] has run).
    pub fn buffers(&self) -> &SelectBuffers {
        &self.out
    }

    /// The compacted indirection (tree indices, mesh by mesh): `DrawInputs::indirection` for
    /// Vegetation, the instance list of the Primitive's quads.
    pub fn indirection(&self) -> &wgpu::Buffer {
        &self.indirection
    }

    /// One [`DrawIndirectArgs`] `{6, visible trees, 0, 0}`: the Primitive's `draw_indirect`.
    pub fn draw_args(&self) -> &wgpu::Buffer {
        &self.draw_args
    }

    /// Workgroup counts `(x, y)` covering every tree with `CULL_WORKGROUP_SIZE` invocations each,
    /// spilling into `y` beyond the per-dimension limit.
    fn groups(&self) -> (u32, u32) {
        let groups = self.tree_count.div_ceil(CULL_WORKGROUP_SIZE);
        self.ctx.workgroup_grid(groups)
    }

    /// Records one frame's culling into `encoder`: writes the uniform (through the queue, so it
    /// lands before the next submit), clears the per-mesh counts, then three dispatches. `camera`
    /// and `params` should be validated, as for the reference.
    pub fn encode(&mut self, encoder: &mut wgpu::CommandEncoder, camera: &Camera, params: &Params) {
        let uniform = CullUniform::new(camera, params, self.tree_count, self.mesh_count);
        self.ctx
            .queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uniform));
        encoder.clear_buffer(&self.mesh_counts, 0, None);
        let pipelines = &self.pipelines;
        let (x, y) = self.groups();
        compute_pass(
            encoder,
            "cull",
            &self.bind_group,
            &[
                (&pipelines.count, Dispatch::Groups(x, y)),
                (&pipelines.commands, Dispatch::Groups(1, 1)),
                (&pipelines.scatter, Dispatch::Groups(x, y)),
            ],
        );
    }

    /// Runs one frame's culling and leaves the result on the GPU. Does not wait.
    pub fn dispatch(&mut self, camera: &Camera, params: &Params) -> Result<(), GpuError> {
        let ctx = self.ctx;
        ctx.submit("cull dispatch", "cull", |encoder| {
            self.encode(encoder, camera, params)
        })
    }

    /// Reads the last frame's output back: counters, commands, data, the compacted indirection
    /// and the indirect arguments. Blocks.
    pub fn read(&self) -> Result<GpuCulled, GpuError> {
        let selection = self.out.read(self.ctx)?;
        let n = selection.counters.instances;
        if n > self.tree_count {
            return Err(GpuError::Input {
                field: "counters.instances",
                value: n.to_string(),
                reason: "exceeds the tree count: the GPU wrote out of range",
            });
        }
        Ok(GpuCulled {
            indirection: read_buffer(self.ctx, &self.indirection, 0, n as usize)?,
            draw_args: read_buffer::<DrawIndirectArgs>(self.ctx, &self.draw_args, 0, 1)?[0],
            selection,
        })
    }

    /// The visible trees of the last frame, ascending (the reference's `visible_trees`). Blocks.
    pub fn read_visible(&self) -> Result<Vec<u32>, GpuError> {
        let mut visible = self.read()?.indirection;
        visible.sort_unstable();
        Ok(visible)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wgsl_layout::{assert_layout, assert_view_uniform, rust_layout, validate};

    /// `CullUniform` (with its `ViewUniform`) and `DrawIndirectArgs` have their WGSL twins' layout (naga reflection of the
    /// full `cull.wgsl` module, which also validates it; `CullTree`, in `common.wgsl`, is checked
    /// by `gpu/tests/layout.rs`).
    #[test]
    fn wgsl_layouts_match_rust() {
        let module = validate(&SOURCE.module());
        assert_layout(
            &module,
            &rust_layout!(CullUniform {
                view,
                tree_count,
                mesh_count,
                _pad0,
                _pad1
            }),
        );
        assert_view_uniform(&module);
        assert_layout(
            &module,
            &rust_layout!(DrawIndirectArgs {
                vertex_count,
                instance_count,
                first_vertex,
                first_instance
            }),
        );
    }

    /// The indirect arguments are wgpu's own.
    #[test]
    fn draw_indirect_args_are_wgpus() {
        let args = DrawIndirectArgs {
            vertex_count: 6,
            instance_count: 7,
            first_vertex: 8,
            first_instance: 9,
        };
        let theirs = wgpu::util::DrawIndirectArgs {
            vertex_count: 6,
            instance_count: 7,
            first_vertex: 8,
            first_instance: 9,
        };
        assert_eq!(bytemuck::bytes_of(&args), theirs.as_bytes());
    }
}
