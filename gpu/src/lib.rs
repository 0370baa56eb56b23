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
//! | occlusion culling's depth pyramid (issue 31) | [`pyramid`] | `shaders/pyramid.wgsl` | beyond the seeds (E§7) |
//! | occlusion culling of the commands (issue 31) | [`occlude`] | `shaders/occlude.wgsl` | beyond the seeds (E§7) |
//! | the far level's octant impostors, leaves rendered and reduced (issue 32) | [`far_bake`] | `shaders/far_bake.wgsl` | G§2.2-2.4 |
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
//! - [`readback`]: creating and uploading buffers (`Pod` slices, the stages' uniforms) and reading
//!   buffers and texture levels back;
//! - [`shaders`]: the composition of the WGSL modules (the constants of `forestlod-shared`, then
//!   `common.wgsl`, which mirrors `forestlod-shared`'s `Pod` structs field for field, checked by a
//!   naga reflection test, then the stage's own files);
//! - the stage drivers ([`select`], [`bake`], [`mips`], [`draw`], [`cull`], [`primitive`],
//!   [`hier_select`], [`coalesce`], [`command_order`], [`refine`]), each declaring its WGSL
//!   module, its `.wgsl` file and the constants it owns, as its `SOURCE` ([`StageSource`]);
//!   [`STAGE_SOURCES`] lists them.
//!
//! **Rule: no per-frame state behind `&self`.** `queue.write_buffer` lands at the next submit of
//! *any* thread, so a driver that rewrites a buffer it owns from a `&self` method lets two threads
//! record two frames into one buffer, and one frame is drawn with the other's camera (this was the
//! flake of issue 10: a `GpuDraw` shared by two tests through a static). Two shapes are allowed:
//! - drivers that hold only compiled pipelines (shared `Arc`s from the context's cache, which
//!   holds nothing per frame: [`GpuDraw`], [`GpuPrimitive`], [`GpuBake`], [`GpuMips`]) are `Sync`
//!   and take `&self`; every per-frame buffer (uniforms, outputs) is
//!   created by the call itself (`readback::frame_uniform`) or lives in a per-call or per-target
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
pub mod far_bake;
pub mod hier_select;
pub mod mips;
pub mod occlude;
pub mod primitive;
pub mod pyramid;
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
    terrain_vertices_of, upload_texture_array,
};
pub use far_bake::{FarLeaf, GpuFarBake};
pub use hier_select::{GpuHierSelect, HierUniform};
pub use mips::{GpuMips, MipArray, MipLevelStats, MipTexels};
pub use occlude::{GpuOcclude, GpuOccluded, OccludeUniform};
pub use primitive::{GpuPrimitive, GpuProxies, PrimitiveInputs};
pub use pyramid::GpuPyramid;
pub use refine::{GpuRefine, GpuRefined, RefineCounters, RefineDispatch};
pub use select::{Compaction, GpuSelect, GpuSelection, SelectBuffers, SelectUniform};
pub use shaders::{StageSource, WgslFile};

/// Every stage's WGSL module as its driver declares it, in the order of the table above. The
/// crate's tests compile each and check their constants against each other.
pub const STAGE_SOURCES: [&StageSource; 14] = [
    &select::SOURCE,
    &bake::SOURCE,
    &mips::SOURCE,
    &draw::SOURCE,
    &cull::SOURCE,
    &primitive::SOURCE,
    &hier_select::SOURCE,
    &coalesce::SOURCE,
    &command_order::SOURCE,
    &refine::SOURCE,
    &pyramid::SOURCE,
    &occlude::SOURCE,
    &far_bake::SOURCE,
    &draw::POINT_SOURCE,
];

#[cfg(test)]
mod tests {
    use std::collections::{BTreeMap, BTreeSet};

    use crate::STAGE_SOURCES;
    use crate::shaders::{COMMON_WGSL, shared_constants};
    use crate::wgsl_layout::validate;

    /// `(name, text)` of every compiled-in `.wgsl` file: `common.wgsl`, every file of every
    /// stage's module (a part shared by several once), and the standalone `depth_copy.wgsl`.
    fn compiled_in_files() -> BTreeMap<&'static str, &'static str> {
        let mut files = BTreeMap::from([
            ("common.wgsl", COMMON_WGSL),
            ("depth_copy.wgsl", crate::draw::DEPTH_COPY_WGSL),
        ]);
        for file in STAGE_SOURCES.iter().flat_map(|s| s.files()) {
            files.insert(file.name, file.wgsl);
        }
        files
    }

