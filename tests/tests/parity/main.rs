//! Parity: everything that needs a GPU adapter (wgpu; lavapipe in CI), one test binary so the
//! suite links once instead of once per stage. Each module checks one GPU stage or concern
//! against the reference pipeline:
//! - [`hier_select`]: the hierarchical cut (issue 13) against the reference, frames against the grid's;
//! - [`select`], [`refine`], [`draw`], [`mips`], [`bake`]: the GPU twin of each reference stage;
//! - [`far_bake`]: issue 32's far level bake (octant impostors' leaves) against the reference;
//! - [`impostors`]: issue 33 item 2's hierarchical impostors drawn by the GPU along a camera path;
//! - [`blend`]: issue 30's G§4 blend (texture-space noise, per-tree progress) in the draw stage,
//!   with the noise level's rounding boundary classified;
//! - [`every_stage`]: every stage of the stage table run alone on the GPU and judged by its
//!   harness judge, on a few small frames (issue 27);
//! - [`baselines`]: the GPU Vegetation and Primitive baselines against the reference's;
//! - [`metamorphic`]: relations between two runs of one backend (translation, permutation,
//!   LOD0 everywhere = Vegetation, LOD monotone in distance), on the reference and the GPU;
//! - [`threads`]: frames recorded from several threads on one context equal single-thread ones;
//! - [`mutants`]: the CI-sized mutation subset (issue 36): WGSL mutants that must stay killed,
//!   each run through the mutation hook in a child of this binary;
//! - [`sampler_lod`]: the adapter's implicit level of detail, measured (the data behind the
//!   tolerances of `forestlod_harness::image_compare`), and held to the specification's interval;
//! - [`h200`]: the first real GPU's logged single-pixel failures, classified on the reference.
//!
//! Run one module with `cargo test -p forestlod-tests --test parity <module>::`. Statics that
//! each file once had to itself (GPU contexts and objects) are now shared by the modules; the GPU
//! objects hold no per-frame state behind `&self` (`gpu/src/lib.rs`), so sharing is race-free.

mod bake;
mod baselines;
mod blend;
mod counters;
mod draw;
mod every_stage;
mod far;
mod far_bake;
mod from_cpu;
mod h200;
mod hier_select;
mod impostors;
mod metamorphic;
mod mips;
mod mutants;
mod occlusion;
mod octahedral_depth;
mod points;
mod refine;
mod sampler_lod;
mod select;
mod stage_table;
mod threads;
