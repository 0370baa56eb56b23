//! # forestlod-gpu: the wgpu twin of the reference pipeline
//!
//! Every stage of the grouped-LOD forest pipeline (Eichner 2024, cited as "E§…") that runs on the
//! GPU, written in WGSL and driven through wgpu 30, plus the readback helpers that let tests judge
//! it buffer by buffer against the CPU oracle `forestlod-reference` (SPEC §8). Stages share their
//! names with the reference: `reference/src/<stage>.rs` ↔ `gpu/src/shaders/<stage>.wgsl` ↔
//! `gpu/src/<stage>.rs`.
//!
//! | stage | Rust driver | WGSL | seed |
//! |---|---|---|---|
//! | per-batch selection | [`select`] | `shaders/select.wgsl` | E§3.5, §4.3; SPEC §5.4 |
//! | billboard bake | [`bake`] | `shaders/bake.wgsl` | E Alg. 3.1, §4.1; SPEC §5.1 |
//! | billboard mip chains | [`mips`] | `shaders/mips.wgsl` | E Alg. 3.2, §3.3.2, §4.1; SPEC §5.2 |
//! | draw execution | [`draw`] | `shaders/draw.wgsl` | E§3.3.1, §4.4; SPEC §5.5 |
//! | baselines' per-tree culling | [`cull`] | `shaders/cull.wgsl` | E§5; SPEC §9 |
//! | Primitive baseline's ray-cast quads | [`primitive`] | `shaders/primitive.wgsl` | E§5; SPEC §9 |
//! | the hierarchy's cut | [`hier_select`] | `shaders/hier_select.wgsl` | G§3 Fig. 4, C§4.5 |
//! | the cut's runs merged | [`coalesce`] | `shaders/coalesce.wgsl` | G§3 |
//! | the cut's commands front to back | [`command_order`] | `shaders/command_order.wgsl` | E§7 |
//! | per-tree refinement of the selected commands (beyond the thesis) | [`refine`] | `shaders/refine.wgsl` | E§3.5, §7 |
//!
//! Every stage is a `forestlod_shared::StageId`; the frame's order of them is
//! `forestlod_shared::FramePlan`, and the harness's stage table (`harness/src/stages.rs`) names
//! each stage's twins, backend and parity case.
//!
//! What this crate owns:
//! - [`GpuContext`]: adapter and device selection (any Vulkan adapter, lavapipe included), the
//!   optional features the pipeline uses, and the context a test gets or is told how to get
//!   ([`gpu_or_explain`]);
//! - the one pipeline cache: every stage's compiled pipelines (a [`StagePipelines`] type:
//!   `SelectPipelines`, `CullPipelines`, `RefinePipelines`, `DrawPipelines`,
//!   `PrimitivePipelines`, `MipsPipelines`, `BakePipelines`, `DepthCopyPipelines`) are compiled
//!   once per context on first use and shared by every driver ([`GpuContext::pipelines`]);
//! - [`readback`]: uploading `Pod` slices and reading buffers and texture levels back;
//! - [`shaders`]: the WGSL sources, with `common.wgsl` mirroring `forestlod-shared`'s `Pod` structs
//!   field for field (a naga reflection test checks every offset);
//! - the stage drivers ([`select`], [`bake`], [`mips`], [`draw`], [`cull`], [`primitive`],
//!   [`refine`]).
//!
//! **Rule: no per-frame state behind `&self`.** `queue.write_buffer` lands at the next submit of
//! *any* thread, so a driver that rewrites a buffer it owns from a `&self` method lets two threads
//! record two frames into one buffer, and one frame is drawn with the other's camera (this was the
//! flake of issue 10: a `GpuDraw` shared by two tests through a static). Two shapes are allowed:
//! - drivers that hold only compiled pipelines (shared `Arc`s from the context's cache, which
//!   holds nothing per frame: [`GpuDraw`], [`GpuPrimitive`], [`GpuBake`], [`GpuMips`]) are `Sync`
//!   and take `&self`; every per-frame buffer (uniforms, outputs) is
//!   created by the call itself (`context::frame_uniform`) or lives in a per-call or per-target
//!   object the caller owns ([`DrawTarget`]);
//! - drivers that own per-scene outputs the frame writes ([`GpuSelect`], [`GpuCull`],
//!   [`GpuRefine`]) take `&mut self` to record a frame, and a stage that rewrites another stage's
//!   output takes it as `&mut` ([`GpuSelect::buffers_mut`]), so the borrow checker forbids two
//!   frames in flight on one object. Reads (`read`, `buffers`) take `&self`.
//!
//! `tests/tests/parity/threads.rs` renders different scenarios from several threads on one context
//! with shared drivers and asserts each frame equals its single-thread twin.
//!
//! What it must not depend on: `forestlod-reference`. The oracle and its twin meet only in the
//! `tests` crate, so a bug cannot leak from one into the other through shared code; the only code
//! both sides share is `forestlod-shared` (types and scalar formulas).
//!
//! Numerics: the WGSL repeats the shared formulas operation for operation, in the same order, but
//! a GPU compiler may contract `a * b + c` into a fused multiply-add or otherwise round
//! differently. The parity tests therefore classify decisions within a small ε of a threshold as
//! ambiguous instead of failing them (SPEC §8).

pub mod bake;
pub mod coalesce;
pub mod command_order;
pub mod context;
pub mod cull;
pub mod draw;
pub mod hier_select;
pub mod mips;
pub mod primitive;
pub mod readback;
pub mod refine;
pub mod select;
pub mod shaders;
#[cfg(test)]
mod wgsl_layout;

pub use bake::{BakeMesh, GpuBake, GpuBaked};
pub use coalesce::{CoalesceUniform, GpuCoalesce};
pub use command_order::{GpuCommandOrder, OrderStep, OrderUniform};
pub use context::{
    ALLOW_NO_GPU_ENV, GpuContext, GpuError, NO_GPU_HINT, REQUIRED_DOWNLEVEL, REQUIRED_FEATURES,
    StagePipelines, adapter_shortfall, gpu_or_explain,
};
pub use cull::{CullTree, DrawIndirectArgs, GpuCull, GpuCulled};
pub use draw::{
    DrawCalls, DrawInputs, DrawInstance, DrawScene, DrawSceneDesc, DrawTarget, DrawTextures,
    DrawVertex, DrawnImages, GpuDraw, IndirectMode, MipLevel, TerrainVertex, terrain_vertices,
    upload_texture_array,
};
pub use hier_select::{GpuHierSelect, HierUniform};
pub use mips::{GpuMips, MipArray, MipLevelStats, MipTexels};
pub use primitive::{GpuPrimitive, GpuProxies, PrimitiveInputs};
pub use refine::{GpuRefine, GpuRefined, RefineCounters, RefineDispatch};
pub use select::{Compaction, GpuSelect, GpuSelection, SelectBuffers, SelectUniform};