    /// Every generated constant `(name, value, declared by)`: the shared ones, then each stage
    /// file's own (a part shared by several stages once per stage).
    fn every_generated_constant() -> Vec<(String, u32, &'static str)> {
        let shared = shared_constants()
            .into_iter()
            .map(|(n, v)| (n, v, "shared"));
        let own = STAGE_SOURCES
            .iter()
            .flat_map(|s| s.files())
            .flat_map(|f| f.constants.iter().map(|&(n, v)| (n.to_string(), v, f.name)));
        shared.chain(own).collect()
    }

    /// Every `.wgsl` file of `gpu/src/shaders/` is compiled in: a stage's file or part, the
    /// common file, or the standalone depth copy (so a new stage's file without a
    /// [`STAGE_SOURCES`] entry fails here), and no two stages share an own file.
    #[test]
    fn every_wgsl_file_is_in_a_module() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/src/shaders");
        let on_disk: BTreeSet<String> = std::fs::read_dir(dir)
            .expect("gpu/src/shaders")
            .map(|e| {
                e.expect("dir entry")
                    .file_name()
                    .to_string_lossy()
                    .into_owned()
            })
            .filter(|n| n.ends_with(".wgsl"))
            .collect();
        let compiled: BTreeSet<String> =
            compiled_in_files().keys().map(|n| n.to_string()).collect();
        assert_eq!(
            on_disk, compiled,
            "gpu/src/shaders (left) vs compiled in (right)"
        );
        let own: BTreeSet<&str> = STAGE_SOURCES.iter().map(|s| s.own.name).collect();
        assert_eq!(
            own.len(),
            STAGE_SOURCES.len(),
            "two stages share an own file"
        );
        eprintln!("{} .wgsl files, {} stage modules", on_disk.len(), own.len());
    }

    /// No `.wgsl` file declares a constant that is generated (else the module would not compile,
    /// or, for a standalone source, a hand-kept copy could drift).
    #[test]
    fn stage_sources_declare_no_generated_constant() {
        let names: BTreeSet<String> = every_generated_constant()
            .into_iter()
            .map(|(n, _, _)| n)
            .collect();
        for (file, src) in compiled_in_files() {
            for name in &names {
                let decl = format!("const {name}:");
                assert!(!src.contains(&decl), "{file} declares generated `{name}`");
            }
        }
        eprintln!("{} generated names, none declared by hand", names.len());
    }

    /// No constant name is generated with two values (across the shared list and every stage's
    /// list), and no module declares a name twice.
    #[test]
    fn no_constant_is_generated_twice_with_different_values() {
        let mut seen: BTreeMap<String, (u32, &str)> = BTreeMap::new();
        for (name, value, by) in every_generated_constant() {
            let (first, first_by) = *seen.entry(name.clone()).or_insert((value, by));
            assert_eq!(
                first, value,
                "`{name}` is {first} in {first_by}'s constants but {value} in {by}'s"
            );
        }
        for stage in STAGE_SOURCES {
            let constants = stage.constants();
            let names: BTreeSet<&str> = constants.iter().map(|(n, _)| n.as_str()).collect();
            assert_eq!(
                names.len(),
                constants.len(),
                "{}'s module declares a constant twice",
                stage.own.name
            );
        }
        eprintln!("{} distinct generated constants", seen.len());
    }

    /// Every stage's module, as the driver compiles it, parses and validates (naga): it declares
    /// every constant its files read, and nothing twice.
    #[test]
    fn every_stage_module_validates() {
        for stage in STAGE_SOURCES {
            validate(&stage.module());
            eprintln!("{}: valid", stage.own.name);
        }
    }

    /// A stage's own constants reach its module with their Rust values (a spot check: a workgroup
    /// size, the scan part's, a table offset).
    #[test]
    fn stage_constants_are_the_rust_items() {
        for (stage, line) in [
            (
                &crate::select::SOURCE,
                "const SELECT_WORKGROUP_SIZE: u32 = 64u;",
            ),
            (
                &crate::select::SOURCE,
                "const SCAN_WORKGROUP_SIZE: u32 = 256u;",
            ),
            (
                &crate::hier_select::SOURCE,
                "const SCAN_WORKGROUP_SIZE: u32 = 256u;",
            ),
            (
                &crate::coalesce::SOURCE,
                "const SCAN_WORKGROUP_SIZE: u32 = 256u;",
            ),
            (
                &crate::mips::SOURCE,
                "const TABLE_UNORM_ENCODE: u32 = 768u;",
            ),
        ] {
            let module = stage.module();
            assert!(module.contains(line), "{} lacks `{line}`", stage.own.name);
        }
    }
}
